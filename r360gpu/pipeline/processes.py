"""Scoring in worker processes on this machine: the views of a scene cut into tasks, one
GPU device per worker process, no Ray needed.

A serial run overlaps its stages on threads, but the Python parts of the
probes, the measures and the pictures share one interpreter lock: on a
machine with many cores the run uses about one core's worth of them.
:class:`ProcessExecutor` (``score --processes N``) runs N worker processes
instead; per scene, as the Ray executor does (:mod:`.distributed`, whose
task function and bookkeeping it shares):

* this process opens the :class:`~.run.SceneRun` as a serial run does, so the
  probes that learn from the scene are fitted once, here;
* the views the view cache lacks are cut into chunks of consecutive views
  (ceil(views / (2 x workers)), at most 16, or ``chunk``), each scored by a
  worker with :func:`~.distributed.score_task`: the worker opens its own GPU
  device (once, on its first task) and scores the chunk without any cache.
  On a machine with two or more GPUs (or CUDA_VISIBLE_DEVICES naming them),
  the workers take them round-robin, one GPU each while there are as many
  GPUs as workers (:mod:`r360gpu.gpu.assign`);
* as chunks finish, their pictures and then their cells are written into
  ``--out`` exactly where a serial run writes them, so an interrupted run
  resumes from the view cache.

The cells are the values :func:`~.stages.score_view` computes, so the
results document equals the serial run's (``tests/test_processes.py``).
Workers are started with the ``spawn`` method: a fork of a process that
holds a GPU device and threads is not safe.  A worker that dies (killed, out
of memory) ends the run with an error naming the chunk; the chunks already
written stay in the view cache.
"""
from __future__ import annotations

import os
import shutil
import signal
import tempfile
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager

from ..errors import InputError, R360Error, WorkerLostError
from ..gpu.assign import worker_slots
from .distributed import ChunkExecutor, TaskProgress, chunk_views, score_task


