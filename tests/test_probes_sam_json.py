"""The fast SAM-JSON reader gives exactly the masks (and errors) of the standard one."""
from __future__ import annotations

import json

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.probes import sam_records as P
from r360gpu.probes import sam_json


def _standard(path):
    """What the reader did before the fast path: json.loads + read_sam_records."""
    return P.read_sam_records(json.loads(path.read_bytes().decode("utf-8")), path)


def _same(path):
    fast = P.read_sam_json(path)
    slow = _standard(path)
    assert fast.masks.dtype == slow.masks.dtype == bool
    np.testing.assert_array_equal(fast.masks, slow.masks)
    if slow.scores is None:
        assert fast.scores is None
    else:
        np.testing.assert_array_equal(fast.scores, slow.scores)
    return fast


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text) if isinstance(text, str) else p.write_bytes(text)
    return p


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (7, 1), (23, 41), (64, 33)])
@pytest.mark.parametrize("indent", [None, 2])
def test_public_script_format_round_trips(tmp_path, shape, indent):
    rng = np.random.default_rng(abs(hash((shape, indent))) % 2**32)
    masks = [rng.random(shape) < p for p in (0.0, 0.3, 1.0)]
    recs = [{"segmentation": m.tolist(), "area": int(m.sum()), "bbox": [0, 0, 1, 1], "predicted_iou": 0.5 + i / 8}
            for i, m in enumerate(masks)]
    path = _write(tmp_path, "v.json", json.dumps(recs, indent=indent))
    got = _same(path)
    np.testing.assert_array_equal(got.masks, np.stack(masks))
    if indent is None:  # json.dump's own spelling: the fast path is taken
        assert sam_json._fast(path.read_bytes()) is not None


def test_integer_lists_mask_key_and_mixed_values(tmp_path):
    rng = np.random.default_rng(1)
    m = (rng.random((9, 14)) < 0.5).astype(int)
    mixed = [[bool(v) if j % 2 else int(v) for j, v in enumerate(row)] for row in m.tolist()]
    recs = [{"mask": m.tolist()}, {"segmentation": mixed, "label": "a \"segmentation\": [[1]] string"},
            {"segmentation": m.tolist(), "mask": (1 - m).tolist()}]
    _same(_write(tmp_path, "v.json", json.dumps(recs)))


@pytest.mark.parametrize(
    "seg, message",
    [
        ("[]", "non-empty"),
        ("[[]]", "non-empty"),
        ("[[1, 0], [1]]", "different lengths"),
        ("[[1, 0], [1, 0, 1]]", "different lengths"),
        ("[[1, 2]]", "0/1 or true/false"),
        ("[[1, -1]]", "0/1 or true/false"),
        ('[["1", "0"]]', "0/1 or true/false"),
        ("[[[1]]]", "H x W"),
        ("[1, 0]", "H x W"),
    ],
)
def test_bad_segmentations_give_the_standard_error(tmp_path, seg, message):
    good = json.dumps([[True, False]])
    path = _write(tmp_path, "bad.json", f'[{{"segmentation": {good}}}, {{"segmentation": {seg}}}]')
    with pytest.raises(InputError, match=message) as exc:
        P.read_sam_json(path)
    assert "bad.json" in str(exc.value)
    with pytest.raises(InputError) as exc2:
        _standard(path)
    assert str(exc.value) == str(exc2.value)


@pytest.mark.parametrize("seg", ["[[1.0, 0.0]]", "[[true, 0], [1, false]]", "[ [ 1 ,0 ] ,\n [0,1]\t]", "[[1,0],[0,1]]"])
def test_other_valid_spellings(tmp_path, seg):
    _same(_write(tmp_path, "v.json", f'[{{"segmentation": {seg}}}]'))


@pytest.mark.parametrize("text", ['[{"segmentation": [[1 0]]}]', '[{"segmentation": [[tr ue]]}]',
                                  '[{"segmentation": [[1,,0]]}]', '[{"segmentation": [[1, 0]]', b'\xff[]'])
def test_malformed_files_give_the_standard_error(tmp_path, text):
    path = _write(tmp_path, "m.json", text)
    with pytest.raises(InputError) as exc:
        P.read_sam_json(path)
    assert "m.json" in str(exc.value)
    assert "malformed JSON" in str(exc.value) or "utf-8" in str(exc.value)


