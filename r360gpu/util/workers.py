"""A small pool of worker processes for host-side decoding that holds the GIL.

Some readers spend most of their time in many short numpy calls (the SAM
JSON reader: about 20 ms per 1000 x 1200 mask, in ~20 calls), which keep the
GIL held in between: two of them in threads run one after the other, and
they hold up the threads that feed the GPU.  In a worker process they run
beside the scoring process instead (bench/bench_vs_public.py).

:func:`call` runs a module-level function in a worker and returns its
result (exceptions come back as raised there).  The pool starts on first use
with the ``forkserver`` (or ``spawn``) method -- never ``fork``: the scoring
process has GPU and writer threads -- and has ``min(2, CPUs - 1)`` workers.

Both methods start each worker by importing the caller's main script again
(as ``__mp_main__``), which re-runs a script without an ``if __name__ ==
"__main__":`` guard.  So the pool is used only where that is known to be
safe: under the ``r360gpu`` command (its ``__main__`` is a package's, which
multiprocessing does not re-run; the CLI calls :func:`allow`), or when the
caller sets ``R360GPU_WORKERS=N`` itself.  Otherwise, inside a worker, with 0
workers, or with ``R360GPU_WORKERS=0`` (Ray workers set it: each already is
one process per CPU), ``call`` runs the function in this process.
"""
from __future__ import annotations

import atexit
import os
import threading

ENV_VAR = "R360GPU_WORKERS"
_pool = None
_lock = threading.Lock()
_in_worker = False
_allowed = False


def allow() -> None:
    """Let :func:`call` use worker processes by default (the CLI; see the module docstring),
    unless the main script would be re-run by them (no ``__main__`` guard)."""
    global _allowed
    _allowed = _main_is_guarded()


def _main_is_guarded() -> bool:
    import sys

    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    if spec is not None and spec.name.endswith("__main__"):
        return True  # python -m pkg: multiprocessing does not run a package's __main__ again
    path = getattr(main, "__file__", None)
    if path is None:
        return True  # interactive
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read(1 << 16)
    except OSError:
        return False
    return "__name__ == '__main__'" in text or '__name__ == "__main__"' in text


def workers() -> int:
    """How many worker processes :func:`call` may use (0: runs in this process)."""
    if _in_worker:
        return 0
    env = os.environ.get(ENV_VAR, "").strip()
    if env:
        try:
            return max(0, int(env))
        except ValueError:
            return 0
    return max(0, min(2, (os.cpu_count() or 1) - 1)) if _allowed else 0


def _mark_worker() -> None:
    global _in_worker
    _in_worker = True


def _get_pool():
    global _pool
    with _lock:
        if _pool is None:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            method = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
            _pool = ProcessPoolExecutor(max_workers=workers(), mp_context=mp.get_context(method),
                                        initializer=_mark_worker)
            atexit.register(shutdown)
        return _pool


def call(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` in a worker process (or here: see the module docstring)."""
    if workers() == 0:
        return fn(*args, **kwargs)
    return _get_pool().submit(fn, *args, **kwargs).result()


def shutdown() -> None:
    """Stop the pool (started again on the next :func:`call`)."""
    global _pool
    with _lock:
        pool, _pool = _pool, None
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)
