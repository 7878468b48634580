"""COCO RLE: our encoder/decoder against pycocotools (test-only dependency)."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.probes import rle

mask_utils = pytest.importorskip("pycocotools.mask")

# pycocotools 2.0.x trips numpy 2's __array__(copy=...) deprecation; not ours.
pytestmark = pytest.mark.filterwarnings("ignore:__array__ implementation:DeprecationWarning")


def _coco_encode(mask: np.ndarray) -> dict:
    out = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    return {"size": [int(s) for s in out["size"]], "counts": out["counts"].decode("utf-8")}


def _coco_decode(obj: dict) -> np.ndarray:
    if isinstance(obj["counts"], list):
        obj = mask_utils.frPyObjects(obj, obj["size"][0], obj["size"][1])
    else:
        obj = {"size": obj["size"], "counts": obj["counts"].encode("utf-8")}
    return mask_utils.decode(obj).astype(bool)


def _random_masks(seed: int = 7, n: int = 120):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        h, w = (int(v) for v in rng.integers(1, 70, size=2))
        kind = rng.integers(0, 3)
        if kind == 0:  # salt and pepper: many short runs
            yield rng.random((h, w)) < rng.random()
        elif kind == 1:  # blobs: long runs, negative deltas in the string
            m = np.zeros((h, w), bool)
            for _ in range(int(rng.integers(1, 4))):
                r0, c0 = rng.integers(0, h), rng.integers(0, w)
                m[r0 : r0 + rng.integers(1, h + 1), c0 : c0 + rng.integers(1, w + 1)] = True
            yield m
        else:  # sparse single pixels in a big field
            m = np.zeros((h, w), bool)
            m.flat[rng.integers(0, h * w, size=int(rng.integers(1, 5)))] = True
            yield m


def _adversarial_masks():
    yield np.zeros((1, 1), bool)
    yield np.ones((1, 1), bool)
    yield np.zeros((37, 53), bool)
    yield np.ones((37, 53), bool)
    for h, w in [(1, 17), (17, 1), (3, 5), (64, 33)]:
        for r, c in [(0, 0), (0, w - 1), (h - 1, 0), (h - 1, w - 1)]:
            m = np.zeros((h, w), bool)
            m[r, c] = True
            yield m
            yield ~m
    m = np.zeros((40, 31), bool)
    m[::2, ::3] = True  # alternating runs of every length class
    yield m
    # A count large enough for several 5-bit chunks next to tiny ones, so the
    # deltas swing between large positive and large negative values.
    big = np.zeros((1000, 700), bool)
    big[500, 350] = True
    big[501, 350] = True
    big[0, 699] = True
    yield big


ALL_MASKS = list(_random_masks()) + list(_adversarial_masks())


def test_mask_to_counts_conventions():
    assert rle.mask_to_counts(np.zeros((2, 3), bool)).tolist() == [6]
    assert rle.mask_to_counts(np.ones((2, 3), bool)).tolist() == [0, 6]
    m = np.array([[1, 0], [0, 1]], bool)  # column-major: 1,0,0,1
    assert rle.mask_to_counts(m).tolist() == [0, 1, 2, 1]
    m = np.array([[0, 0, 1]], np.uint8)  # integer input, non-zero = set
    assert rle.mask_to_counts(m).tolist() == [2, 1]


def test_counts_string_small_known_values():
    # 0..15 fit one chunk: chr(48 + x); 16 needs a second chunk (sign bit).
    # (Expected strings checked against pycocotools 2.0.11 by hand.)
    assert rle.counts_to_string([0, 1, 15]) == "01?"
    # 16 has bit 0x10 set, which would read as a sign: 0x10|0x20 then 0.
    assert rle.counts_to_string([16]) == "`0"
    assert rle.string_to_counts("`0") == [16]
    # From the 4th count on, the difference to the count two before is stored:
    # [1, 1, 3, 4, 4] -> 1, 1, 3, 4-1, 4-3.
    assert rle.counts_to_string([1, 1, 3, 4, 4]) == "11331"
    assert rle.string_to_counts("11331") == [1, 1, 3, 4, 4]


@pytest.mark.parametrize("index", range(len(ALL_MASKS)))
def test_our_encode_matches_pycocotools(index):
    mask = ALL_MASKS[index]
    ours = rle.encode(mask)
    theirs = _coco_encode(mask)
    assert ours == theirs
    assert np.array_equal(_coco_decode(ours), mask)


@pytest.mark.parametrize("index", range(len(ALL_MASKS)))
def test_our_decode_of_pycocotools(index):
    mask = ALL_MASKS[index]
    decoded = rle.decode(_coco_encode(mask))
    assert decoded.dtype == bool and decoded.shape == mask.shape
    assert np.array_equal(decoded, mask)
    # pycocotools' own bytes counts are accepted as well.
    raw = mask_utils.encode(np.asfortranarray(mask.astype(np.uint8)))
    assert np.array_equal(rle.decode(raw), mask)


@pytest.mark.parametrize("index", range(0, len(ALL_MASKS), 3))
def test_uncompressed_both_ways(index):
    mask = ALL_MASKS[index]
    ours = rle.encode(mask, compressed=False)
    assert isinstance(ours["counts"], list) and sum(ours["counts"]) == mask.size
    assert np.array_equal(_coco_decode(ours), mask)  # ours -> pycocotools
    assert np.array_equal(rle.decode(ours), mask)
    # pycocotools' reading of an uncompressed RLE, compressed by it, agrees.
    compressed = mask_utils.frPyObjects(ours, *ours["size"])
    assert compressed["counts"].decode() == rle.encode(mask)["counts"]


def test_hand_written_uncompressed_rle():
    # 3x2, column-major pixels: 0 1 1 | 0 0 1
    obj = {"size": [3, 2], "counts": [1, 2, 2, 1]}
    expected = np.array([[0, 0], [1, 0], [1, 1]], bool)
    assert np.array_equal(rle.decode(obj), expected)
    assert np.array_equal(_coco_decode(obj), expected)


@pytest.mark.parametrize(
    "obj, fragment",
    [
        ({"size": [2, 2], "counts": [1, 2]}, "sum to 3"),
        ({"size": [2, 2], "counts": "3"}, "sum to 3"),  # compressed, short
        ({"size": [2, 2], "counts": "5"}, "sum to 5"),  # compressed, long
        ({"size": [2, 2], "counts": [5, -1]}, "negative"),
        ({"size": [2, 2], "counts": "4 "}, "invalid character"),
        ({"size": [2, 2], "counts": "4p"}, "invalid character"),
        ({"size": [2, 2], "counts": "0X"}, "ends inside a number"),
        ({"size": [2], "counts": "4"}, "size"),
        ({"size": [0, 2], "counts": []}, "positive"),
        ({"size": [2, 2.0], "counts": "4"}, "size"),
        ({"counts": "4"}, "both"),
        ({"size": [2, 2], "counts": 4}, "string or a list"),
        ({"size": [2, 2], "counts": [2, True, 1]}, "list of integers"),
        ([4], "object"),
    ],
)
def test_bad_rle_raises_input_error_naming_the_file(obj, fragment):
    with pytest.raises(InputError) as err:
        rle.decode(obj, "masks/view7.json")
    assert "masks/view7.json" in str(err.value)
    assert fragment in str(err.value)


def test_negative_count_from_delta_is_rejected():
    # 4th count = 1 + delta(-3) = -2 via the counts[i-2] delta.
    text = rle.counts_to_string([2, 1, 3, -2])
    assert rle.string_to_counts(text) == [2, 1, 3, -2]
    with pytest.raises(InputError, match="negative"):
        rle.decode({"size": [2, 2], "counts": text})


def test_encode_rejects_non_2d():
    with pytest.raises(ValueError):
        rle.encode(np.zeros((2, 2, 2), bool))
    with pytest.raises(ValueError):
        rle.encode(np.zeros((0, 3), bool))