def test_size_mismatch_between_records(tmp_path):
    recs = [{"segmentation": [[1, 0]]}, {"segmentation": [[1], [0]]}]
    with pytest.raises(InputError, match="record 1: segmentation is 2x1, record 0 is 1x2"):
        P.read_sam_json(_write(tmp_path, "v.json", json.dumps(recs)))


def test_empty_record_list_and_merged_file(tmp_path):
    assert P.read_sam_json(_write(tmp_path, "e.json", "[]")).masks.shape == (0, 0, 0)
    rng = np.random.default_rng(3)
    m = rng.random((5, 6)) < 0.5
    d = tmp_path / "sam"
    d.mkdir()
    (d / "merged.json").write_text(json.dumps({"v1.png": [{"segmentation": m.tolist()}], "v2.jpg": []}))
    sd = P.SamJsonDir(d)
    np.testing.assert_array_equal(sd.read("v1").masks[0], m)
    assert sd.read("v2").masks.shape[0] == 0


def test_parse_grid_rejects_non_grids():
    for t in (b"[[1,0]]x", b"[[1,0],[0]]", b"[[10]]", b"[[1,0],[0,1],]", b"[[1,0]", b"[[1,0]][[1]]", b"[[2]]",
              b"[[tru, true]]", b"[[truee]]", b"[[tr ue]]", b"[[true ,false]]", b"[[ falsee]]", b"[[fasle]]",
              b"[[true,]]", b"[[t,f]]", b"[[rtue]]", b"[ [1]]", b"[[1, 0],[0, 1]]", b"[[1,0], [0,1]]",
              b"[[1],[0,1]]", b"[[true], [false], [true]] ", b"[[1, 1, 0], [1, 0]]", b"[[1, 0], [1, 0, 1]]"):
        assert sam_json.parse_grid(t) is None, t
    np.testing.assert_array_equal(sam_json.parse_grid(b"[[1,0],[0,1]]"), [[True, False], [False, True]])
    np.testing.assert_array_equal(sam_json.parse_grid(b"[[true, false], [false, true]]"), [[True, False], [False, True]])
    np.testing.assert_array_equal(sam_json.parse_grid(b"[[true]]"), [[True]])
    np.testing.assert_array_equal(sam_json.parse_grid(b"[[0],[1],[1]]"), [[False], [True], [True]])


def _canonical_bool_grid(text: bytes):
    """The grid when ``text`` is exactly json.dumps of a rectangular bool list (either separator), else None."""
    try:
        obj = json.loads(text)
    except ValueError:
        return None
    if not (isinstance(obj, list) and obj and all(isinstance(r, list) and r for r in obj)):
        return None
    if len({len(r) for r in obj}) != 1 or not all(type(v) is bool for r in obj for v in r):
        return None
    if text.decode() not in (json.dumps(obj), json.dumps(obj, separators=(",", ":"))):
        return None
    return np.array(obj, bool)


#: The true/false grid parsers: the dispatcher and both of its ways.
_BOOL_PARSERS = {"grid": sam_json.parse_bool_grid, "runs": sam_json.parse_bool_runs,
                 "tokens": sam_json.parse_bool_tokens}


@pytest.mark.parametrize("parser", sorted(_BOOL_PARSERS))
@pytest.mark.parametrize("sep", [", ", ","])
@pytest.mark.parametrize("shape", [(1, 1), (1, 3), (3, 1), (2, 3), (3, 4)])
def test_parse_bool_grid_takes_exactly_json_dumps_text(parser, sep, shape):
    """Every single-byte change, deletion and insertion of a canonical text is either decoded as the grid it
    spells (when it still is json.dump's text of one) or refused (None: the standard reader takes over)."""
    parse = _BOOL_PARSERS[parser]
    rng = np.random.default_rng(len(sep) * 10 + shape[0] * 3 + shape[1])
    grid = rng.random(shape) < 0.5
    text = json.dumps(grid.tolist(), separators=(sep, ": ")).encode()
    pad = b'{"a": ' + text + b"}"  # the grid inside a file, as _fast sees it
    lo = 6
    np.testing.assert_array_equal(parse(pad, lo, lo + len(text)), grid)
    variants = set()
    for i in range(len(text)):
        for c in b"tfrueals, []01e":
            variants.add(text[:i] + bytes([c]) + text[i + 1 :])
            variants.add(text[:i] + bytes([c]) + text[i:])
        variants.add(text[:i] + text[i + 1 :])
    for v in variants:
        want = _canonical_bool_grid(v)
        got = parse(b"xx" + v + b"yy", 2, 2 + len(v))
        if want is None:
            assert got is None, v
        else:
            assert got is not None, v
            np.testing.assert_array_equal(got, want, err_msg=str(v))


