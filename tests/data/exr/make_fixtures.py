"""Regenerate the EXR fixtures of tests/test_io_renders.py with the official OpenEXR bindings.

Run with a Python that has ``pip install openexr numpy`` (r360gpu itself does not
need them): ``python tests/data/exr/make_fixtures.py``.  The files are written by
an independent EXR implementation so that r360gpu's own reader
(r360gpu/io/exr.py) is checked against it, not against itself.  ``expected.npz``
holds, per file, the array each channel was written from (float16 and uint32
values as written).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenEXR

HERE = Path(__file__).resolve().parent
H, W = 23, 37  # 23 rows: ZIP's 16-line blocks end in a partial block


def _depth(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:H, 0:W]
    d = 1.5 + 0.05 * x + 0.02 * y + 0.01 * rng.standard_normal((H, W))
    d[:4, :6] = 0.0  # no coverage
    return d.astype(np.float32)


def _write(name: str, channels: dict[str, np.ndarray], compression, expected: dict) -> None:
    for ch, arr in channels.items():
        expected[f"{name}:{ch}"] = arr.copy()
    header = {"compression": compression, "type": OpenEXR.scanlineimage}
    # OpenEXR.File replaces the dict's values by Channel objects: pass a copy.
    with OpenEXR.File(header, dict(channels)) as f:
        f.write(str(HERE / name))


def main() -> None:
    expected: dict[str, np.ndarray] = {}
    d = _depth(0)
    for tag, comp in (("none", OpenEXR.NO_COMPRESSION), ("rle", OpenEXR.RLE_COMPRESSION),
                      ("zips", OpenEXR.ZIPS_COMPRESSION), ("zip", OpenEXR.ZIP_COMPRESSION)):
        _write(f"z_float_{tag}.exr", {"Z": d}, comp, expected)
    _write("z_half_zip.exr", {"Z": d.astype(np.float16)}, OpenEXR.ZIP_COMPRESSION, expected)
    _write("z_half_rle.exr", {"Z": d.astype(np.float16)}, OpenEXR.RLE_COMPRESSION, expected)
    grey = d.astype(np.float16)
    _write("rgb_half_zip.exr", {"R": grey, "G": grey, "B": grey}, OpenEXR.ZIP_COMPRESSION, expected)
    noise = np.random.default_rng(1).uniform(0.1, 100.0, (H, W)).astype(np.float32)
    _write("z_float_zip_noise.exr", {"Z": noise}, OpenEXR.ZIP_COMPRESSION, expected)
    _write("z_uint_zips.exr", {"Z": (d * 1000).astype(np.uint32)}, OpenEXR.ZIPS_COMPRESSION, expected)
    _write("rg_float_zip.exr", {"R": d, "G": d + 1.0}, OpenEXR.ZIP_COMPRESSION, expected)
    _write("z_float_piz.exr", {"Z": d}, OpenEXR.PIZ_COMPRESSION, expected)
    np.savez(HERE / "expected.npz", **expected)


if __name__ == "__main__":
    main()
