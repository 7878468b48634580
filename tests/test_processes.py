"""Scoring in worker processes (r360gpu.pipeline.processes, ``--processes N``) gives the serial
run's --out, and a worker that dies ends the run clearly, with the finished views kept."""
from __future__ import annotations

import json

import pytest

from r360gpu.cli import main
from r360gpu.errors import InputError
from r360gpu.pipeline.distributed import FAIL_ONCE_ENV
from r360gpu.pipeline.processes import ProcessExecutor, default_workers

from run_compare import comparable, scenes, serial, tree, tree_differences  # noqa: F401 (scenes, serial: module fixtures)

CLI_STATS = ["--n-boot", "200", "--n-perm", "100", "--quiet"]


def _assert_same_output(out, s_out):
    doc = json.loads((out / "results.json").read_text())
    assert comparable(doc) == comparable(json.loads((s_out / "results.json").read_text()))
    assert (out / "tables.md").read_bytes() == (s_out / "tables.md").read_bytes()
    pictures = tree(out, "pictures")
    assert pictures and not tree_differences(pictures, tree(s_out, "pictures")), \
        tree_differences(pictures, tree(s_out, "pictures"))
    assert tree(out, ".r360cache/views") == tree(s_out, ".r360cache/views")
    return doc


def test_two_scenes_in_worker_processes_equal_the_serial_run(scenes, serial, tmp_path, capsys):
    """--processes 2: results, tables, pictures and view cache are the serial run's."""
    s_out, _ = serial
    out = tmp_path / "processes"
    rc = main(["score", *map(str, scenes), "--out", str(out), "--processes", "2", *CLI_STATS])
    assert rc == 0, capsys.readouterr().err
    doc = _assert_same_output(out, s_out)
    # default chunk: ceil(2 views / (2 x 2 workers)) = 1 view per task, 2 views per scene
    ex = doc["timing"]["executor"]
    assert ex["kind"] == "processes" and ex["workers"] == 2
    assert ex["tasks"] == 4 and ex["views_sent"] == 4
    assert "render" in doc["timing"]["stages_s"]  # the workers' stage timings are merged


def test_a_dead_worker_ends_the_run_and_a_rerun_resumes(scenes, serial, tmp_path, monkeypatch, capsys):
    """The first task to start ends its worker process (os._exit): one line, exit 2, the views other
    workers finished are in the view cache; the same command again sends only the rest and gives
    the serial run's output."""
    s_out, _ = serial
    marker = tmp_path / "fail-once"
    marker.write_text("")
    monkeypatch.setenv(FAIL_ONCE_ENV, str(marker))  # spawned workers inherit the environment
    out = tmp_path / "processes"
    args = ["score", *map(str, scenes), "--out", str(out), "--processes", "2", *CLI_STATS]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "a worker process died while scoring scene" in err and "run again to resume" in err
    assert "Traceback" not in err
    assert not marker.exists()
    assert not (out / "results.json").exists()  # nothing half-written
    # views/<key>/<scene>/<method>/<view>.json: a finished view has a cell for every method
    cached = {(p.parts[-3], p.stem) for p in (out / ".r360cache").glob("views/*/*/*/*.json")}
    assert main(args) == 0, capsys.readouterr().err
    doc = _assert_same_output(out, s_out)
    assert doc["timing"]["executor"]["views_sent"] == 4 - len(cached)  # the finished views are not sent again


@pytest.mark.parametrize("value, problem", [
    ("0", "--processes must be at least 1, got 0"),
    ("-3", "--processes must be at least 1, got -3"),
    ("many", "--processes takes a number of worker processes or 'auto', got 'many'"),
])
def test_bad_process_counts_are_refused_before_any_work(value, problem, scenes, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["score", str(scenes[0]), "--out", str(out), "--processes", value, "--quiet"]) == 2
    assert problem in capsys.readouterr().err
    assert not (out / "results.json").exists()


def test_processes_and_ray_do_not_combine(scenes, tmp_path, capsys):
    assert main(["score", str(scenes[0]), "--out", str(tmp_path / "o"), "--processes", "2", "--ray", "local",
                 "--quiet"]) == 2
    assert "--processes and --ray cannot be combined" in capsys.readouterr().err


def test_one_process_is_the_serial_run_and_auto_follows_the_cores(monkeypatch):
    from argparse import Namespace

    from r360gpu.cli.score import processes_from_args

    assert processes_from_args(Namespace(processes="1", adapter=None)) is None
    assert processes_from_args(Namespace(processes=None, adapter=None)) is None
    monkeypatch.setattr("os.cpu_count", lambda: 16)
    assert default_workers() == 8
    ex = processes_from_args(Namespace(processes="auto", adapter=None))
    assert isinstance(ex, ProcessExecutor) and ex.workers == 8
    monkeypatch.setattr("os.cpu_count", lambda: 3)
    assert default_workers() == 1
    assert processes_from_args(Namespace(processes="auto", adapter=None)) is None
    with pytest.raises(InputError, match="chunk size must be at least 1"):
        ProcessExecutor(2, chunk=0)


def test_ctrl_c_stops_the_workers_without_their_tracebacks(scenes, tmp_path):
    """Ctrl-C reaches the whole process group: the driver says it was interrupted (exit 130) and
    stops its workers; the workers print nothing of their own."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    # The command starts as from a terminal, with Ctrl-C live.  A test process started with SIGINT
    # ignored (a shell's background job: `pytest ... &`) would pass that on, and a process that starts
    # with SIGINT ignored rightly keeps ignoring it (r360gpu.util.interrupts.install).  A handler of
    # ours in this process becomes the default disposition in the child when it execs.
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = subprocess.Popen([sys.executable, "-m", "r360gpu", "score", *map(str, scenes), "--out",
                                 str(tmp_path / "o"), "--processes", "2", "--n-boot", "200", "--n-perm", "100"],
                                cwd=root, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                start_new_session=True)
    finally:
        signal.signal(signal.SIGINT, old)
    seen = []
    for line in proc.stdout:  # plain progress lines (not a terminal)
        seen.append(line)
        if "in 2 worker processes" in line:
            break
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: every process of the group
    rest, _ = proc.communicate(timeout=120)
    out = "".join(seen) + rest
    assert proc.returncode == 130, out
    assert "r360gpu: interrupted" in out and "Traceback" not in out and "KeyboardInterrupt" not in out
