"""Content digests of input files, remembered so unchanged reruns do not re-read them.

A cache keyed by path, size and modification time serves stale results when
a file is replaced by other bytes of the same size with its mtime restored
(``cp -p``, ``rsync -a`` and archive tools do that).  :func:`content_digest`
hashes the bytes (BLAKE2b, about 1 GB/s) and remembers the digest under the
file's device, inode, size, mtime *and ctime*: ctime is set by the kernel
on every write or ``utime`` and cannot be restored by the user, so a
remembered digest is reused only for a file nobody has touched since.

The memory lives in the process and, within :func:`memo_file`, in a JSON
file (``r360gpu score`` keeps it in ``OUT/.r360cache``), so nothing is
written outside the output folder.
"""
from __future__ import annotations

import contextvars
import hashlib
import json
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

_CHUNK = 1 << 20
_memo: dict[str, list] = {}
_memo_path: contextvars.ContextVar[Path | None] = contextvars.ContextVar("r360gpu_hash_memo", default=None)


def _stamp(st: os.stat_result) -> list:
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


def content_digest(path: str | os.PathLike, st: os.stat_result | None = None) -> str:
    """Hex BLAKE2b-128 of the file's bytes (OSError when it cannot be read)."""
    path = os.path.abspath(os.fspath(path))
    st = st or os.stat(path)
    stamp = _stamp(st)
    hit = _memo.get(path)
    if hit is not None and hit[0] == stamp:
        return hit[1]
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    digest = h.hexdigest()
    _memo[path] = [stamp, digest]
    return digest


def forget() -> None:
    """Drop the remembered digests (tests)."""
    _memo.clear()


@contextmanager
def memo_file(path: str | os.PathLike) -> Iterator[None]:
    """Load remembered digests from ``path`` and save them back when the block ends."""
    path = Path(path)
    try:
        saved = json.loads(path.read_text(encoding="utf-8"))
        if isinstance(saved, dict):
            for k, v in saved.items():
                if isinstance(v, list) and len(v) == 2 and isinstance(v[1], str):
                    _memo.setdefault(k, v)
    except (OSError, ValueError):
        pass  # no memory yet, or a damaged one: digests are recomputed
    token = _memo_path.set(path)
    try:
        yield
    finally:
        _memo_path.reset(token)
        from .atomic import write_json

        try:
            write_json(path, _memo, indent=None)
        except OSError:
            pass  # the memory is an optimisation; the run's own writes report a full disk
