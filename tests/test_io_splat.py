"""The .splat format reader and writer."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.gaussians import Gaussians, random_gaussians
from r360gpu.io.sh import C0
from r360gpu.io.splat import load_splat, save_splat


def _record(pos=(0, 0, 0), scale=(1, 1, 1), rgba=(128, 128, 128, 255), rot=(255, 128, 128, 128)) -> bytes:
    """One 32-byte record written by hand (independent of r360gpu's writer)."""
    return (np.array(pos, "<f4").tobytes() + np.array(scale, "<f4").tobytes()
            + bytes(rgba) + bytes(rot))


def test_hand_made_record_decodes_by_the_documented_rules(tmp_path):
    p = tmp_path / "a.splat"
    p.write_bytes(_record((1, -2, 3.5), (0.1, 2, 3), (255, 0, 51, 204), (128, 255, 128, 0))
                  + _record())
    g = load_splat(p)
    assert g.n == 2 and g.sh_degree == 0
    np.testing.assert_array_equal(g.means[0], np.array([1, -2, 3.5], np.float32))
    np.testing.assert_array_equal(g.scales[0], np.array([0.1, 2, 3], np.float32))
    np.testing.assert_allclose(g.sh[0, 0], [0.5 / C0, -0.5 / C0, (0.2 - 0.5) / C0], rtol=1e-6)
    np.testing.assert_allclose(g.opacities[0], 0.8, rtol=1e-6)
    q = np.array([0, 127 / 128, 0, -1])  # (byte - 128) / 128, then normalised
    np.testing.assert_allclose(g.quats[0], q / np.linalg.norm(q), rtol=1e-6)
    np.testing.assert_allclose(g.quats[1], [1, 0, 0, 0], atol=1e-7)


def test_round_trip_within_documented_bounds(tmp_path):
    g = random_gaussians(500, 0, seed=7)
    save_splat(tmp_path / "s.splat", g)
    h = load_splat(tmp_path / "s.splat")
    assert h.n == g.n
    np.testing.assert_array_equal(h.means, g.means)
    np.testing.assert_array_equal(h.scales, g.scales)
    inside = np.abs(g.sh[:, 0]) <= 0.5 / C0  # colour within [0, 1]
    err = np.abs(h.sh[:, 0] - g.sh[:, 0])
    assert (err[inside] <= 1 / (2 * 255 * C0) + 1e-6).all()
    clipped = np.clip(0.5 + C0 * g.sh[:, 0].astype(np.float64), 0, 1)
    np.testing.assert_allclose(h.sh[:, 0], (np.round(clipped * 255) / 255 - 0.5) / C0, atol=1e-6)
    assert np.abs(h.opacities - g.opacities).max() <= 1 / 510 + 1e-7
    assert np.linalg.norm(h.quats - g.quats, axis=1).max() <= math.sqrt(7) / 128


def test_quaternion_component_of_one_is_clipped(tmp_path):
    g = random_gaussians(2, 0)
    g = Gaussians(g.means, g.scales, np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0]]), g.opacities, g.sh)
    save_splat(tmp_path / "s.splat", g)
    raw = np.frombuffer((tmp_path / "s.splat").read_bytes(), np.uint8).reshape(2, 32)
    assert raw[0, 28:].tolist() == [255, 128, 128, 128] and raw[1, 28:].tolist() == [128, 128, 0, 128]
    np.testing.assert_allclose(load_splat(tmp_path / "s.splat").quats, g.quats, atol=1e-7)


def test_writer_discards_higher_sh_with_warning(tmp_path):
    g = random_gaussians(5, 2)
    with pytest.warns(R360Warning, match="discarding degree 1..2"):
        save_splat(tmp_path / "s.splat", g)
    assert load_splat(tmp_path / "s.splat").sh_degree == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        save_splat(tmp_path / "t.splat", g.with_sh_degree(0))


def test_truncated_and_empty(tmp_path):
    p = tmp_path / "a.splat"
    p.write_bytes(_record() * 3 + b"\x00" * 7)
    with pytest.raises(InputError, match="103 bytes is not a multiple") as e:
        load_splat(p)
    assert "a.splat" in str(e.value)
    p.write_bytes(b"")
    with pytest.raises(InputError, match="empty"):
        load_splat(p)
    with pytest.raises(InputError, match="cannot read"):
        load_splat(tmp_path / "missing.splat")


def test_bad_records_dropped_with_one_warning(tmp_path):
    p = tmp_path / "a.splat"
    p.write_bytes(_record() + _record(rot=(128, 128, 128, 128)) + _record(scale=(1, -1, 1))
                  + _record(scale=(1, 0, 1)) + _record(pos=(math.inf, 0, 0)) + _record(pos=(2, 0, 0)))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        g = load_splat(p)
    msgs = [str(w.message) for w in rec if issubclass(w.category, R360Warning)]
    assert len(msgs) == 1
    assert "dropped 4 of 6" in msgs[0] and "1 with zero quaternion" in msgs[0]
    assert "2 with non-positive scale" in msgs[0] and "1 with NaN/Inf" in msgs[0]
    np.testing.assert_array_equal(g.means[:, 0], [0, 2])
