"""The hierarchy structural probe's masks equal, bit for bit, those of the plain reference
(:mod:`structural_oracle`: every level as a label image, areas and first pixels from every pixel):
on random images, the demo room's renderings, odd sizes, one pixel, uniform images, many tiny regions,
and renderings larger than the working image (upsampled masks)."""
from __future__ import annotations

import numpy as np
import pytest
from structural_oracle import compact_oracle, hierarchy_levels_oracle, hierarchy_masks_oracle, label_masks_oracle
from test_probes_builtin import demo

from r360gpu.probes.builtin import as_rgb_uint8, label_masks, lut_masks, to_working, working_size
from r360gpu.probes.builtin_structural import (
    BuiltinStructuralProbe,
    StructuralParams,
    _compact,
    _compact_firsts,
    hierarchy_levels,
)


def _same_as_oracle(image: np.ndarray, params: StructuralParams | None = None) -> int:
    """Asserts the probe's masks equal the oracle's; returns how many masks there are."""
    probe = BuiltinStructuralProbe(params)
    got = probe.predict_image(image).masks
    rgb = as_rgb_uint8(image)
    size = rgb.shape[:2]
    work = to_working(rgb, working_size(size[0], size[1], int(probe.config.work_long_side)))
    want = hierarchy_masks_oracle(work, probe.config, size)
    assert got.dtype == bool and got.shape == want.shape
    assert np.array_equal(got, want)
    return got.shape[0]


def _noise(h, w, seed, levels=256):
    rng = np.random.default_rng(seed)
    return (rng.integers(0, levels, (h, w, 3)) * (255 // max(levels - 1, 1))).astype(np.uint8)


def _blocks(h, w, seed, cell):
    """Piecewise-constant colour blocks of ``cell`` px with a little noise: many regions of a known size."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (-(-h // cell), -(-w // cell), 3))
    img = np.repeat(np.repeat(small, cell, 0), cell, 1)[:h, :w] + rng.normal(0, 2, (h, w, 3))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("seed", range(3))
def test_random_images_match_oracle(seed):
    assert _same_as_oracle(_noise(47, 61, seed)) >= 0
    assert _same_as_oracle(_noise(90, 120, seed, levels=4)) >= 1


def test_demo_room_renderings_match_oracle():
    counts = [_same_as_oracle(demo.render(180, 320, pose, case)[0])
              for pose in (0, demo.HELD_OUT) for case in ("pre", *demo.CASES)]
    assert min(counts) >= 5  # the room gives several masks per view: the comparison is not of empty sets


@pytest.mark.parametrize("h,w", [(1, 1), (1, 7), (9, 1), (2, 2), (3, 5), (31, 17)])
def test_odd_and_tiny_sizes_match_oracle(h, w):
    _same_as_oracle(_noise(h, w, h * 100 + w))
    _same_as_oracle(_blocks(h, w, h + w, 2))


@pytest.mark.parametrize("value", [0, 77, 255])
def test_uniform_images_match_oracle(value):
    img = np.full((40, 50, 3), value, np.uint8)
    assert _same_as_oracle(img) == 1  # one mask: the whole image


def test_many_tiny_regions_match_oracle():
    # min_area_frac 0 keeps every region and max_masks caps a long list: ties in area broken by first pixel
    params = StructuralParams(min_area_frac=0.0, fine_min_area_frac=0.0, max_masks=500)
    assert _same_as_oracle(_blocks(60, 80, 1, 3), params) > 100
    assert _same_as_oracle(_blocks(64, 64, 2, 1), StructuralParams(min_area_frac=0.0, max_masks=3)) == 3


@pytest.mark.parametrize("h,w", [(700, 300), (513, 1025)])
def test_renderings_larger_than_the_working_image_match_oracle(h, w):
    # shrunk to the working image, masks upsampled by nearest neighbour
    img = _blocks(h, w, 5, 37)
    assert _same_as_oracle(img) >= 2


def test_float_image_and_other_levels_match_oracle():
    img = demo.render(120, 160, 0, "pre")[0]
    _same_as_oracle(img.astype(np.float32) / np.float32(255.0))
    _same_as_oracle(img, StructuralParams(levels=(1.0, 3.0), colour_weight=2.0, edge_blur=0.0))


def test_hierarchy_levels_match_oracle():
    for img in (demo.render(90, 160, 1, "pre")[0], _noise(33, 21, 4)):
        got, want = hierarchy_levels(img, StructuralParams()), hierarchy_levels_oracle(img, StructuralParams())
        assert len(got) == len(want) and all(np.array_equal(a, b) and a.dtype == b.dtype for a, b in zip(got, want))


def test_compact_matches_oracle_on_any_numbering():
    rng = np.random.default_rng(0)
    cases = [
        np.array([[0]]),
        np.array([[5, 5], [5, 5]]),
        np.array([[0, 1, 0], [2, 1, 3]]),  # already in raster order: the fast path
        np.array([[1, 0], [2, 2]]),  # not in raster order
        np.array([[0, 2], [1, 3]]),  # a label skipped at first appearance
        np.array([[0, -1], [1, 1]]),  # negative label
        rng.integers(-3, 50, (13, 17)),
        np.repeat(np.arange(40), 3).reshape(10, 12),
    ]
    for labels in cases:
        want = compact_oracle(labels)
        got, firsts = _compact_firsts(labels)
        assert got.dtype == np.int32 and np.array_equal(got, want) and np.array_equal(_compact(labels), want)
        _, first = np.unique(want.reshape(-1), return_index=True)
        assert np.array_equal(firsts, first)


def test_label_masks_and_lut_masks_match_oracle():
    rng = np.random.default_rng(1)
    labels = rng.integers(-2, 9, (7, 11))
    for size in [(7, 11), (15, 4), (1, 1), (30, 40)]:
        ids = np.array([8, -2, 3, 100])  # 100: absent, an empty mask
        assert np.array_equal(label_masks(labels, ids, size), label_masks_oracle(labels, ids, size))
    fine = rng.integers(0, 6, (5, 6))
    luts = [np.array([0, -1, 1, 1, -1, 2]), np.array([3, 3, 3, -1, -1, -1])]
    got = lut_masks(fine, luts, 4, (10, 9))
    want = label_masks_oracle(fine, [0, 2, 3], (10, 9))
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1] | label_masks_oracle(fine, [3], (10, 9))[0])
    assert np.array_equal(got[2], label_masks_oracle(fine, [5], (10, 9))[0])
    assert np.array_equal(got[3], label_masks_oracle(fine, [0, 1, 2], (10, 9)).any(axis=0))
    assert lut_masks(fine, [], 0, (3, 4)).shape == (0, 3, 4)
