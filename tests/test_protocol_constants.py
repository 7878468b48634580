"""Protocol constants are written once, in r360gpu/protocol.py.

The scanner walks the syntax tree of every module of the package and reports a protocol literal
written again: a default argument or dataclass field (``xi=0.3``, ``nu: float = 1000.0``), a
module constant bound to a literal (``XI = 0.3``, ``SCHEMA = "r360gpu.results/1"``), a
tuple/list/set of the axis names or of sweep thresholds (``(0.3,)`` included), a schema string, a
statistics default (``default=20000``).

Output prose too (table notes and headers, report text, help and messages: every string that is
not a docstring) gets the values from r360gpu.protocol (``f"xi = {XI_DEFAULT:g}"``): the prose
scanner reports a protocol value written into such a string beside its symbol.  Docstrings and
comments explain the code and may say "xi = 0.3".
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from r360gpu import protocol as P

PKG = Path(P.__file__).resolve().parent

#: Parameter / field names whose literal default is a protocol value, and that constant's name.
PARAM_CONSTANTS = {
    "xi": "XI_DEFAULT", "retain_iou": "RETAIN_IOU", "nu": "GHT_NU", "tau": "GHT_TAU", "kappa": "GHT_KAPPA",
    "omega": "GHT_OMEGA", "n_bins": "GHT_BINS", "n_boot": "N_BOOT", "n_perm": "N_PERM", "ci_level": "CI_LEVEL",
}
PARAM_VALUES = {k: getattr(P, c) for k, c in PARAM_CONSTANTS.items()}
#: Module-level aliases of protocol constants used before r360gpu.protocol existed.
ALIASES = {"XI": "XI_DEFAULT", "DEFAULT_XIS": "XI_SWEEP", "XIS": "XI_SWEEP", "SCHEMA": "RESULTS_SCHEMA"}
#: Module-level names that must not be bound to a literal outside protocol.py.
CONSTANT_NAMES = set(P.__all__) | set(ALIASES)
#: Literal sequences that are protocol constants (compared as tuples, and as sets for sets).
SEQUENCES = {"AXES": P.AXES, "XI_SWEEP": P.XI_SWEEP, "XI_PUBLIC": P.XI_PUBLIC,
             "BOUNDARY_PX": P.BOUNDARY_PX, "STRUCTURAL_MODES": P.STRUCTURAL_MODES}
SCHEMAS = {P.RESULTS_SCHEMA: "RESULTS_SCHEMA", P.VIEW_RECORD_SCHEMA: "VIEW_RECORD_SCHEMA"}
#: Call keywords that give a statistics default (argparse ``default=``).
STAT_DEFAULTS = {P.N_BOOT: "N_BOOT", P.N_PERM: "N_PERM"}


def _literal(node: ast.AST):
    try:
        return ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError, RecursionError):
        return None


def _eq(value, target) -> bool:
    return type(value) is not bool and isinstance(value, (int, float)) and value == target


def _seq_hit(node: ast.AST) -> str | None:
    """The name of the protocol sequence ``node`` writes out literally, if any."""
    if not isinstance(node, (ast.Tuple, ast.List, ast.Set)) or not node.elts:
        return None
    vals = _literal(node)
    if vals is None:
        return None
    for name, seq in SEQUENCES.items():
        if isinstance(node, ast.Set) and set(vals) == set(seq):
            return name
        if tuple(vals) == tuple(seq):
            return name
    # a set or tuple of acc_seg thresholds that includes the default ({0.3}, (0.3, 0.7)):
    # the thresholds of a sweep written again
    if all(isinstance(v, float) for v in vals) and P.XI_DEFAULT in vals and set(vals) <= set(P.XI_SWEEP) \
            and (isinstance(node, (ast.Set, ast.Tuple)) or len(vals) > 1):
        return "XI_SWEEP"
    return None


def scan(source: str, filename: str = "<src>") -> list[str]:
    """Protocol literals written in ``source``: one line 'file:line: CONSTANT: what' each."""
    tree = ast.parse(source, filename)
    hits: list[str] = []

    def hit(node: ast.AST, what: str, const: str) -> None:
        hits.append(f"{filename}:{node.lineno}: {const}: {what}")

    def check_default(name: str, default: ast.AST | None, node: ast.AST) -> None:
        if default is None or name not in PARAM_VALUES:
            return
        v = _literal(default)
        if _eq(v, PARAM_VALUES[name]):
            hit(node, f"literal default {name}={v!r}", PARAM_CONSTANTS[name])

    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            a = node.args
            pos = a.posonlyargs + a.args
            for arg, d in zip(pos[len(pos) - len(a.defaults):], a.defaults):
                check_default(arg.arg, d, d)
            for arg, d in zip(a.kwonlyargs, a.kw_defaults):
                check_default(arg.arg, d, d if d is not None else node)
        elif isinstance(node, ast.ClassDef):
            for stmt in node.body:
                if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
                    check_default(stmt.target.id, stmt.value, stmt)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in SCHEMAS:
            hit(node, f"schema string {node.value!r}", SCHEMAS[node.value])
        elif isinstance(node, ast.Call):
            for kw in node.keywords:
                for value, const in STAT_DEFAULTS.items():
                    if kw.arg == "default" and _eq(_literal(kw.value), value):
                        hit(kw.value, f"statistics default={value!r}", const)
        elif isinstance(node, ast.Dict):
            for k, v in zip(node.keys, node.values):
                if isinstance(k, ast.Constant) and k.value in PARAM_VALUES and _eq(_literal(v), PARAM_VALUES[k.value]):
                    hit(v, f"literal {k.value!r}: {_literal(v)!r}", PARAM_CONSTANTS[k.value])
        what = _seq_hit(node)
        if what:
            hit(node, f"literal copy: {ast.unparse(node)}", what)
    for stmt in tree.body:
        targets = stmt.targets if isinstance(stmt, ast.Assign) else [stmt.target] if isinstance(stmt, ast.AnnAssign) else []
        value = getattr(stmt, "value", None)
        for t in targets:
            if isinstance(t, ast.Name) and t.id in CONSTANT_NAMES and value is not None \
                    and _literal(value) is not None:
                hit(stmt, f"module constant {t.id} bound to a literal", ALIASES.get(t.id, t.id))
    return sorted(set(hits))


def package_hits(pkg: Path = PKG) -> list[str]:
    """Every protocol literal in the package rooted at ``pkg`` (its own protocol.py excepted)."""
    out = []
    for path in sorted(pkg.rglob("*.py")):
        if path.name == "protocol.py" and path.parent == pkg:
            continue
        out += scan(path.read_text(encoding="utf-8"), str(path.relative_to(pkg.parent)))
    return out


def test_no_protocol_literal_outside_protocol_module():
    hits = package_hits()
    assert not hits, "protocol constants written again (import them from r360gpu.protocol):\n" + "\n".join(hits)


@pytest.mark.parametrize("src, expect", [
    ("def f(xi=0.3): pass", "literal default xi=0.3"),
    ("def f(*, xi: float = 0.3): pass", "literal default xi=0.3"),
    ("def f(xis=(0.3, 0.5)): pass", "XI_PUBLIC"),
    ("A = {0.3}", "XI_SWEEP"),
    ("AXES = ('s_sem', 's_geo', 's_str')", "AXES"),
    ("for a in ['s_sem', 's_geo', 's_str']: pass", "AXES"),
    ("XI = 0.3", "module constant XI"),
    ("S = 'r360gpu.results/1'", "schema string"),
    ("class G:\n    nu: float = 1000.0\n", "literal default nu=1000.0"),
    ("p.add_argument('--n-boot', default=20000)", "statistics default=20000"),
    ("settings = {'ci_level': 0.95}", "literal 'ci_level': 0.95"),
    ("OFFS = (-15, -10, -5, 0, 5, 10, 15)[4:]", None),
    ("def f(xis=(0.3,)): pass", "XI_SWEEP"),
])
def test_scanner_finds_each_kind_of_copy(src, expect):
    hits = scan(src)
    if expect is None:
        assert hits == []
    else:
        assert any(expect in h for h in hits), hits


def test_scanner_ignores_prose_and_other_numbers():
    src = '"""s_sem = acc_seg at xi = 0.3; nu=1000."""\n# xi=0.3\ndef f(x=0.3, alpha=0.1): return (0.3, 3.0)\n'
    assert scan(src) == []


def test_protocol_values_match_the_spec():
    # docs/protocol.md: "Default ξ = 0.3; the sensitivity sweep reports ξ ∈ {0.3, 0.5, 0.7, 0.9}",
    # "IoU with M^v is ≥ 0.1", "nu = 1000, tau = 300, kappa = 0, omega = 0", "256 bins",
    # "RQS = (s_sem · s_geo · s_str)^(1/3)", "20,000 resamples", dilate "by 5, 10, 15 px".
    assert P.XI_DEFAULT == 0.3 and P.XI_SWEEP == (0.3, 0.5, 0.7, 0.9) and P.XI_DEFAULT in P.XI_PUBLIC
    assert P.RETAIN_IOU == 0.1
    assert (P.GHT_NU, P.GHT_TAU, P.GHT_KAPPA, P.GHT_OMEGA, P.GHT_BINS) == (1000, 300, 0, 0, 256)
    assert P.AXES == ("s_sem", "s_geo", "s_str")
    assert P.N_BOOT == 20000 and P.BOUNDARY_PX == (5, 10, 15)


#: A protocol value in output prose: (constant, the value as written, the symbols it stands beside
#: (within PROSE_WINDOW characters either side); None: the number alone says which constant).
PROSE_VALUES = [
    ("XI_DEFAULT", r"0\.3", r"xi|ξ|threshold|acc_seg|\bseg\b|iou|s_sem"),
    ("RETAIN_IOU", r"0\.1", r"iou|retain"),
    ("GHT_NU / GHT_TAU", r"1000|300", r"\bnu\b|\btau\b|ν|τ"),
    ("N_BOOT", r"20,?000", r"resampl|bootstrap|default|n.boot"),
    ("N_PERM", r"5,?000", r"permut|default|n.perm"),
    ("CI_LEVEL", r"95 ?\\?%|0\.95", r"\bCI\b|confidence"),
    ("BOUNDARY_PX", r"5\D{1,3}10\D{1,3}15", None),
]
PROSE_WINDOW = 16


def _output_strings(tree: ast.AST):
    """The string constants of ``tree`` that can reach output: all but docstrings (a string alone as
    a statement), f-string pieces included."""
    docs = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            yield node


def prose_scan(source: str, filename: str = "<src>") -> list[str]:
    """Protocol values written into the output strings of ``source``: 'file:line: CONSTANT: text'."""
    import re

    hits = []
    for node in _output_strings(ast.parse(source, filename)):
        text = node.value
        for const, value, symbols in PROSE_VALUES:
            for m in re.finditer(rf"(?<![\d.])(?<!\d,)(?:{value})(?!\d|,\d)", text):
                near = text[max(0, m.start() - PROSE_WINDOW): m.end() + PROSE_WINDOW]
                if symbols is None or re.search(symbols, near, re.IGNORECASE):
                    hits.append(f"{filename}:{node.lineno}: {const}: {text[:80]!r}")
    return sorted(set(hits))


def test_no_protocol_value_typed_into_output_prose():
    hits = []
    for path in sorted(PKG.rglob("*.py")):
        if not (path.name == "protocol.py" and path.parent == PKG):
            hits += prose_scan(path.read_text(encoding="utf-8"), str(path.relative_to(PKG.parent)))
    assert not hits, ("protocol values typed into output text (format them from r360gpu.protocol, "
                      "f\"xi = {XI_DEFAULT:g}\"):\n" + "\n".join(hits))


@pytest.mark.parametrize("src, expect", [
    ('NOTE = "s_sem uses xi = 0.3; higher thresholds count fewer views"', "XI_DEFAULT"),
    ('h = ("acc_seg (xi=0.3)", r"acc$_{\\mathrm{seg},0.3}$")', "XI_DEFAULT"),
    ('t = f"IoU_post &lt; 0.3; {n} views"', "XI_DEFAULT"),
    ('t = f"below {low:g} (s_sem 0/1 at xi = 0.3, acc_depth)"', "XI_DEFAULT"),
    ('p.add_argument("--xi", help="(0.3 is s_sem and always reported)")', "XI_DEFAULT"),
    ('c = Cell("95% CI", r"95\\% CI")', "CI_LEVEL"),
    ('h = "bootstrap resamples (default: 20000)"', "N_BOOT"),
    ('h = "GHT with nu = 1000"', "GHT_NU"),
    ('m = "masks with IoU >= 0.1 are kept"', "RETAIN_IOU"),
    ('m = "erode by 5, 10, 15 px"', "BOUNDARY_PX"),
])
def test_prose_scanner_finds_a_typed_value(src, expect):
    hits = prose_scan(src)
    assert any(expect in h for h in hits), hits


def test_prose_scanner_leaves_docstrings_formatted_values_and_other_numbers():
    src = ('"""s_sem = acc_seg at xi = 0.3; nu = 1000, 95% CI."""\n'
           'def f(n):\n    """xi = 0.3"""\n'
           '    return f"xi = {XI_DEFAULT:g}; opacity 0.3; width:95%; {n:.3f}; 0.35 of 20001; port 5000x"\n'
           'CSS = "a{opacity:0.3} b{width:95%}"\n')
    assert prose_scan(src) == []
