"""Uniform buffers packed by field name from the WGSL struct that declares them.

A kernel's uniform struct is declared once, in its WGSL file; :func:`uniform`
reads that declaration (after includes) and packs the values given by name in
the struct's order, so host and shader cannot disagree on positions.  A
missing or unknown field is an error.  Fields are 32-bit scalars (u32, i32,
f32), as every r360gpu uniform struct; anything else is refused rather than
packed with a guessed layout.
"""
from __future__ import annotations

import re
from functools import lru_cache

from .shaders import load_shader_source

_STRUCT = re.compile(r"\bstruct\s+(\w+)\s*\{(.*?)\}", re.DOTALL)
_FIELD = re.compile(r"^\s*(\w+)\s*:\s*([\w<>, ]+?)\s*$")
_COMMENT = re.compile(r"//[^\n]*")
SCALARS = ("u32", "i32", "f32")


@lru_cache(maxsize=None)
def _fields_of(source: str, struct: str) -> tuple[tuple[str, str], ...]:
    for m in _STRUCT.finditer(_COMMENT.sub("", source)):
        if m.group(1) != struct:
            continue
        fields = []
        for part in m.group(2).split(","):
            if not part.strip():
                continue
            f = _FIELD.match(part)
            if f is None:
                raise ValueError(f"struct {struct}: cannot read field {part.strip()!r}")
            fields.append((f.group(1), f.group(2).strip()))
        return tuple(fields)
    raise ValueError(f"no struct {struct} in the shader")


def struct_fields(shader: str, struct: str = "Params") -> tuple[tuple[str, str], ...]:
    """(name, WGSL type) of each field of ``struct`` in shader ``shader``, in order."""
    return _fields_of(load_shader_source(shader), struct)


@lru_cache(maxsize=None)
def _layout(shader: str, struct: str, shader_dir: str | None) -> tuple[tuple[str, bool], ...]:
    """(name, is f32) per field, read once per process like the GpuContext's shader modules (a
    uniform is packed for every dispatch, and reading and expanding the WGSL each time was most
    of the renderer's host time); ``shader_dir`` (R360GPU_SHADER_DIR) is part of the key."""
    out = []
    for name, typ in struct_fields(shader, struct):
        if typ not in SCALARS:
            raise ValueError(f"{shader}.wgsl {struct}.{name}: type {typ} is not a 32-bit scalar")
        out.append((name, typ == "f32"))
    return tuple(out)


def pack_words(shader: str, values: dict, struct: str = "Params") -> list:
    """The values of ``struct``'s fields in declaration order, typed for :meth:`GpuContext.uniform`."""
    import os

    fields = _layout(shader, struct, os.environ.get("R360GPU_SHADER_DIR"))
    if len(values) != len(fields) or any(n not in values for n, _ in fields):
        names = [n for n, _ in fields]
        missing = [n for n in names if n not in values]
        unknown = [k for k in values if k not in names]
        raise ValueError(f"{shader}.wgsl {struct}: missing fields {missing}, unknown fields {unknown}")
    return [float(values[n]) if f32 else int(values[n]) for n, f32 in fields]


def uniform(ctx, shader: str, struct: str = "Params", **values):
    """A uniform buffer for ``struct`` of ``shader`` with its fields given by name."""
    return ctx.uniform(*pack_words(shader, values, struct), label=f"{shader}.{struct}")
