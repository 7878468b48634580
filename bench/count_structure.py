"""Structure counts of a checkout of r360gpu: long functions, wide signatures, protocol constants defined twice.

    python bench/count_structure.py [PACKAGE_DIR]      # default: this checkout's r360gpu/

Prints: the number of functions, those over 80 lines (with their names), those with 10 or more
parameters (``self``/``cls`` not counted; ``*args``/``**kwargs`` counted), and for each protocol
constant of :mod:`r360gpu.protocol` how many places define it: its definition in protocol.py (when
the checkout has one) plus every literal copy ``tests/test_protocol_constants.py``'s scanner finds
(default arguments, dataclass fields, module constants, literal tuples, schema strings).  Give the
package folder of an older checkout to count it with today's scanner.
"""
from __future__ import annotations

import ast
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from test_protocol_constants import package_hits  # noqa: E402  (the scanner the test uses)

from r360gpu import protocol  # noqa: E402


def functions(pkg: Path):
    for path in sorted(pkg.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                params = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg not in ("self", "cls")]
                params += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
                yield (f"{path.relative_to(pkg.parent)}:{node.lineno} {node.name}",
                       node.end_lineno - node.lineno + 1, len(params))


def main(argv: list[str]) -> int:
    pkg = Path(argv[0]).resolve() if argv else ROOT / "r360gpu"
    funcs = list(functions(pkg))
    long_ = [(n, ln) for n, ln, _ in funcs if ln > 80]
    wide = [(n, k) for n, _, k in funcs if k >= 10]
    print(f"package: {pkg}")
    print(f"functions: {len(funcs)}")
    print(f"functions over 80 lines: {len(long_)}")
    for n, ln in sorted(long_, key=lambda x: -x[1]):
        print(f"  {ln:4d} lines  {n}")
    print(f"functions with >= 10 parameters: {len(wide)}")
    for n, k in sorted(wide, key=lambda x: -x[1]):
        print(f"  {k:4d} params {n}")
    hits = package_hits(pkg)
    per = Counter(h.split(": ")[1] for h in hits)
    own = (pkg / "protocol.py").exists()
    print("definitions of each protocol constant (protocol.py + literal copies elsewhere):")
    for name in protocol.__all__:
        print(f"  {name:<20} {int(own) + per.get(name, 0)}")
    print(f"literal copies outside protocol.py: {len(hits)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
