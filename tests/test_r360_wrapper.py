"""./r360's set-up checks: "driver present" cannot fail spuriously, and no package manager runs once set up."""
import glob
import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
WRAPPER = REPO / "r360"
HAS_ICD = bool(glob.glob("/usr/share/vulkan/icd.d/*.json") or glob.glob("/etc/vulkan/icd.d/*.json"))
LOADER_LINE = "\tlibvulkan.so.1 (libc6,x86-64) => /usr/lib/x86_64-linux-gnu/libvulkan.so.1"

pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="./r360 is a bash script")


def _bash(script: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """`script` in bash after sourcing ./r360 (which defines its functions and runs nothing when sourced)."""
    return subprocess.run(["bash", "-c", f'set -euo pipefail; source "{WRAPPER}"; {script}'],
                          capture_output=True, text=True, timeout=120, env=env)


def _fake_bin(tmp_path: Path, **scripts: str) -> Path:
    """A folder of executables, each a shell script body, to put first on PATH."""
    fake = tmp_path / "fakebin"
    fake.mkdir(exist_ok=True)
    for name, body in scripts.items():
        (fake / name).write_text("#!/bin/sh\n" + body + "\n")
        (fake / name).chmod(0o755)
    return fake


def _big_ldconfig(tmp_path: Path) -> Path:
    """An ldconfig whose cache names the loader first, then writes far more than a pipe holds: a reader
    that stops at the first match makes it die of SIGPIPE."""
    listing = tmp_path / "cache.txt"
    listing.write_text(LOADER_LINE + "\n" + "\tlibfiller.so.0 (libc6,x86-64) => /usr/lib/libfiller.so.0\n" * 20000)
    return _fake_bin(tmp_path, ldconfig=f'cat "{listing}"')


@pytest.mark.skipif(not HAS_ICD, reason="no Vulkan ICD manifest on this machine")
def test_driver_check_never_fails_spuriously():
    """1,000 calls of the wrapper's own check, under the wrapper's pipefail: none says "no driver"."""
    if _bash("have_vulkan_driver").returncode != 0:
        pytest.skip("no Vulkan loader in the linker cache")
    r = _bash('n=0; for i in $(seq 1000); do have_vulkan_driver || n=$((n+1)); done; echo "failures=$n"')
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "failures=0"


@pytest.mark.skipif(not HAS_ICD, reason="no Vulkan ICD manifest on this machine")
def test_driver_check_survives_an_early_match_in_a_long_cache(tmp_path):
    """The listing that broke `ldconfig -p | grep -q` (loader first, a long tail) breaks the pipe form here
    too, and never the wrapper's check."""
    env = {**os.environ, "PATH": f"{_big_ldconfig(tmp_path)}:{os.environ['PATH']}"}
    loop = 'n=0; for i in $(seq 20); do {} || n=$((n+1)); done; echo "failures=$n"'
    piped = _bash(loop.format("{ ldconfig -p 2>/dev/null | grep -q libvulkan.so.1; }"), env)
    assert piped.stdout.strip() != "failures=0", "the fixture no longer reproduces the SIGPIPE failure"
    ours = _bash(loop.format("have_vulkan_driver"), env)
    assert ours.returncode == 0, ours.stderr
    assert ours.stdout.strip() == "failures=0"


def test_library_check_reads_the_cache_without_a_pipe(tmp_path):
    """have_library (also used for libXcursor) answers from the cache's text: present and absent."""
    env = {**os.environ, "PATH": f"{_big_ldconfig(tmp_path)}:{os.environ['PATH']}"}
    assert _bash("have_library libvulkan.so.1", env).returncode == 0
    assert _bash("have_library libXcursor.so.1", env).returncode == 1
    piped = [line for line in WRAPPER.read_text().splitlines()
             if "ldconfig" in line and not line.lstrip().startswith("#") and re.search(r"(?<!\|)\|(?!\|)", line)]
    assert piped == []


def _venv(tmp_path: Path, system_stamp: str | None) -> Path:
    """A venv the wrapper takes as current (its python is this interpreter), with or without the stamp
    of a finished system set-up."""
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(sys.executable)
    stamp = hashlib.sha256((REPO / "pyproject.toml").read_bytes()).hexdigest()[:16]
    (venv / ".r360-installed").write_text(stamp + "\n")
    if system_stamp is not None:
        (venv / ".r360-system").write_text(system_stamp + "\n")
    return venv


def _run_as_root(tmp_path: Path, venv: Path, cache: str, command: list[str]):
    """./r360 COMMAND as if root (a fake `id`), with a linker cache of `cache` and an apt-get that only
    records its calls.  Returns the process and the recorded apt-get calls."""
    calls = tmp_path / "apt-get.calls"
    listing = tmp_path / "cache.txt"
    listing.write_text(cache)
    fake = _fake_bin(tmp_path, **{"id": "echo 0", "ldconfig": f'cat "{listing}"',
                                  "apt-get": f'echo "$@" >> "{calls}"'})
    env = {**os.environ, "PATH": f"{fake}:{os.environ['PATH']}", "R360_VENV": str(venv)}
    r = subprocess.run([str(WRAPPER), *command], capture_output=True, text=True, timeout=120, env=env)
    return r, calls.read_text().splitlines() if calls.exists() else []


@pytest.mark.skipif(not HAS_ICD, reason="no Vulkan ICD manifest on this machine")
def test_no_package_manager_once_set_up(tmp_path):
    """Set up (stamp present, driver present): the command runs and apt-get is never called, even for
    `test`, whose extra packages (Chromium, Xvfb) are not looked for again."""
    venv = _venv(tmp_path, "test")
    for command in (["python", "-c", "print('ran')"], ["test", "--version"]):
        r, calls = _run_as_root(tmp_path, venv, LOADER_LINE + "\n", command)
        assert r.returncode == 0, r.stderr
        assert calls == []
    assert "ran" in _run_as_root(tmp_path, venv, LOADER_LINE + "\n", ["python", "-c", "print('ran')"])[0].stdout


@pytest.mark.skipif(not HAS_ICD, reason="no Vulkan ICD manifest on this machine")
def test_driver_gone_after_set_up_prints_the_command(tmp_path):
    """The driver removed after the set-up: the command stops with the line that puts it back (exit 3),
    and installs nothing itself."""
    r, calls = _run_as_root(tmp_path, _venv(tmp_path, "base"), "", ["python", "-c", "print('ran')"])
    assert r.returncode == 3
    assert calls == []
    assert "sudo apt-get install -y mesa-vulkan-drivers" in r.stderr
    assert "ran" not in r.stdout


@pytest.mark.skipif(not HAS_ICD, reason="no Vulkan ICD manifest on this machine")
def test_first_set_up_installs_then_records(tmp_path):
    """No stamp yet: the first command is the set-up.  With the driver present nothing is installed and
    the stamp is written; with it missing (as root) apt-get is called -- the recorder sees it."""
    venv = _venv(tmp_path, None)
    r, calls = _run_as_root(tmp_path, venv, LOADER_LINE + "\n", ["python", "-c", "print('ran')"])
    assert r.returncode == 0 and calls == []
    assert (venv / ".r360-system").read_text().strip() == "base"

    (venv / ".r360-system").unlink()
    r, calls = _run_as_root(tmp_path, venv, "", ["python", "-c", "print('ran')"])
    assert any(c.startswith("install") and "mesa-vulkan-drivers" in c for c in calls)
    assert r.returncode == 3 and not (venv / ".r360-system").exists()
