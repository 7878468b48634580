"""The bad-input corpus (tests/badinput_cases.py) through the real CLI, plus the cases that need a
second process (Ctrl-C, a killed writer) or a simulated file system (read-only, disk full).

Every case asserts: the exit code; no traceback; the message (or the recorded warning) names the
file; nothing written outside --out (the inputs, the working folder and everything else under the
test's folder are unchanged); after an error, no results.json and no temporary file in --out.
"""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from badinput_cases import CASES, SCORE_FLAGS, _depth_pre, renders_bundle
from r360gpu import cli
from r360gpu.util import filehash

ROOT = Path(__file__).resolve().parents[1]


def _snapshot(root: Path, skip: Path) -> dict:
    out = {}
    for p in root.rglob("*"):
        if p == skip or skip in p.parents:
            continue
        st = p.lstat()
        out[p.relative_to(root).as_posix()] = (p.is_dir(), st.st_size if not p.is_dir() else 0, st.st_mtime_ns)
    return out


def _run(argv, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    argv = [a.replace("{out}", str(out)) for a in argv]
    cwd = tmp_path / "cwd"
    cwd.mkdir(exist_ok=True)
    monkeypatch.chdir(cwd)
    before = _snapshot(tmp_path, out)
    rc = cli.main(argv)
    captured = capsys.readouterr()
    assert _snapshot(tmp_path, out) == before, "something was written outside --out"
    return rc, captured.out, captured.err, out


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_corpus(case, tmp_path, capsys, monkeypatch):
    filehash.forget()
    argv, named = case.build(tmp_path)
    lock = None
    if case.id == "out-locked-by-another-run":
        from r360gpu.util.outdir import open_output_folder

        lock = open_output_folder(tmp_path / "out")
    try:
        rc, stdout, stderr, out = _run(argv, tmp_path, capsys, monkeypatch)
    finally:
        if lock is not None:
            lock.release()
    text = stdout + stderr
    assert "Traceback" not in text
    results = json.loads((out / "results.json").read_text()) if (out / "results.json").is_file() else None
    if case.outcome == "error":
        assert rc == 2, text
        assert named in text, f"the message does not name {named!r}: {text}"
        assert case.keyword in text, text
        if argv[0] == "score":
            assert "r360gpu: error:" in stderr
            assert results is None and not list(out.rglob("*.tmp")) if out.is_dir() else True
    else:
        assert rc == 0, text
        if argv[0] == "score":
            assert results is not None
            warnings = results["warnings"]
            if case.outcome == "warning":
                hits = [w for w in warnings if case.keyword in w["message"]
                        and named in f"{w['file']} {w['message']}"]
                assert hits, warnings
                for w in hits:
                    assert set(w) == {"scene", "method", "view", "file", "message"} and w["scene"]
                    line = f"{w['file']}: {w['message']}" if w["file"] else w["message"]
                    assert stderr.count(line) == 1, stderr  # printed once
            else:
                assert warnings == [], warnings
        else:
            assert "OK" in stdout
    if case.verify is not None:
        case.verify(out, results, stderr)


def test_corpus_size_and_outcomes():
    outcomes = {}
    for c in CASES:
        outcomes[c.outcome] = outcomes.get(c.outcome, 0) + 1
    assert len(CASES) >= 60 and len({c.id for c in CASES}) == len(CASES)
    assert set(outcomes) == {"error", "warning", "accepted"}


# --- simulated file systems -------------------------------------------------------------------------

def test_read_only_output_file_system(tmp_path, capsys, monkeypatch):
    b = renders_bundle(tmp_path / "b")
    out = tmp_path / "out"
    real_mkdir, real_open = os.mkdir, os.open

    def guard(p):
        if str(out) in os.fspath(p):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(p))

    monkeypatch.setattr(os, "mkdir", lambda p, *a, **k: (guard(p), real_mkdir(p, *a, **k))[1])
    monkeypatch.setattr(os, "open", lambda p, *a, **k: (guard(p), real_open(p, *a, **k))[1])
    rc = cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS])
    err = capsys.readouterr().err
    assert rc == 2 and "read-only file system" in err and str(out) in err and "Traceback" not in err
    assert not out.exists()


