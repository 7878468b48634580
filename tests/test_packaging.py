"""The WGSL shaders are found from a checkout and from an installed wheel."""
from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from r360gpu.gpu import available_shaders, shader_path

ROOT = Path(__file__).resolve().parents[1]


def test_shaders_found_in_checkout():
    names = sorted(p.stem for p in (ROOT / "shaders").glob("*.wgsl"))
    assert names and set(names) <= set(available_shaders())
    for n in names:
        assert shader_path(n).read_text() == (ROOT / "shaders" / f"{n}.wgsl").read_text()


def test_missing_shader_is_a_clear_error():
    with pytest.raises(FileNotFoundError, match="no_such_kernel.wgsl not found"):
        shader_path("no_such_kernel")


def test_wheel_carries_the_shaders(tmp_path):
    """Build the wheel, unpack it as site-packages would, and load every shader
    from it in a fresh interpreter that cannot see the checkout."""
    try:
        import hatchling  # noqa: F401

        isolation = ["--no-build-isolation"]
    except ImportError:
        isolation = []  # pip fetches hatchling into an isolated build env
    out = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", *isolation, "-w", str(tmp_path / "dist"), str(ROOT)],
        capture_output=True, text=True,
    )
    assert out.returncode == 0, out.stderr
    wheel = next((tmp_path / "dist").glob("r360gpu-*.whl"))
    site = tmp_path / "site"
    with zipfile.ZipFile(wheel) as z:
        z.extractall(site)
    shipped = sorted(p.name for p in (site / "r360gpu" / "shaders").glob("*.wgsl"))
    assert shipped == sorted(p.name for p in (ROOT / "shaders").glob("*.wgsl"))
    code = (
        "import r360gpu, r360gpu.gpu.shaders as s, pathlib;"
        "assert str(pathlib.Path(r360gpu.__file__).resolve()).startswith(%r);"
        "names = s.available_shaders(); assert names, names;"
        "[s.load_shader_source(n) for n in names];"
        "print(s.shader_path(names[0]))" % str(site.resolve())
    )
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "R360GPU_SHADER_DIR")}
    env["PYTHONPATH"] = str(site)
    res = subprocess.run([sys.executable, "-I", "-c", code.replace("import r360gpu", "import sys; sys.path.insert(0, %r); import r360gpu" % str(site), 1)],
                         capture_output=True, text=True, cwd=tmp_path, env=env)
    assert res.returncode == 0, res.stderr
    assert Path(res.stdout.strip()).resolve().is_relative_to((site / "r360gpu" / "shaders").resolve())
