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

Hash while reading: the readers of every input r360gpu decodes (renderings,
depth, masks, splat files) get the bytes through :func:`read_file`, which
hashes exactly the bytes it returns and remembers that digest
(:func:`decoded_digest`).  A result is cached only when the bytes decoded
for it are the bytes its cache key was computed from
(:func:`r360gpu.pipeline.cache.ViewCache.store_view`): a file replaced
while a run reads it, and even restored afterwards, cannot leave a result
of the other bytes under the original bytes' key.  A file that did not
change while it was read (and is older than 2 s, see ``_SETTLED_NS``) also
has its digest remembered for the next run's key, so an input read for
scoring is not read again to be hashed.
"""
from __future__ import annotations

import contextvars
import hashlib
import json
import os
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..errors import InputError

_CHUNK = 1 << 20
_memo: dict[str, list] = {}
_decoded: dict[str, str] = {}  # absolute path -> digest of the bytes read_file last returned
_lock = threading.Lock()
_memo_path: contextvars.ContextVar[Path | None] = contextvars.ContextVar("r360gpu_hash_memo", default=None)


def _stamp(st: os.stat_result) -> list:
    return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]


# A digest is remembered only for a file whose ctime is older than this: file systems stamp times
# from a coarse clock (a few ms), so two writes of the same size in one tick leave the same stamp
# (git's "racily clean" entries, handled the same way).
_SETTLED_NS = 2_000_000_000


def _settled(st: os.stat_result) -> bool:
    return time.time_ns() - st.st_ctime_ns > _SETTLED_NS


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
    if _settled(st):
        _memo[path] = [stamp, digest]
    return digest


def read_file(path: str | os.PathLike) -> bytes:
    """Every byte of the file, read once and hashed as read (OSError when it cannot be read).

    The digest of the bytes returned is what :func:`decoded_digest` gives for the path afterwards
    (the last read wins); when the file's identity and times are the same after the read as before,
    it is also remembered as the file's content digest (:func:`content_digest`).  A file whose
    content digest is remembered under those same identity and times (a run keys its inputs
    before decoding them) is not hashed a second time: its bytes are the ones that digest was taken
    of, as :func:`content_digest` itself trusts (a write changes the ctime)."""
    key = os.path.abspath(os.fspath(path))
    with open(key, "rb") as f:
        before = os.fstat(f.fileno())
        data = f.read()
    try:
        after = os.stat(key)
    except OSError:
        after = None
    same = after is not None and _stamp(before) == _stamp(after) and after.st_size == len(data)
    hit = _memo.get(key) if same else None
    if hit is not None and hit[0] == _stamp(after):
        digest = hit[1]
    else:
        digest = hashlib.blake2b(data, digest_size=16).hexdigest()
        if same and _settled(after):
            _memo[key] = [_stamp(after), digest]
    with _lock:
        _decoded[key] = digest
    return data


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes (for the model hashes in ``describe()``).

    Raises InputError naming the file when it cannot be read.
    """
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    except OSError as exc:
        raise InputError(f"cannot read model file ({exc.strerror or exc})", path) from None
    return digest.hexdigest()


def file_stamp(path: str | os.PathLike) -> list | None:
    """[inode, size, mtime_ns, ctime_ns] of a file or folder, None when there is none.

    For inputs that are not hashed (precomputed probe files, read in full only when a view is
    scored): equal stamps taken before a read and later mean the bytes did not change in between,
    since every write sets the ctime and nobody can set it back.  The device number is left out:
    shared storage mounted on several machines gives one file several device numbers.  A stamp
    proves that only when it is settled (:func:`stamp_settled`)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return _stamp(st)[1:]


#: What :func:`input_stamp` gives for a file written too recently for its stamp to prove anything.
UNSETTLED = "unsettled"


def input_stamp(path: str | os.PathLike) -> list | None | str:
    """:func:`file_stamp` of an input about to be read, or :data:`UNSETTLED` when its ctime is within
    the file system clock's coarseness (``_SETTLED_NS``) of now: a second write in the same clock
    tick could leave the same stamp (git's "racily clean" entries), so what is read from such a
    file is not cached."""
    stamp = file_stamp(path)
    if stamp is not None and time.time_ns() - stamp[3] <= _SETTLED_NS:
        return UNSETTLED
    return stamp


def changed_stamps(stamps: dict) -> list[str]:
    """The paths of ``stamps`` ({path: :func:`input_stamp` taken before reading}) that are unsettled
    or whose file's stamp is another now: what was read from them may not be what is there."""
    return [p for p, s in stamps.items() if s == UNSETTLED or file_stamp(p) != s]


def decoded_digest(path: str | os.PathLike) -> str | None:
    """The digest of the bytes :func:`read_file` last returned for ``path`` in this process (None: not
    read through it)."""
    with _lock:
        return _decoded.get(os.path.abspath(os.fspath(path)))


def decoded_digests(paths) -> dict[str, str]:
    """{absolute path: digest} of those of ``paths`` read through :func:`read_file` in this process."""
    with _lock:
        found = ((os.path.abspath(os.fspath(p)), None) for p in paths)
        return {k: _decoded[k] for k, _ in found if k in _decoded}


def forget_decoded(paths) -> None:
    """Drop what :func:`read_file` remembered of ``paths`` (a new run: what an earlier one decoded
    is not what this one decodes)."""
    with _lock:
        for p in paths:
            _decoded.pop(os.path.abspath(os.fspath(p)), None)


def forget() -> None:
    """Drop the remembered digests (tests)."""
    _memo.clear()
    with _lock:
        _decoded.clear()


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
