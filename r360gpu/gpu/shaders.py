"""Finding the WGSL kernels by name.

In a checkout they live in the top-level ``shaders/`` folder; an installed
wheel carries them as ``r360gpu/shaders/`` (see ``pyproject.toml``).  The
environment variable ``R360GPU_SHADER_DIR`` overrides both (for shader
development against an installed package).
"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

_PKG = Path(__file__).resolve().parent.parent  # .../r360gpu


def shader_dirs() -> list[Path]:
    """Candidate shader folders, in the order they are searched."""
    dirs = []
    env = os.environ.get("R360GPU_SHADER_DIR")
    if env:
        dirs.append(Path(env))
    dirs.append(_PKG / "shaders")  # installed wheel
    dirs.append(_PKG.parent / "shaders")  # checkout / editable install
    return dirs


def shader_path(name: str) -> Path:
    """Path of ``<name>.wgsl`` (``name`` may include the suffix)."""
    fname = name if name.endswith(".wgsl") else f"{name}.wgsl"
    for d in shader_dirs():
        p = d / fname
        if p.is_file():
            return p
    searched = ", ".join(str(d) for d in shader_dirs())
    raise FileNotFoundError(f"shader {fname} not found (searched: {searched})")


@lru_cache(maxsize=None)
def _read(path: str, mtime: float) -> str:
    return Path(path).read_text(encoding="utf-8")


def load_shader_source(name: str) -> str:
    p = shader_path(name)
    return _read(str(p), p.stat().st_mtime)


def available_shaders() -> list[str]:
    names: set[str] = set()
    for d in shader_dirs():
        if d.is_dir():
            names.update(p.stem for p in d.glob("*.wgsl"))
    return sorted(names)
