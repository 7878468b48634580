"""report.png: PNGs that decode to exactly the input, with either deflate library."""
from __future__ import annotations

import zlib

import cv2
import numpy as np
import pytest

from r360gpu.report import png


@pytest.mark.parametrize("deflate", ["default", "zlib"])
@pytest.mark.parametrize("shape", [(1, 1, 3), (1, 1), (2, 3, 3), (17, 5), (64, 97, 3), (300, 1, 3)])
def test_png_decodes_to_the_input(deflate, shape):
    rng = np.random.default_rng(sum(shape))
    img = rng.integers(0, 256, shape, dtype=np.uint8)
    img[: shape[0] // 2] = 255  # flat rows (long matches) and noise (none)
    data = png.encode(img, deflate=zlib if deflate == "zlib" else None)
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data.endswith(b"IEND\xaeB`\x82")
    got = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    want = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    np.testing.assert_array_equal(got, want)
    assert png.encode(img, deflate=zlib if deflate == "zlib" else None) == data  # deterministic


def test_png_chunks_carry_their_crc():
    data = png.encode(np.arange(12, dtype=np.uint8).reshape(2, 2, 3))
    pos = 8
    kinds = []
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        assert int.from_bytes(data[pos + 8 + n : pos + 12 + n], "big") == zlib.crc32(kind + body)
        kinds.append(kind)
        pos += 12 + n
    assert kinds == [b"IHDR", b"IDAT", b"IEND"]


@pytest.mark.parametrize("bad", [np.zeros((2, 2), np.float32), np.zeros((2, 2, 4), np.uint8),
                                 np.zeros((0, 3, 3), np.uint8), np.zeros(5, np.uint8)])
def test_png_refuses_other_arrays(bad):
    with pytest.raises(ValueError, match="PNG"):
        png.encode(bad)