def _enospc_on(monkeypatch, name):
    from r360gpu.util import atomic

    real = atomic.atomic_open

    def failing(path, mode="w", **kw):
        if Path(path).name == name:
            return _raising(real, path, mode, **kw)
        return real(path, mode, **kw)

    monkeypatch.setattr(atomic, "atomic_open", failing)


def _raising(real, path, mode, **kw):
    from contextlib import contextmanager

    @contextmanager
    def cm():
        with real(path, mode, **kw) as f:
            f.write("partial" if "b" not in mode else b"partial")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            yield f  # pragma: no cover
    return cm()


def test_disk_full_while_writing_the_report_leaves_the_previous_set(tmp_path, capsys, monkeypatch):
    b = renders_bundle(tmp_path / "b")
    out = tmp_path / "out"
    assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 0
    capsys.readouterr()
    before = {n: (out / n).read_bytes() for n in ("results.json", "results.csv", "tables.md", "report.html")}
    _enospc_on(monkeypatch, "report.html")
    rc = cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS, "--xi", "0.3,0.6"])
    err = capsys.readouterr().err
    assert rc == 2 and "no space left on device" in err and "report.html" in err and "Traceback" not in err
    assert {n: (out / n).read_bytes() for n in before} == before  # the whole previous set, untouched
    assert not list(out.rglob("*.tmp"))


def test_disk_full_on_the_first_run_leaves_no_results(tmp_path, capsys, monkeypatch):
    b = renders_bundle(tmp_path / "b")
    out = tmp_path / "out"
    _enospc_on(monkeypatch, "tables.tex")
    rc = cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS])
    err = capsys.readouterr().err
    assert rc == 2 and "tables.tex" in err and "Traceback" not in err
    assert not any((out / n).exists() for n in ("results.json", "results.csv", "tables.md", "report.html"))
    assert not list(out.rglob("*.tmp"))


def test_disk_full_while_caching_a_view(tmp_path, capsys, monkeypatch):
    b = renders_bundle(tmp_path / "b")
    out = tmp_path / "out"
    _enospc_on(monkeypatch, "view_01.json")
    rc = cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS])
    err = capsys.readouterr().err
    assert rc == 2 and "view_01.json" in err and "no space" in err.lower() and "Traceback" not in err
    assert not (out / "results.json").exists() and not list(out.rglob("*.tmp"))


# --- cache keyed by content ---------------------------------------------------------------------------

def test_same_size_other_bytes_with_restored_mtime_are_rescored(tmp_path, capsys):
    b = renders_bundle(tmp_path / "b")
    out = tmp_path / "out"
    assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 0
    first = json.loads((out / "results.json").read_text())
    p = b / "a" / "depth" / "view_01.npy"
    st = p.stat()
    d = np.load(p)
    np.save(p, _depth_pre())  # same shape and dtype: same size, other bytes (the depth did not change)
    assert p.stat().st_size == st.st_size
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns))  # as cp -p / rsync -a do
    assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 0
    second = json.loads((out / "results.json").read_text())
    capsys.readouterr()

    def acc(res):
        return [r["geometric"]["acc_depth"] for r in res["scenes"]["r"]["methods"]["a"]["views"]]
    assert acc(first)[1] > 0.5 and acc(second)[1] == 0.0
    assert acc(second)[0] == acc(first)[0]


def test_unchanged_rerun_is_served_from_the_cache_with_its_warnings(tmp_path, capsys):
    b = renders_bundle(tmp_path / "b", post_depth={"view_01": np.zeros((12, 16), np.float32)})
    out = tmp_path / "out"
    assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 0
    first = json.loads((out / "results.json").read_text())
    assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 0
    second = json.loads((out / "results.json").read_text())
    capsys.readouterr()
    assert second["warnings"] == first["warnings"] and len(first["warnings"]) == 1
    assert "Input warning:" in (out / "report.html").read_text()  # shown in the report's summary
    assert second["scenes"] == first["scenes"]
    assert "view_01" in first["warnings"][0]["view"]


# --- second processes ---------------------------------------------------------------------------------

def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


