"""Finding the WGSL kernels by name.

In a checkout they live in the top-level ``shaders/`` folder; an installed
wheel carries them as ``r360gpu/shaders/`` (see ``pyproject.toml``).  The
environment variable ``R360GPU_SHADER_DIR`` overrides both (for shader
development against an installed package).

Includes: a line ``//!include NAME.wgsl`` is replaced by that file's text
(found by name like any shader, itself expanded, each file at most once per
shader), so helpers shared by several kernels (``common.wgsl``) are written
once.  Files named in :data:`INCLUDE_ONLY` hold no entry point and are not
kernels of their own.
"""
from __future__ import annotations

import os
import re
from functools import lru_cache
from pathlib import Path

_PKG = Path(__file__).resolve().parent.parent  # .../r360gpu
_INCLUDE = re.compile(r"^[ \t]*//!include[ \t]+(\S+)[ \t]*$", re.MULTILINE)
#: Shader files that exist only to be included.
INCLUDE_ONLY = ("common", "workgroup_scan")


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
    """The WGSL text of shader ``name`` with its ``//!include`` lines expanded."""
    return _expand(name, [], set())


def _expand(name: str, stack: list[str], seen: set[str]) -> str:
    p = shader_path(name)
    key = p.stem
    if key in stack:
        raise ValueError(f"shader include cycle: {' -> '.join(stack + [key])}")
    seen.add(key)
    text = _read(str(p), p.stat().st_mtime)

    def sub(m: re.Match) -> str:
        inc = Path(m.group(1)).stem
        if inc in stack or inc == key:
            raise ValueError(f"shader include cycle: {' -> '.join(stack + [key, inc])}")
        if inc in seen:
            return f"// (included above: {m.group(1)})"
        return f"// ---- {m.group(1)} ----\n{_expand(inc, stack + [key], seen)}// ---- end of {m.group(1)} ----"

    return _INCLUDE.sub(sub, text)


def available_shaders(include_only: bool = True) -> list[str]:
    """Names of the shader files found (``include_only=False``: kernels only)."""
    names: set[str] = set()
    for d in shader_dirs():
        if d.is_dir():
            names.update(p.stem for p in d.glob("*.wgsl"))
    if not include_only:
        names -= set(INCLUDE_ONLY)
    return sorted(names)
