"""Modules a run needs only at its end, imported on a thread while it does other work.

``scipy.stats`` (the cross-scene statistics) takes ~0.3 s to import and is
first needed after every view is scored; imported where it is used, those
0.3 s are spent on the GPU thread with the other core idle.  :class:`ImportAhead`
imports such modules on a thread of its own at the start of a run; ``wait()``
before the code that uses them (a no-op once done).

Python's per-module import locks make a second import of a module wait for
the first; an import that fails here is left for the place of use to raise.
The thread is a daemon: a Ctrl-C that lands in the main thread while it holds
an import lock can leave that lock held, and this thread then waits on it for
ever; a process exiting after the interrupt must not wait for the thread
(seen as `score` hanging at exit in about 1 of 40 Ctrl-Cs in its first second).
"""
from __future__ import annotations

import importlib
import sys
import threading

__all__ = ["ImportAhead"]


class ImportAhead:
    """Import ``modules`` (dotted names) on a thread, those not imported yet."""

    def __init__(self, *modules: str):
        todo = [m for m in modules if m not in sys.modules]
        self._thread = threading.Thread(target=self._run, args=(todo,), name="r360-imports",
                                        daemon=True) if todo else None
        if self._thread is not None:
            self._thread.start()

    @staticmethod
    def _run(modules: list[str]) -> None:
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception:  # noqa: BLE001 - raised again, with its context, where the module is used
                return

    def wait(self) -> None:
        if self._thread is not None:
            self._thread.join()
