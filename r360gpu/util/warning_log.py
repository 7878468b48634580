"""One collector for every warning of a run: printed once on stderr, recorded for results.json.

Every layer warns the same way: :func:`warn` (or, in modules that predate
this one, ``warnings.warn(..., R360Warning)`` with a message that starts with
``"FILE: "``).  While a :func:`collecting` block is active (``r360gpu score``
and ``demo`` open one around the whole run), each distinct warning is printed
once on stderr as ``r360gpu: warning: ...`` and kept as an object with the
keys ``scene``, ``method``, ``view``, ``file`` and ``message``; the pipeline
says where it is with :func:`where`, so a warning raised deep in a reader
still names the scene, method and view it concerns.  Outside a
:func:`collecting` block, :func:`warn` is an ordinary ``R360Warning`` (library
use keeps Python's warning machinery).

Counters (:func:`count`) are for events that are warned once and then only
counted (e.g. missing probe files): they land in ``results.json`` beside the
warnings.
"""
from __future__ import annotations

import contextvars
import os
import re
import sys
import threading
import warnings
from contextlib import contextmanager
from typing import Iterator, TextIO

from ..errors import R360Warning

KEYS = ("scene", "method", "view", "file", "message")

_log: contextvars.ContextVar["WarningLog | None"] = contextvars.ContextVar("r360gpu_warning_log", default=None)
_where: contextvars.ContextVar[dict] = contextvars.ContextVar("r360gpu_warning_where", default={})
# "path: message" as the readers format their warnings; the path has no ": " in it.
_FILE_PREFIX = re.compile(r"^(?P<file>[^\n]+?): (?P<message>.+)$", re.S)


class WarningLog:
    """The warnings of one run, in the order they were first raised."""

    def __init__(self, stream: TextIO | str | None = None):
        self.stream = stream
        self._records: list[dict] = []
        self._seen: set[tuple] = set()
        self.counts: dict[str, dict[str, int]] = {}
        self.done: set = set()
        # What each (scene, view) added, for the view cache (see for_view); stages of
        # different views run on different threads at once.
        self.by_view: dict[tuple, dict] = {}
        self._lock = threading.RLock()

    def add(self, message: str, *, scene=None, method=None, view=None, file=None) -> bool:
        """Record (and print) a warning unless the same one was recorded already; True when new."""
        rec = {"scene": scene, "method": method, "view": view,
               "file": None if file is None else os.fspath(file), "message": str(message)}
        key = tuple(rec[k] for k in KEYS)
        with self._lock:
            if key in self._seen:
                return False
            self._seen.add(key)
            self._records.append(rec)
            if view is not None:
                self._view_entry(scene, view)["records"].append(dict(rec))
        if self.stream is not None:
            stream = sys.stderr if self.stream == "stderr" else self.stream  # (the current one: tests swap it)
            print(f"r360gpu: warning: {format_record(rec)}", file=stream, flush=True)
        return True

    def count(self, kind: str, key: str, n: int = 1, *, scene=None, view=None) -> None:
        with self._lock:
            d = self.counts.setdefault(kind, {})
            d[key] = d.get(key, 0) + n
            if view is not None:
                vc = self._view_entry(scene, view)["counts"].setdefault(kind, {})
                vc[key] = vc.get(key, 0) + n

    def _view_entry(self, scene, view) -> dict:
        return self.by_view.setdefault((scene, view), {"records": [], "counts": {}})

    def records(self) -> list[dict]:
        return [dict(r) for r in self._records]


def format_record(rec: dict) -> str:
    """One line: ``FILE: message (scene S, method M, view V)``."""
    where = ", ".join(f"{k} {rec[k]}" for k in ("scene", "method", "view") if rec.get(k))
    head = f"{rec['file']}: " if rec.get("file") else ""
    return head + rec["message"] + (f" ({where})" if where else "")


def active() -> WarningLog | None:
    """The collector of the current run, or None."""
    return _log.get()


def warn(message: str, *, file=None, **where) -> None:
    """Warn about a doubtful but usable input.  ``where`` (scene, method, view) overrides the
    location set by :func:`where`."""
    log = _log.get()
    loc = {**_where.get(), **{k: v for k, v in where.items() if v is not None}}
    if log is None:
        head = f"{os.fspath(file)}: " if file is not None else ""
        warnings.warn(head + message, R360Warning, stacklevel=2)
        return
    log.add(message, file=file, **{k: loc.get(k) for k in ("scene", "method", "view")})


