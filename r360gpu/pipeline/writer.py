"""A background writer: jobs run off the submitting thread, at most ``bound`` waiting.

Pictures and view-cache files are written here, off the GPU thread; the
bound keeps memory flat when writing is slower than scoring (the submitting
thread then waits).  With one worker (the default) jobs run in order; with
several they run at once, so each job must touch only its own files (a
view's pictures and cells).  The first error is raised again by :meth:`close`.
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor


class BackgroundWriter:
    def __init__(self, bound: int = 4, name: str = "r360-writer", workers: int = 1):
        self._pool = ThreadPoolExecutor(max_workers=max(1, int(workers)), thread_name_prefix=name)
        self._slots = threading.BoundedSemaphore(bound)
        self._futures: list = []

    def submit(self, fn, *args, **kwargs) -> None:
        self._raise_first_error(done_only=True)
        self._slots.acquire()
        try:
            fut = self._pool.submit(fn, *args, **kwargs)
        except BaseException:
            self._slots.release()
            raise
        fut.add_done_callback(lambda _: self._slots.release())
        self._futures.append(fut)

    def _raise_first_error(self, done_only: bool) -> None:
        keep = []
        for f in self._futures:
            if done_only and not f.done():
                keep.append(f)
                continue
            f.result()  # raises the job's error
        self._futures = keep

    def close(self, wait_errors: bool = True) -> None:
        """Wait for every job; raise the first error (``wait_errors=False``: cancel what has not started)."""
        if not wait_errors:
            for f in self._futures:
                f.cancel()
            self._pool.shutdown(wait=True)
            self._futures = []
            return
        try:
            self._raise_first_error(done_only=False)
        finally:
            self._pool.shutdown(wait=True, cancel_futures=True)
