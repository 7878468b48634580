"""Precomputed masks per method: post/METHOD/ folders and post/METHOD=DIR specs."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.probes.base import ProbeView
from r360gpu.probes.registry import parse_probe_spec


def _png(path, rows):
    path.parent.mkdir(parents=True, exist_ok=True)
    m = np.zeros((6, 8), np.uint8)
    m[rows] = 255
    assert cv2.imwrite(str(path), m)


@pytest.fixture
def masks_dir(tmp_path):
    _png(tmp_path / "pre" / "v0.png", slice(0, 1))
    _png(tmp_path / "post" / "v0.png", slice(1, 2))  # plain post: methods without their own folder
    _png(tmp_path / "post" / "clean" / "v0.png", slice(2, 3))
    return tmp_path


def _row(pred):
    return int(np.flatnonzero(pred.union().any(1))[0])


def test_method_folders_win_over_plain_post(masks_dir):
    probe = parse_probe_spec(f"png:{masks_dir}")
    view = lambda r, m=None: ProbeView("v0", size=(6, 8), rendering=r, method=m)  # noqa: E731
    assert _row(probe.predict([view("pre")], "x")[0]) == 0
    assert _row(probe.predict([view("post", "clean")], "x")[0]) == 2
    assert _row(probe.predict([view("post", "other")], "x")[0]) == 1
    assert _row(probe.predict([view("post")], "x")[0]) == 1


def test_explicit_per_method_spec(masks_dir):
    probe = parse_probe_spec(f"png:pre={masks_dir / 'pre'},post/Clean-1={masks_dir / 'post' / 'clean'}")
    assert _row(probe.predict([ProbeView("v0", size=(6, 8), rendering="post", method="Clean-1")], "x")[0]) == 2
    with pytest.raises(InputError, match="no precomputed masks for the 'post'"):
        probe.predict([ProbeView("v0", size=(6, 8), rendering="post", method="other")], "x")