def default_workers() -> int:
    """Worker processes for ``--processes auto``: one per two cores (each worker's GPU
    thread and host work), at least 1."""
    return max(1, (os.cpu_count() or 1) // 2)


@contextmanager
def _interrupts_ignored():
    """Ctrl-C ignored in this process while it starts worker processes (they start in ``submit``):
    a process started with SIGINT ignored keeps it ignored through its interpreter's start-up
    (Python installs its own handler only over the default one), so a Ctrl-C then does not end
    a worker with a traceback; :func:`_worker_start` keeps it ignored.  The window is the few
    milliseconds of the starts; a Ctrl-C outside it reaches the driver, which stops the workers."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _worker_start(threads: int, slots: list, claims: str | None) -> None:
    """In each worker, before its first task: Ctrl-C (sent to the whole process group) is the
    driver's to handle (it stops the workers itself, so a worker prints no traceback of its own);
    OpenCV's and a CPU Vulkan driver's thread pools get the worker's share of the cores
    (``threads``), not every core each, unless the environment already sizes lavapipe's.  With
    GPUs to spread over (``slots``, `r360gpu.gpu.assign.worker_slots`), the k-th worker to
    start (its claim in the folder ``claims``, `_claim`) takes slot k mod len(slots) as its
    CUDA_VISIBLE_DEVICES, which its tasks map to a wgpu adapter
    (`r360gpu.gpu.assign.worker_adapter`) and CUDA honours."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # already so when the driver started it (_interrupts_ignored)
    if slots:
        os.environ["CUDA_VISIBLE_DEVICES"] = slots[_claim(claims) % len(slots)]
    os.environ.setdefault("LP_NUM_THREADS", str(threads))  # read when the worker opens its device
    import cv2

    cv2.setNumThreads(threads)


def _claim(claims: str | None) -> int:
    """The least k whose file ``k`` this worker created first in the folder ``claims`` (O_EXCL makes
    the claim atomic across processes).  A file, not a shared counter: a counter's lock is a named
    semaphore that the driver unlinks when it exits, so a worker still starting after a Ctrl-C
    would end in a traceback while reading its arguments, before any code of ours could catch it.
    A folder already removed (the driver has stopped) gives 0: the worker is about to be stopped."""
    k = 0
    while claims is not None:
        try:
            os.close(os.open(os.path.join(claims, str(k)), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            return k
        except FileExistsError:
            k += 1
        except OSError:
            return 0
    return k


def check_workers(workers) -> int:
    """``workers`` unless it is not a whole number >= 1 (InputError): the one check of ``--processes``
    and of :class:`ProcessExecutor`."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"--processes must be at least 1, got {workers!r} (a whole number of worker "
                         f"processes, or 'auto')")
    return workers


class ProcessExecutor(ChunkExecutor):
    """Scores the uncached views of each scene in ``workers`` processes (module docstring).

    chunk: views per task (None: ceil(views / (2 x workers)), at most 16);
    adapter, on_task: as `ChunkExecutor`.  The pool is
    started on the first scene with views to score and kept for the next
    scenes; `close` stops it.
    """

    kind = "worker-process"

    def __init__(self, workers: int, *, chunk: int | None = None, adapter: str | None = None, log=print,
                 on_task=None):
        check_workers(workers)
        if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1):
            raise InputError(f"the chunk size must be at least 1, got {chunk!r} (a whole number of views)")
        super().__init__(adapter=adapter, log=log, on_task=on_task)
        self.workers = workers
        self.chunk = chunk
        self._pool = None
        self._claims = None  # the folder in which starting workers claim their GPU slots

    def _start(self):
        if self._pool is None:
            import multiprocessing

            threads = max(1, (os.cpu_count() or 1) // self.workers)
            spawn = multiprocessing.get_context("spawn")
            slots = worker_slots(self.adapter)  # the GPUs the workers take round-robin
            self._claims = tempfile.mkdtemp(prefix="r360-worker-slots-") if slots else None
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=spawn, initializer=_worker_start,
                                             initargs=(threads, slots, self._claims))
        return self._pool

    def close(self) -> None:
        """Stop the worker processes (a chunk still running is abandoned, not waited for)."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        # a process still scoring would otherwise finish its chunk after the driver has stopped
        terminate = getattr(pool, "terminate_workers", None)  # Python >= 3.14
        if terminate is not None:
            terminate()
        else:
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
        pool.shutdown(wait=True, cancel_futures=True)
        if self._claims is not None:
            shutil.rmtree(self._claims, ignore_errors=True)
            self._claims = None

    def score_scene(self, run, view_cache, sink, progress: bool) -> dict:
        """{view: ScoredView} for the views of ``run`` the view cache lacks; stored there as they arrive."""
        from concurrent.futures.process import BrokenProcessPool

        todo = self.todo(run, view_cache, sink)
        if not todo:
            return {}
        common = self.common(run, sink)
        chunks = chunk_views(todo, self.chunk_size(self.chunk, len(todo), self.workers))
        with _interrupts_ignored():
            pool = self._start()
            pending = {pool.submit(score_task, common, chunk): chunk for chunk in chunks}
        self.sent_views += [(run.bundle.name, v) for v in todo]
        where = f"in {self.workers} worker process{'es' if self.workers > 1 else ''}"
        bar = TaskProgress(run.bundle.name, where, len(chunks), len(todo), self.log, progress)
        fresh: dict = {}
        t0 = time.perf_counter()
        try:
            while pending:
                done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
                for fut in done:
                    chunk = pending.pop(fut)
                    try:
                        result = fut.result()
                    except R360Error:
                        raise
                    except BrokenProcessPool:
                        raise WorkerLostError(f"a worker process died while scoring scene {run.bundle.name} views "
                                           f"{chunk[0]}..{chunk[-1]} (killed, or out of memory); the views "
                                           "finished before are in the view cache: run again to resume") from None
                    self.take(run, view_cache, sink, result)
                    fresh.update(result["cells"])
                    bar.update(len(chunk))
        except BaseException:
            self.close()  # a driver stopping early leaves no worker behind
            raise
        finally:
            bar.close()
        run.timer.add("worker wait", t0)
        return fresh

    def describe(self) -> dict:
        """What ran where (goes into the results' timing, which a comparison of runs leaves out)."""
        return {"kind": "processes", "workers": self.workers, "tasks": self.tasks,
                "views_sent": len(self.sent_views), "adapters": sorted(self.adapters), "gpus": sorted(self.gpus)}