@pytest.mark.parametrize("sep", [", ", ","])
@pytest.mark.parametrize("kind", ["blobs", "noise", "stripes", "full", "empty", "edges"])
def test_bool_grid_ways_agree_on_large_masks(sep, kind):
    """The run and token ways decode the same masks at full size, and the dispatcher takes the run way
    for few runs and the token way (the run way refusing) for many."""
    rng = np.random.default_rng(len(sep) + len(kind))
    h, w = 97, 131
    yy, xx = np.mgrid[:h, :w]
    grid = {
        "blobs": ((yy - 40) / 30.0) ** 2 + ((xx - 70) / 45.0) ** 2 < 1,
        "noise": rng.random((h, w)) < 0.5,
        "stripes": (xx % 3 == 0) | (yy == h - 1),
        "full": np.ones((h, w), bool),
        "empty": np.zeros((h, w), bool),
        "edges": (xx == 0) | (xx == w - 1) | (yy == 0),
    }[kind]
    text = b"ab" + json.dumps(grid.tolist(), separators=(sep, ": ")).encode() + b"cd"
    lo, hi = 2, len(text) - 2
    for parse in _BOOL_PARSERS.values():
        np.testing.assert_array_equal(parse(text, lo, hi), grid)
    runs = int((grid[:, 1:] & ~grid[:, :-1]).sum() + grid[:, 0].sum())
    assert (sam_json.parse_bool_runs(text, lo, hi, max_runs=runs) is None) is False
    assert sam_json.parse_bool_runs(text, lo, hi, max_runs=runs - 1) is None or runs == 0
    # a wrong byte in the middle of a long run is refused by both ways
    bad = bytearray(text)
    k = text.index(b"false" if kind != "full" else b"true", len(text) // 2)
    bad[k + 1] = ord("x")
    for parse in _BOOL_PARSERS.values():
        assert parse(bytes(bad), lo, hi) is None


def test_grid_end_finds_the_first_double_bracket():
    raw = b'{"segmentation": [[true, false], [false, true]], "b": [[1]]}'
    start = raw.index(b"[[")
    assert raw[start : sam_json._grid_end(raw, start)] == b"[[true, false], [false, true]]"
    assert sam_json._grid_end(b"[[true], [false] ]", 0) == -1


def test_short_file_after_a_long_one_is_read_as_itself(tmp_path):
    """A short file read after a long one in the same thread is read as itself, by the fast path,
    the standard one and the error path alike."""
    rng = np.random.default_rng(7)
    big = [{"segmentation": (rng.random((40, 60)) < 0.3).tolist(), "area": 1, "bbox": [0, 0, 1, 1]}
           for _ in range(3)]
    long_file = _write(tmp_path, "long.json", json.dumps(big))
    short_fast = _write(tmp_path, "short.json", json.dumps([{"segmentation": [[True, False]], "area": 1}]))
    short_indented = _write(tmp_path, "indented.json", json.dumps([{"segmentation": [[False], [True]]}], indent=1))
    broken = _write(tmp_path, "broken.json", '[{"segmentation": [[true]]}')
    for p in (long_file, short_fast, long_file, short_indented, long_file):
        _same(p)
    sam_json._read(long_file)
    assert sam_json._fast(sam_json._read(short_fast)) is not None  # the fast path taken
    _same(long_file)
    with pytest.raises(InputError) as got:
        P.read_sam_json(broken)
    with pytest.raises(InputError) as want:
        sam_json._standard(broken.read_bytes(), broken)  # the message of the file read on its own
    assert str(got.value) == str(want.value) and "line 1, column 28" in str(got.value)
