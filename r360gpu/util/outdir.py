"""The output folder of a run: checked before any work, locked while the run writes to it.

:func:`open_output_folder` is the first thing ``r360gpu score`` and
``demo`` do: it refuses (``InputError`` naming the path) an ``--out`` that is
a file or cannot be created or written, takes the folder's lock, and removes
the temporaries a killed run left behind.  The lock is ``OUT/.r360lock``
holding the holder's pid, host and start time; it is an advisory ``flock``,
which the kernel drops when the holding process dies, so a lock left by a
killed run is simply taken over.  A second run on the same folder is refused
with a message naming the holder.
"""
from __future__ import annotations

import errno
import json
import os
import socket
import time
from pathlib import Path

from ..errors import InputError
from .atomic import remove_stale_temporaries

LOCK_NAME = ".r360lock"

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: O_EXCL lock file, dead holders detected by pid
    fcntl = None


class OutputLock:
    """A held lock on an output folder; :meth:`release` (or ``with``) gives it back."""

    def __init__(self, path: Path, fd: int):
        self.path = path
        self._fd = fd

    def release(self) -> None:
        if self._fd is None:
            return
        # The file stays (unlinking it would let a run that opened it just before lock a dead inode
        # while a third run locks a new file); an empty file is a free lock.
        try:
            os.ftruncate(self._fd, 0)
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> "OutputLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def check_output_folder(out: str | os.PathLike) -> Path:
    """``out`` as a Path, refusing what cannot be an output folder before any work is done."""
    if not os.fspath(out).strip():  # Path("") is ".": the outputs would land in the current folder
        raise InputError("--out is empty; give the output folder (e.g. --out results)")
    out = Path(out)
    for parent in [out, *out.parents]:
        if parent.is_symlink() and not parent.exists():  # mkdir would say "File exists"
            raise InputError(f"--out: {parent} is a symbolic link to {os.readlink(parent)!r}, which does not "
                             f"exist (or is a link loop)", out)
        if parent.exists():
            if parent == out and not out.is_dir():
                raise InputError("--out must be a folder, but this is an existing file", out)
            if not parent.is_dir():
                raise InputError(f"--out: {parent} is a file, not a folder", out)
            break
    return out


def open_output_folder(out: str | os.PathLike) -> OutputLock:
    """Create ``out`` if needed, take its lock and remove stale temporaries; returns the lock."""
    out = check_output_folder(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create the output folder: {os_error_reason(e)}", out) from None
    lock = _acquire(out / LOCK_NAME)
    try:
        remove_stale_temporaries(out)
    except OSError as e:
        lock.release()
        raise InputError(f"cannot clean the output folder: {os_error_reason(e)}", out) from None
    return lock


def os_error_reason(e: OSError) -> str:
    if e.errno == errno.EROFS:
        return "read-only file system"
    if e.errno == errno.ENOSPC:
        return "no space left on device"
    return e.strerror or str(e)


def _holder_text(info: dict) -> str:
    started = info.get("started")
    when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(started)) if isinstance(started, (int, float)) else "?"
    return f"pid {info.get('pid', '?')} on {info.get('host', '?')}, started {when}"


def _read_info(path: Path) -> dict:
    try:
        info = json.loads(path.read_text(encoding="utf-8") or "{}")
        return info if isinstance(info, dict) else {}
    except (OSError, ValueError):
        return {}


def _acquire(path: Path) -> OutputLock:
    info = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()}
    try:
        if fcntl is not None:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as e:
                os.close(fd)
                if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise InputError(f"another r360gpu run is writing to this folder ({_holder_text(_read_info(path))}); "
                                     f"wait for it to finish or use another --out", path.parent) from None
                raise
        else:  # pragma: no cover
            fd = _acquire_exclusive(path)
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps(info).encode())
        os.fsync(fd)
    except InputError:
        raise
    except OSError as e:
        raise InputError(f"cannot write to the output folder: {os_error_reason(e)}", path.parent) from None
    return OutputLock(path, fd)


def _acquire_exclusive(path: Path) -> int:  # pragma: no cover - Windows only
    for _ in range(2):
        try:
            return os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            info = _read_info(path)
            if info.get("host") == socket.gethostname() and not _alive(info.get("pid")):
                os.unlink(path)
                continue
            raise InputError(f"another r360gpu run is writing to this folder ({_holder_text(info)}); wait for it "
                             f"to finish or use another --out (remove {path} if that run is gone)",
                             path.parent) from None
    raise InputError("cannot take the output folder's lock", path.parent)


def _alive(pid) -> bool:  # pragma: no cover - Windows only
    if not isinstance(pid, int):
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True
