"""One nearest-neighbour rule for the whole project (r360gpu.util.resize): output pixel i takes
source pixel floor(i * n_in / n_out), what cv2.INTER_NEAREST picks.  Masks read from disk, the
report's panels and the viewer's overlays all go through it."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from r360gpu.util.resize import nearest_index, resize_nearest

SIZES = [((4, 5), (8, 10)), ((7, 3), (13, 11)), ((480, 640), (270, 360)), ((33, 67), (100, 100)),
         ((1, 1), (5, 3)), ((9, 9), (1, 1)), ((6, 8), (3, 4)), ((97, 131), (31, 17)), ((2, 1000), (3, 7))]


@pytest.mark.parametrize("src, dst", SIZES)
def test_rule_matches_opencv_inter_nearest(src, dst):
    rng = np.random.default_rng(sum(src) + sum(dst))
    m = rng.random(src) < 0.5
    ref = cv2.resize(m.astype(np.uint8), dst[::-1], interpolation=cv2.INTER_NEAREST) > 0
    assert np.array_equal(resize_nearest(m, dst), ref)
    # the same rule on a (K, H, W) stack and on an (H, W, C) image
    stack = resize_nearest(np.stack([m, ~m]), dst)
    assert np.array_equal(stack[0], ref) and np.array_equal(stack[1], ~ref)
    img = rng.integers(0, 255, (*src, 3), dtype=np.uint8)
    ref_img = cv2.resize(img, dst[::-1], interpolation=cv2.INTER_NEAREST)
    assert np.array_equal(resize_nearest(img, dst, axes=(0, 1)), ref_img)


def test_index_is_the_floor_rule_and_edges():
    assert nearest_index(4, 2).tolist() == [0, 2]  # a pixel-centre rule would pick [1, 3]
    assert nearest_index(3, 6).tolist() == [0, 0, 1, 1, 2, 2]
    a = np.zeros((3, 4), bool)
    assert resize_nearest(a, (3, 4)) is a  # already that size: no copy
    assert resize_nearest(np.zeros((0, 0, 0), bool), (3, 4)).shape == (0, 3, 4)
    with pytest.raises(ValueError, match="cannot resize"):
        resize_nearest(np.zeros((0, 5), bool), (3, 4))


def test_every_mask_resize_in_the_project_is_this_rule():
    from r360gpu.probes import precomputed
    from r360gpu.report.contact_sheets import resize_mask
    from r360gpu.viewer import frame_pictures as viewer_pictures

    assert precomputed.resize_nearest is resize_nearest
    assert viewer_pictures.resize_nearest is resize_nearest
    m = np.random.default_rng(1).random((37, 53)) < 0.3
    assert np.array_equal(resize_mask(m, (20, 11)), resize_nearest(m, (11, 20)))
