import sys

from .util.interrupts import install

install()  # before the imports a Ctrl-C could otherwise leave half done (util/interrupts.py)
try:
    from .cli import main
except KeyboardInterrupt:  # Ctrl-C during the first imports
    print("r360gpu: interrupted", file=sys.stderr)
    sys.exit(130)


def _exit(code: int) -> None:
    """Exit with ``code`` without the interpreter's teardown (freeing every module's objects) once
    nothing is left to do: every output of a command is written and closed before main() returns,
    and the atexit functions still run.  With another thread still working,
    the ordinary exit waits for it."""
    import atexit
    import os
    import threading

    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.exit(code)
    atexit._run_exitfuncs()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed pipe: the ordinary exit reports it as Python does
        sys.exit(code)
    os._exit(code)


_exit(main())