@pytest.mark.parametrize("delay", [0.1, 0.3, 0.6, 0.9])
def test_ctrl_c_in_the_first_second(tmp_path, delay):
    b = renders_bundle(tmp_path / "b")
    old = signal.signal(signal.SIGINT, signal.default_int_handler)  # Ctrl-C live in the child, as from a
    try:                                                              # terminal (tests/test_processes.py)
        proc = subprocess.Popen([sys.executable, "-m", "r360gpu", "score", str(b), "--out", str(tmp_path / "o"),
                                 *SCORE_FLAGS], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env(),
                                cwd=tmp_path)
    finally:
        signal.signal(signal.SIGINT, old)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    err = err.decode()
    started = "Traceback" not in err or f"{os.sep}r360gpu{os.sep}" in err  # a traceback inside r360gpu's code
    if proc.returncode == -signal.SIGINT or "Could not import runpy module" in err or not started:  # pragma: no cover
        pytest.skip("SIGINT arrived while the interpreter itself was starting (before any r360gpu code)")
    assert proc.returncode in (130, 0), err
    assert "Traceback" not in err
    if proc.returncode == 130:
        assert err.strip().splitlines()[-1].startswith("r360gpu: interrupted")
        assert not (tmp_path / "o" / "results.json").exists()


def test_interrupted_run_names_how_to_resume(tmp_path, capsys, monkeypatch):
    b = renders_bundle(tmp_path / "b")
    import importlib

    pipeline_evaluate = importlib.import_module("r360gpu.pipeline.schedule")  # where views are gathered

    def interrupt(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(pipeline_evaluate, "gather", interrupt)
    assert cli.main(["score", str(b), "--out", str(tmp_path / "o"), *SCORE_FLAGS]) == 130
    err = capsys.readouterr().err
    assert "r360gpu: interrupted" in err and "run the same command again to resume" in err
    assert "Traceback" not in err


def test_ctrl_c_inside_an_extension_import_is_an_interrupt(tmp_path, capsys, monkeypatch):
    """Ctrl-C while a C extension initialises (matplotlib's _image, seen in CI) surfaces as
    "ImportError: initialization failed" caused by the KeyboardInterrupt: exit 130, no traceback."""
    b = renders_bundle(tmp_path / "b")
    import importlib

    pipeline_evaluate = importlib.import_module("r360gpu.pipeline.schedule")

    def extension_import(*a, **k):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as e:
            raise ImportError("initialization failed") from e
    monkeypatch.setattr(pipeline_evaluate, "gather", extension_import)
    assert cli.main(["score", str(b), "--out", str(tmp_path / "o"), *SCORE_FLAGS]) == 130
    err = capsys.readouterr().err
    assert err.strip().splitlines()[-1].startswith("r360gpu: interrupted") and "Traceback" not in err
    assert not (tmp_path / "o" / "results.json").exists()

    def plain_import_error(*a, **k):  # an ImportError of its own is not an interrupt
        raise ImportError("no module named nowhere")
    monkeypatch.setattr(pipeline_evaluate, "gather", plain_import_error)
    with pytest.raises(ImportError, match="nowhere"):
        cli.main(["score", str(b), "--out", str(tmp_path / "o2"), *SCORE_FLAGS])


def test_a_killed_run_holds_no_lock_and_its_temporaries_go(tmp_path, capsys):
    b = renders_bundle(tmp_path / "b")
    out = tmp_path / "o"
    code = ("import sys, time; from r360gpu.util.outdir import open_output_folder; "
            f"l = open_output_folder({str(out)!r}); "
            f"open({str(out / '.results.json.abcdefgh.tmp')!r}, 'w').write('{{'); print('held', flush=True); "
            "time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, env=_env())
    assert proc.stdout.readline().strip() == b"held"
    try:
        assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 2
        err = capsys.readouterr().err
        assert f"pid {proc.pid}" in err and "another r360gpu run" in err
    finally:
        proc.kill()
        proc.wait()
    assert cli.main(["score", str(b), "--out", str(out), *SCORE_FLAGS]) == 0
    assert not list(out.rglob("*.tmp")) and (out / "results.json").is_file()


def test_too_many_gaussians_for_one_binding_names_the_file(tmp_path, small_ctx):
    from r360gpu.errors import InputError
    from r360gpu.io import random_gaussians, save_ply
    from r360gpu.render.sources import SceneSource

    p = tmp_path / "big.ply"
    save_ply(p, random_gaussians(300, sh_degree=0, seed=0))  # 4 KiB bindings hold 256
    with pytest.raises(InputError) as e:
        SceneSource(p, ctx=small_ctx)
    assert e.value.path == str(p) and "at most 256" in str(e.value) and "prune or split" in str(e.value)
