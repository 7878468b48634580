"""Ctrl-C raised only where it cannot leave an import half done.

Python raises KeyboardInterrupt in the main thread between any two bytecodes,
import machinery included.  Landing inside `importlib._bootstrap` (taking or
releasing a module's lock, or in the weak-reference callback that drops one) it
can leave a module lock held or its bookkeeping half updated; a thread importing
the same module then waits for ever.  r360gpu imports on threads while the main
thread works (`r360gpu.util.imports.ImportAhead`, the GPU context opened ahead),
so a Ctrl-C in a command's first second could hang the process instead of
stopping it (about 1 in 40 interrupts on a loaded 2-core machine).

`install` replaces the default SIGINT handler of the command-line process: an
interrupt that arrives while the main thread is inside an import is sent again
`RETRY_S` later, until it lands outside one, where it raises KeyboardInterrupt
as the default handler does.
"""
from __future__ import annotations

import os
import signal
import threading

__all__ = ["RETRY_S", "install"]

#: Seconds after which an interrupt that arrived inside an import is sent again.
RETRY_S = 0.05
_IMPORT_CODE = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")


def _in_import(frame) -> bool:
    while frame is not None:
        if frame.f_code.co_filename in _IMPORT_CODE:
            return True
        frame = frame.f_back
    return False


def _resend() -> None:
    os.kill(os.getpid(), signal.SIGINT)


def _on_sigint(signum, frame) -> None:
    if _in_import(frame):
        timer = threading.Timer(RETRY_S, _resend)
        timer.daemon = True
        timer.start()
        return
    raise KeyboardInterrupt


def install() -> None:
    """Use `_on_sigint` for SIGINT in this process when Python's default handler is in place (a
    process that ignores SIGINT, as a worker does, or installed its own handler, is left as it is)."""
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