def count(kind: str, key: str, n: int = 1) -> None:
    """Count an event (no-op outside a run), attributed to the scene and view set by :func:`where`."""
    log = _log.get()
    if log is not None:
        loc = _where.get()
        log.count(kind, str(key), n, scene=loc.get("scene"), view=loc.get("view"))


def for_view(scene, view) -> dict:
    """The warnings and counts raised while ``where(scene=..., view=...)`` named this view
    ({"records": [...], "counts": {...}}), to store with its cached result and :func:`replay`
    when the cache serves it.  Safe while other views' stages run on other threads."""
    log = _log.get()
    if log is None:
        return {"records": [], "counts": {}}
    with log._lock:
        e = log.by_view.get((scene, view)) or {"records": [], "counts": {}}
        return {"records": [dict(r) for r in e["records"]],
                "counts": {k: dict(v) for k, v in e["counts"].items()}}


_done_outside_runs: set = set()


def seen(key) -> bool:
    """Whether ``key`` was already marked by :func:`once` in the current run (marks nothing)."""
    log = _log.get()
    return key in (_done_outside_runs if log is None else log.done)


def once(key) -> bool:
    """True the first time ``key`` is seen in the current run (for checks that run once per source)."""
    log = _log.get()
    done = _done_outside_runs if log is None else log.done
    if key in done:
        return False
    done.add(key)
    return True


def mark() -> tuple[int, dict]:
    """A position in the current run's log, for :func:`since`."""
    log = _log.get()
    if log is None:
        return 0, {}
    return len(log._records), {k: dict(v) for k, v in log.counts.items()}


def since(position: tuple[int, dict]) -> dict:
    """The warnings and counts added after ``position`` ({"records": [...], "counts": {...}}), to store
    with a cached result and :func:`replay` when the cache serves it."""
    log = _log.get()
    if log is None:
        return {"records": [], "counts": {}}
    n, before = position
    delta: dict = {}
    for kind, d in log.counts.items():
        for key, v in d.items():
            dv = v - before.get(kind, {}).get(key, 0)
            if dv:
                delta.setdefault(kind, {})[key] = dv
    return {"records": log.records()[n:], "counts": delta}


def replay(saved) -> None:
    """Re-add what :func:`since` returned (a cached view's warnings are part of the run's too)."""
    log = _log.get()
    if log is None or not isinstance(saved, dict):
        return
    for rec in saved.get("records") or []:
        if isinstance(rec, dict) and "message" in rec:
            log.add(rec["message"], **{k: rec.get(k) for k in ("scene", "method", "view", "file")})
    for kind, d in (saved.get("counts") or {}).items():
        for key, v in d.items():
            log.count(kind, key, int(v))


def records() -> list[dict]:
    """The warnings recorded so far in the current run ([] outside one)."""
    log = _log.get()
    return [] if log is None else log.records()


def counts() -> dict:
    log = _log.get()
    return {} if log is None else {k: dict(v) for k, v in log.counts.items()}


@contextmanager
def where(**loc) -> Iterator[None]:
    """Within the block, warnings are attributed to ``scene`` / ``method`` / ``view``."""
    token = _where.set({**_where.get(), **{k: v for k, v in loc.items() if v is not None}})
    try:
        yield
    finally:
        _where.reset(token)


@contextmanager
def collecting(stream: TextIO | str | None = "stderr") -> Iterator[WarningLog]:
    """Collect every warning raised in the block (nested blocks share the outer collector).

    ``R360Warning`` raised with ``warnings.warn`` are routed here too: a
    message ``"FILE: text"`` becomes ``file=FILE``.  Other warnings keep
    Python's handling.
    """
    outer = _log.get()
    if outer is not None:
        yield outer
        return
    log = WarningLog(stream)
    token = _log.set(log)
    with warnings.catch_warnings():
        previous = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, R360Warning):
                _add_python_warning(log, str(message))
            else:
                previous(message, category, filename, lineno, file, line)

        warnings.simplefilter("always", R360Warning)
        warnings.showwarning = show
        try:
            yield log
        finally:
            _log.reset(token)


def _add_python_warning(log: WarningLog, text: str) -> None:
    loc = _where.get()
    m = _FILE_PREFIX.match(text)
    file, message = (m.group("file"), m.group("message")) if m and _looks_like_path(m.group("file")) else (None, text)
    log.add(message, file=file, **{k: loc.get(k) for k in ("scene", "method", "view")})


def _looks_like_path(s: str) -> bool:
    return ("/" in s or "\\" in s or "." in s) and " " not in s.strip()[:1]
