"""Why a path cannot be read, in words: dangling symbolic links and link loops named as such.

A dangling link is listed by the folder but opening it says "No such file or
directory", and ``Path.is_file()`` is False for it, so without this check it
was reported as a missing file or as "a folder".  Every reader that turns an
OSError into an :class:`~r360gpu.errors.InputError` goes through
:func:`read_error`.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path

from ..errors import InputError


def link_problem(path: str | os.PathLike) -> str | None:
    """"symbolic link to 'T', which does not exist" (or "... a link loop") when ``path`` is a link
    that leads nowhere; None otherwise (not a link, or a link to something that exists)."""
    p = Path(path)
    try:
        if not p.is_symlink():
            return None
        target = os.readlink(p)
        p.stat()
    except OSError as e:
        if e.errno == errno.ELOOP:
            return f"symbolic link loop (through {os.readlink(p)!r})"
        try:
            return f"symbolic link to {os.readlink(p)!r}, which does not exist"
        except OSError:
            return "symbolic link that leads nowhere"
    except ValueError:
        return None
    del target
    return None


def read_error(e: OSError, path: str | os.PathLike, what: str = "file") -> InputError:
    """The InputError of an OSError met reading ``path`` (a broken link named as one)."""
    problem = link_problem(path)
    if problem is None and e.errno == errno.ELOOP:
        problem = "symbolic link loop"
    if problem is None:
        problem = e.strerror or str(e)
    return InputError(f"cannot read {what}: {problem}", path)
