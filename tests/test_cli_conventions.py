"""Command-line conventions: list flags, bare r360gpu, progress off a terminal, demo reuse, ./r360 from elsewhere."""
from __future__ import annotations

import glob
import hashlib
import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from r360gpu.cli import build_parser, main
from r360gpu.util.progress import progress

REPO = Path(__file__).resolve().parents[1]


def test_bare_command_prints_help_and_succeeds(capsys):
    assert main([]) == 0
    assert "usage: r360gpu" in capsys.readouterr().out


@pytest.mark.parametrize("command", ["score", "check"])
def test_views_is_one_repeatable_flag_with_comma_lists(command):
    extra = ["--out", "o"] if command == "score" else []
    args = build_parser().parse_args([command, "--views", "a*", "B", *extra])
    assert args.views == ["a*"] and args.bundles == ["B"]  # the bundle is not swallowed
    args = build_parser().parse_args([command, "--views", "a*,b", "--views", "c", "B", *extra])
    assert args.views == ["a*", "b", "c"]


def test_xi_is_a_repeatable_flag_with_comma_lists(capsys):
    from r360gpu.cli.score import options_from_args

    p = build_parser()
    args = p.parse_args(["score", "--xi", "0.5,0.7", "--xi", "0.9", "B", "--out", "o"])
    assert args.xi == [0.5, 0.7, 0.9] and args.bundles == ["B"]
    assert options_from_args(args).xis == (0.3, 0.5, 0.7, 0.9)
    assert options_from_args(p.parse_args(["score", "B", "--out", "o"])).xis == (0.3, 0.5, 0.7, 0.9)
    with pytest.raises(SystemExit):
        p.parse_args(["score", "--xi", "high", "B", "--out", "o"])
    assert "invalid value 'high'" in capsys.readouterr().err
    # demo shares the scoring options
    assert p.parse_args(["demo", "--xi", "0.5", "--views", "view_00*"]).views == ["view_00*"]


class _Clock:
    def __init__(self, step):
        self.t, self.step = 0.0, step

    def __call__(self):
        self.t += self.step
        return self.t


def test_progress_prints_plain_lines_when_not_a_terminal():
    out = io.StringIO()  # not a terminal
    items = list(progress(range(100), desc="scoring room", stream=out, clock=_Clock(0.01)))
    assert items == list(range(100))
    lines = out.getvalue().splitlines()
    assert len(lines) == 10 and "\r" not in out.getvalue()  # every 10%
    assert lines[-1].startswith("scoring room: 100/100 views (100%)") and "left" not in lines[-1]
    # 10 views in 0.1 s: 90 more take about 0.9 s
    assert lines[0] == "scoring room: 10/100 views (10%), 0.1 s, 100.00 views/s, about 1 s left"
    out = io.StringIO()
    list(progress(range(5), desc="slow", stream=out, clock=_Clock(6.0)))  # every ~10 s
    assert [line.split(":")[1].split()[0] for line in out.getvalue().splitlines()] == ["1/5", "2/5", "3/5",
                                                                                        "4/5", "5/5"]
    out = io.StringIO()
    list(progress(range(1000), desc="slow", stream=out, clock=_Clock(0.001), every_s=10.0))
    assert len(out.getvalue().splitlines()) == 10
    assert list(progress([1, 2], desc="x", enabled=False, stream=out)) == [1, 2]


def test_durations_read_as_a_person_says_them():
    from r360gpu.util.progress import duration

    assert [duration(s) for s in (0.4, 40, 89, 600, 5399, 5400, 12600)] == [
        "0 s", "40 s", "89 s", "10 min", "90 min", "1.5 h", "3.5 h"]


def test_progress_bar_on_a_terminal():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    out = Tty()
    list(progress(range(3), desc="bar", stream=out))
    assert "\r" in out.getvalue() and "3/3" in out.getvalue()


def _has_vulkan_driver() -> bool:
    return bool(glob.glob("/usr/share/vulkan/icd.d/*.json") or glob.glob("/etc/vulkan/icd.d/*.json"))


@pytest.mark.skipif(not _has_vulkan_driver() or shutil.which("bash") is None,
                    reason="./r360 would try to install the Vulkan driver")
def test_r360_keeps_the_callers_working_directory(tmp_path, ctx):
    """./r360 run from another folder: relative paths are the caller's.  The set-up is skipped by a venv
    that is already current (R360_VENV pointing at this interpreter, with the stamp ./r360 writes)."""
    from r360gpu.synthetic import generate_benchmark

    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(sys.executable)
    (venv / "bin" / "r360gpu").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m r360gpu "$@"\n')
    (venv / "bin" / "r360gpu").chmod(0o755)
    stamp = hashlib.sha256((REPO / "pyproject.toml").read_bytes()).hexdigest()[:16]
    (venv / ".r360-installed").write_text(stamp + "\n")
    work = tmp_path / "elsewhere"
    generate_benchmark(work / "mine", n_views=2, width=48, height=32, detail=0.1, scenes=("room",),
                       methods=["clean"], ctx=ctx)
    env = {**os.environ, "R360_VENV": str(venv), "PYTHONPATH": str(REPO)}
    r = subprocess.run([str(REPO / "r360"), "check", "mine/room"], cwd=work, env=env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "mine/room: OK" in r.stdout


def test_view_takes_prompt_and_method_name(tmp_path, monkeypatch, ctx):
    """`view` loads a public-layout folder with --prompt / --method-name and hands the viewer the Bundle."""
    pytest.importorskip("r360gpu.viewer.launch")
    import r360gpu.viewer.launch

    from r360gpu.bundle import Bundle
    from public_benchmark import make_public_benchmark

    root = make_public_benchmark(tmp_path, scenes=("room",), n_views=2, width=48, height=32, detail=0.1,
                                 skip=("GC/room", "AF/room"), ctx=ctx)
    folder = root / "OC" / "room"
    (folder / "prompt.txt").unlink()
    seen = []
    monkeypatch.setattr(r360gpu.viewer.launch, "run", lambda args: seen.append(args.bundle) or 0)
    monkeypatch.setattr("r360gpu.cli.view.missing_modules", lambda: [])
    assert main(["view", str(folder), "--prompt", "couch", "--method-name", "OC"]) == 0
    assert isinstance(seen[0], Bundle) and seen[0].prompt == "couch" and list(seen[0].methods) == ["OC"]
    assert main(["view", str(folder)]) == 0 and seen[1] == str(folder)  # no override: the viewer loads it


def test_building_the_command_line_imports_no_scipy_or_matplotlib():
    # Every command builds the whole parser first; scipy.special alone cost each one ~0.17 s
    # (through aggregate.reliability), before any command that needs it had started.
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    code = ("import sys; from r360gpu.cli import build_parser; build_parser(); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'matplotlib', 'wgpu'}))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
