"""Atomic file writes: write to a temporary file beside the target, then rename.

A crash or Ctrl-C never leaves a half-written result behind.  Temporary
files are named ``.NAME.<random>.tmp`` (mkstemp); a SIGKILL between the write and the
rename leaves one, which :func:`remove_stale_temporaries` deletes (the CLI
calls it once it holds the output folder's lock).  Inside an
:func:`all_or_nothing` block, writes to the named files are kept as
temporaries and renamed into place only when the block ends without error,
so a run that cannot write every output (disk full, read-only file system)
leaves the previous set, or none, instead of half of each.

Results are also flushed to disk (fsync) before the rename, so they survive
a power loss.  Files that are regenerated when damaged -- pictures, cache
entries -- are written with ``sync=False``: the rename still keeps a crashed
or interrupted process from leaving half of one, and a run's hundreds of
them do not wait for the disk one by one.
"""
from __future__ import annotations

import contextvars
import json
import os
import re
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator


# Target paths (resolved) whose rename is deferred to the end of an all_or_nothing block -> pending renames.
_staged: contextvars.ContextVar[tuple[frozenset, list] | None] = contextvars.ContextVar("r360gpu_staged",
                                                                                       default=None)
_TMP_NAME = re.compile(r"^\..+\.[A-Za-z0-9_]{8}\.tmp$")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", *, sync: bool = True, **kwargs) -> Iterator[IO]:
    """Open a temporary file for writing; on success it replaces ``path`` (after an fsync unless
    ``sync`` is False: see the module docstring)."""
    if not any(c in mode for c in "wx"):
        raise ValueError("atomic_open is for writing")
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise _naming(e, path) from None
    # mkstemp creates 0600; give the result the mode a plain open() would.
    os.chmod(tmp, 0o666 & ~_umask())
    try:
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            if sync:
                f.flush()
                os.fsync(f.fileno())
        staged = _staged.get()
        if staged is not None and path.resolve() in staged[0]:
            staged[1].append((tmp, path))
        else:
            os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError) and e.filename is None:  # a failed write (ENOSPC) names no file
            raise _naming(e, path) from None
        raise


def _naming(e: OSError, path: Path) -> OSError:
    """``e`` naming the target ``path`` (not the temporary), as OSError(errno, strerror, filename)."""
    return OSError(e.errno, e.strerror or str(e), os.fspath(path))


def write_bytes(path: str | os.PathLike, data: bytes, *, sync: bool = True) -> None:
    with atomic_open(path, "wb", sync=sync) as f:
        f.write(data)


def write_text(path: str | os.PathLike, text: str, *, sync: bool = True) -> None:
    with atomic_open(path, "w", sync=sync, encoding="utf-8") as f:
        f.write(text)


def write_json(path: str | os.PathLike, obj, *, sync: bool = True, **kwargs) -> None:
    kwargs.setdefault("indent", 2)
    with atomic_open(path, "w", sync=sync, encoding="utf-8") as f:
        json.dump(obj, f, **kwargs)
        f.write("\n")


@contextmanager
def all_or_nothing(paths) -> Iterator[None]:
    """Writes (through this module) to ``paths`` inside the block become visible together at its end.

    When the block raises, none of them replaces its previous version and
    every temporary is removed.  Other files are written as usual.
    """
    targets = frozenset(Path(p).resolve() for p in paths)
    pending: list[tuple[str, Path]] = []
    token = _staged.set((targets, pending))
    try:
        yield
    except BaseException:
        for tmp, _ in pending:
            _unlink(tmp)
        raise
    finally:
        _staged.reset(token)
    for i, (tmp, path) in enumerate(pending):
        try:
            os.replace(tmp, path)
        except BaseException:
            for t, _ in pending[i:]:
                _unlink(t)
            raise


def _unlink(p) -> None:
    try:
        os.unlink(p)
    except FileNotFoundError:
        pass


def is_temporary(name: str) -> bool:
    """Whether a file name is one of :func:`atomic_open`'s temporaries."""
    return bool(_TMP_NAME.match(name))


def remove_stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Delete the temporaries a killed writer left under ``folder`` (recursively); returns them.

    Only call it while no other writer uses the folder (under its lock).
    """
    removed = []
    for dirpath, _dirs, files in os.walk(folder):
        for name in files:
            if is_temporary(name):
                p = Path(dirpath) / name
                _unlink(p)
                removed.append(p)
    return removed
