"""ImportAhead: modules imported on a thread; a failure is left to the place of use."""
from __future__ import annotations

import importlib
import sys

import pytest

from r360gpu.util.imports import ImportAhead


def test_modules_are_imported_on_a_thread_and_failures_left_to_the_place_of_use(tmp_path, monkeypatch):
    (tmp_path / "r360_ahead_a.py").write_text("import threading\nTHREAD = threading.current_thread().name\n")
    (tmp_path / "r360_ahead_broken.py").write_text("raise RuntimeError('broken on import')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("r360_ahead_a", "r360_ahead_broken", "r360_ahead_missing"):
        monkeypatch.delitem(sys.modules, name, raising=False)

    ahead = ImportAhead("r360_ahead_a", "r360_ahead_broken", "r360_ahead_missing")
    ahead.wait()
    assert sys.modules["r360_ahead_a"].THREAD == "r360-imports"
    assert "r360_ahead_broken" not in sys.modules
    with pytest.raises(RuntimeError, match="broken on import"):
        importlib.import_module("r360_ahead_broken")

    nothing = ImportAhead("json", "r360_ahead_a")  # imported already: no thread
    assert nothing._thread is None
    nothing.wait()
