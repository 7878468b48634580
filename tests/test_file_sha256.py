"""`file_sha256` (the model hashes probes and LPIPS record) hashes a file in blocks exactly as one
sha256 of its bytes, and an unreadable file is an InputError naming it."""
from __future__ import annotations

import hashlib

import pytest

from r360gpu.errors import InputError
from r360gpu.util.filehash import file_sha256


@pytest.mark.parametrize("size", [0, 1, (1 << 20) - 1, 1 << 20, (1 << 20) + 7])  # around the block size
def test_digest_is_the_sha256_of_the_bytes(tmp_path, size):
    data = bytes((i * 131 + 7) % 251 for i in range(size))
    p = tmp_path / "model.onnx"
    p.write_bytes(data)
    assert file_sha256(p) == hashlib.sha256(data).hexdigest()


def test_unreadable_file_names_itself(tmp_path):
    missing = tmp_path / "absent.onnx"
    with pytest.raises(InputError, match="absent.onnx"):
        file_sha256(missing)
    with pytest.raises(InputError, match="cannot read model file"):
        file_sha256(tmp_path)  # a folder
