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

import ast
import os
import re
from functools import lru_cache
from pathlib import Path

_PKG = Path(__file__).resolve().parent.parent  # .../r360gpu
_INCLUDE = re.compile(r"^[ \t]*//!include[ \t]+(\S+)[ \t]*$", re.MULTILINE)
#: Shader files that exist only to be included.
INCLUDE_ONLY = ("common", "workgroup_scan", "radix_digits", "radix_pass", "tile_pixels", "composite")


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


# ---- sizes the shaders state, read by the host -------------------------------------------------
# Workgroup sizes and per-workgroup block sizes are written once, in the WGSL (a module-scope
# ``const NAME: u32 = ...;`` and ``@workgroup_size(NAME)``); the host reads them from there with
# shader_constants / workgroup_size instead of keeping a copy that could drift.

_CONST_U32 = re.compile(r"^[ \t]*const[ \t]+(\w+)[ \t]*:[ \t]*u32[ \t]*=[ \t]*([^;]+);", re.MULTILINE)
_WORKGROUP_SIZE = re.compile(r"@workgroup_size\(([^)]*)\)\s*fn\s+(\w+)\s*\(")
_U32_LITERAL = re.compile(r"\b(\d+)u\b")
_OPS = {ast.Add: int.__add__, ast.Sub: int.__sub__, ast.Mult: int.__mul__, ast.FloorDiv: int.__floordiv__,
        ast.LShift: int.__lshift__, ast.RShift: int.__rshift__}


def _u32_expr(text: str, known: dict[str, int], where: str) -> int:
    """Value of a WGSL u32 constant expression made of literals, earlier constants and + - * / << >>."""
    src = _U32_LITERAL.sub(r"\1", text.strip()).replace("/", "//")

    def ev(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and type(node.value) is int:
            return node.value
        if isinstance(node, ast.Name) and node.id in known:
            return known[node.id]
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            return _OPS[type(node.op)](ev(node.left), ev(node.right))
        raise ValueError(f"{where}: cannot evaluate u32 expression {text.strip()!r} on the host")

    return ev(ast.parse(src, mode="eval").body)


@lru_cache(maxsize=None)
def _constants_of(source: str, name: str) -> dict[str, int]:
    out: dict[str, int] = {}
    for m in _CONST_U32.finditer(source):
        try:
            out[m.group(1)] = _u32_expr(m.group(2), out, f"{name}.wgsl const {m.group(1)}")
        except ValueError:
            continue  # e.g. a bitcast or a function call: not a size the host needs
    return out


def shader_constants(name: str) -> dict[str, int]:
    """The module-scope ``const NAME: u32`` values of shader ``name`` (includes expanded)."""
    return dict(_constants_of(load_shader_source(name), name))


def shader_constant(name: str, const: str) -> int:
    """One ``const`` of shader ``name``; a clear error if the shader does not declare it."""
    consts = shader_constants(name)
    if const not in consts:
        raise KeyError(f"{name}.wgsl declares no u32 const {const} (has: {', '.join(sorted(consts))})")
    return consts[const]


def workgroup_size(name: str, entry_point: str = "main") -> tuple[int, int, int]:
    """The ``@workgroup_size`` of ``entry_point`` in shader ``name``, as (x, y, z)."""
    source = load_shader_source(name)
    consts = _constants_of(source, name)
    for m in _WORKGROUP_SIZE.finditer(source):
        if m.group(2) == entry_point:
            dims = [_u32_expr(d, consts, f"{name}.wgsl {entry_point}") for d in m.group(1).split(",") if d.strip()]
            return tuple(dims + [1] * (3 - len(dims)))  # type: ignore[return-value]
    raise KeyError(f"{name}.wgsl has no compute entry point {entry_point!r} with a @workgroup_size")


def workgroup_threads(name: str, entry_point: str = "main") -> int:
    """Invocations in one workgroup of ``entry_point`` (the product of its workgroup size)."""
    x, y, z = workgroup_size(name, entry_point)
    return x * y * z


# ---- bindings the shaders declare, checked against the host's names -----------------------------
# The host binds resources by position (``@binding(i)`` gets ``resources[i]``); a kernel module also
# states the WGSL names of those positions, and the pipeline is refused when they disagree, so a
# binding moved in the WGSL (or a list written in another order) fails with a message, not a
# wrong image.

_LINE_COMMENT = re.compile(r"//[^\n]*")
_BINDING = re.compile(r"((?:@\w+\(\s*\w+\s*\)\s*)+)var(?:<[^>]*>)?\s+(\w+)")
_ATTR = re.compile(r"@(group|binding)\(\s*(\d+)\s*\)")


@lru_cache(maxsize=None)
def _bindings_of(source: str) -> dict[int, dict[int, str]]:
    out: dict[int, dict[int, str]] = {}
    for m in _BINDING.finditer(_LINE_COMMENT.sub("", source)):
        attrs = dict(_ATTR.findall(m.group(1)))
        if "binding" in attrs:
            out.setdefault(int(attrs.get("group", 0)), {})[int(attrs["binding"])] = m.group(2)
    return out


def shader_bindings(name: str, group: int = 0) -> dict[int, str]:
    """{binding number: variable name} of bind group ``group`` in shader ``name`` (includes expanded)."""
    return dict(_bindings_of(load_shader_source(name)).get(group, {}))


def check_bindings(name: str, names, group: int = 0) -> None:
    """Raise ValueError unless shader ``name`` declares ``names[i]`` at ``@binding(i)`` of ``group``
    for every ``i`` (``names[i]`` None: position ``i`` left unchecked)."""
    declared = shader_bindings(name, group)
    wrong = [f"@binding({i}) is {declared[i]!r} in the WGSL, the host binds {n!r} there" if i in declared
             else f"the WGSL declares no @binding({i}), the host binds {n!r} there"
             for i, n in enumerate(names) if n is not None and declared.get(i) != n]
    if wrong:
        raise ValueError(f"{name}.wgsl, group {group}: " + "; ".join(wrong))
