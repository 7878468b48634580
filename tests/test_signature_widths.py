"""No function in pipeline/, metrics/ or report/ takes more than MAX_PARAMS parameters (counted with
ast: positional, keyword-only, ``*args`` and ``**kwargs``; ``self`` and ``cls`` not): what a stage
hands to the next goes in a typed object (r360gpu.schema, PictureJob, MeasureJob), not in a long
list of keywords."""
from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parent.parent / "r360gpu"
PACKAGES = ("pipeline", "metrics", "report")
MAX_PARAMS = 10


def n_params(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names) + (a.vararg is not None) + (a.kwarg is not None)


def widths(source: str) -> dict[str, int]:
    """{function name: parameters} of every function (methods and nested functions too) in ``source``."""
    return {n.name: n_params(n) for n in ast.walk(ast.parse(source))
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}


def wide_functions() -> dict[str, int]:
    out = {}
    for pkg in PACKAGES:
        for path in sorted((PKG / pkg).rglob("*.py")):
            for name, k in widths(path.read_text(encoding="utf-8")).items():
                if k > MAX_PARAMS:
                    out[f"{path.relative_to(PKG).as_posix()}:{name}"] = k
    return out


def test_no_wide_function():
    wide = wide_functions()
    assert not wide, f"functions with more than {MAX_PARAMS} parameters (pass a typed object instead): {wide}"


def test_the_count():
    src = ("def f(a, b=1, *c, d, e=2, **f): pass\n"
           "class C:\n    def m(self, x): pass\n    @classmethod\n    def k(cls): pass\n"
           "def g(x, /, y): pass\n")
    assert widths(src) == {"f": 6, "m": 1, "k": 0, "g": 2}
