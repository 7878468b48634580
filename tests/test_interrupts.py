"""A Ctrl-C in the command-line process is raised only outside import machinery (util/interrupts.py)."""
import signal
import threading
import time
from types import SimpleNamespace

import pytest

from r360gpu.util import interrupts


def _frame(*files):
    """A fake frame chain, innermost first."""
    frame = None
    for name in reversed(files):
        frame = SimpleNamespace(f_code=SimpleNamespace(co_filename=name), f_back=frame)
    return frame


def test_outside_an_import_the_interrupt_is_raised_at_once():
    with pytest.raises(KeyboardInterrupt):
        interrupts._on_sigint(signal.SIGINT, _frame("/x/r360gpu/cli/score.py", "<frozen runpy>"))


@pytest.mark.parametrize("where", ["<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>"])
def test_inside_an_import_the_interrupt_is_sent_again_later(monkeypatch, where):
    sent = []
    done = threading.Event()

    def kill(pid, sig):
        sent.append(sig)
        done.set()
    monkeypatch.setattr(interrupts.os, "kill", kill)
    # deep inside a module body that is being imported: the import machinery is further out
    t0 = time.perf_counter()
    assert interrupts._on_sigint(signal.SIGINT, _frame("/site/matplotlib/colors.py", where, "/x/cli.py")) is None
    assert done.wait(5) and sent == [signal.SIGINT]
    assert time.perf_counter() - t0 >= interrupts.RETRY_S * 0.9


def test_install_replaces_only_the_default_handler(monkeypatch):
    old = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a worker process has it
        interrupts.install()
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        signal.signal(signal.SIGINT, signal.default_int_handler)
        interrupts.install()
        assert signal.getsignal(signal.SIGINT) is interrupts._on_sigint
    finally:
        signal.signal(signal.SIGINT, old)
