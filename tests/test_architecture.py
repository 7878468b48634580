"""The import graph follows docs/architecture.md: each package imports only the packages its row
allows (imports parsed with ast, lazy imports inside functions included), and the package graph has
no cycle."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parent.parent / "r360gpu"
DOC = PKG.parent / "docs" / "architecture.md"

#: Leaves every package may import: the error types, the protocol's constants, the stages' data types,
#: the version string.
LEAVES = {"errors", "protocol", "schema", "__version__"}
#: What each package (or top-level module) imports besides LEAVES, and so may import: the data flow
#: io/bundle (load) -> render -> probes -> metrics -> aggregate -> report, pipeline running them,
#: the generator, viewer and command line on top.  Exactly the edges some import uses
#: (test_every_allowed_edge_is_used): a new edge is added here on purpose, not found already open.
#: Keep in step with docs/architecture.md.
ALLOWED: dict[str, set[str]] = {
    "errors": set(),
    "protocol": set(),
    "schema": set(),
    "util": set(),
    "gpu": set(),
    "io": {"util"},
    "kernels": {"gpu", "util"},
    "bundle": {"io", "util"},
    "render": {"gpu", "io"},
    "probes": {"io", "util"},
    "metrics": {"gpu", "kernels", "render", "probes", "util"},
    "aggregate": {"metrics"},
    "report": {"aggregate", "metrics", "util"},
    "pipeline": {"gpu", "kernels", "io", "bundle", "render", "probes", "metrics", "aggregate", "lift", "report",
                 "util"},
    "lift": {"gpu", "io", "render"},
    "synthetic": {"io", "bundle", "render", "util"},
    "viewer": {"gpu", "kernels", "io", "bundle", "render", "probes", "metrics", "lift", "pipeline", "util"},
    "cli": {"gpu", "kernels", "io", "bundle", "render", "probes", "metrics", "aggregate", "lift", "report",
            "pipeline", "synthetic", "viewer", "util"},
    "__main__": {"cli", "util"},
    # the package facade's lazy top-level names
    "__init__": {"bundle", "pipeline", "render"},
}


def _module_name(path: Path) -> list[str]:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    return parts[:-1] if parts[-1] == "__init__" else parts


def imports_of(path: Path) -> set[str]:
    """The r360gpu modules ``path`` imports (dotted, absolute), at any depth of its code."""
    mod = _module_name(path)
    return imports_in(path.read_text(encoding="utf-8"), mod if path.name == "__init__.py" else mod[:-1])


def imports_in(source: str, pkg: list[str]) -> set[str]:
    """The r360gpu modules ``source`` imports, relative imports resolved against package ``pkg``."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - (node.level - 1)] + (node.module.split(".") if node.module else [])
            else:
                base = (node.module or "").split(".")
            if base[0] != "r360gpu":
                continue
            if len(base) == 1 or node.module is None:  # from r360gpu import x / from . import x: x may be a module
                out.update(".".join(base + [a.name]) for a in node.names)
            else:
                out.add(".".join(base))
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.split(".")[0] == "r360gpu")
    return out


def _unit(dotted: str) -> str:
    """The package (or top-level module) a dotted r360gpu module belongs to."""
    parts = dotted.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def package_edges() -> dict[str, dict[str, list[str]]]:
    """{package: {imported package: [files that import it]}}, self-imports left out."""
    edges: dict[str, dict[str, list[str]]] = {}
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG)
        src = rel.parts[0].removesuffix(".py") if len(rel.parts) >= 1 else "__init__"
        for target in imports_of(path):
            dst = _unit(target)
            if dst != src:
                edges.setdefault(src, {}).setdefault(dst, []).append(str(rel))
    return edges


def test_every_package_has_a_row():
    units = {p.name.removesuffix(".py") for p in PKG.iterdir()
             if (p.is_dir() and (p / "__init__.py").exists()) or (p.suffix == ".py")}
    assert units - set(ALLOWED) == set(), "add the new package to ALLOWED and docs/architecture.md"
    assert set(ALLOWED) - units == set()


def violations(edges: dict[str, dict[str, list[str]]]) -> list[str]:
    return [f"{src} -> {dst} ({', '.join(sorted(set(files))[:3])})"
            for src, dsts in edges.items() for dst, files in dsts.items()
            if dst not in ALLOWED.get(src, set()) | LEAVES]


def test_imports_follow_the_allowed_edges():
    bad = violations(package_edges())
    assert not bad, "imports against the data flow (docs/architecture.md):\n" + "\n".join(bad)


def unused_edges(edges: dict[str, dict[str, list[str]]]) -> list[str]:
    """Allowed edges no import uses ("src -> dst")."""
    return [f"{src} -> {dst}" for src, allowed in ALLOWED.items() for dst in sorted(allowed)
            if dst not in edges.get(src, {})]


def test_every_allowed_edge_is_used():
    unused = unused_edges(package_edges())
    assert not unused, ("allowed edges no import uses (drop them from ALLOWED and docs/architecture.md):\n"
                        + "\n".join(unused))


def test_an_unused_edge_is_reported():
    edges = {s: {d: ["x.py"] for d in allowed} for s, allowed in ALLOWED.items()}
    assert unused_edges(edges) == []
    del edges["lift"]["render"]
    assert unused_edges(edges) == ["lift -> render"]


def test_package_graph_has_no_cycle():
    # the facade (__init__) and the version string are outside the flow
    graph = {s: {d for d in dsts if d in ALLOWED and d != "__init__"}
             for s, dsts in package_edges().items() if s != "__init__"}
    seen, on_path = set(), []

    def visit(n):
        if n in on_path:
            raise AssertionError("import cycle: " + " -> ".join(on_path[on_path.index(n):] + [n]))
        if n in seen:
            return
        on_path.append(n)
        for m in sorted(graph.get(n, ())):
            visit(m)
        on_path.pop()
        seen.add(n)

    for n in sorted(graph):
        visit(n)


def test_the_doc_states_the_same_table():
    text = DOC.read_text(encoding="utf-8")
    for src, allowed in ALLOWED.items():
        if src.startswith("__"):
            continue
        row = next((line for line in text.splitlines() if line.startswith(f"| `{src}` |")), None)
        assert row is not None, f"docs/architecture.md has no row for {src}"
        cells = row.split("|")[3]
        listed = {c.strip(" `") for c in cells.split(",") if c.strip(" `-")}
        assert listed == allowed, f"{src}: doc lists {sorted(listed)}, test allows {sorted(allowed)}"


@pytest.mark.parametrize("src, expect", [
    ("from ..pipeline import evaluate\n", {"r360gpu.pipeline"}),
    ("from . import json_values\n", {"r360gpu.metrics.json_values"}),
    ("from .semantic import acc_seg\n", {"r360gpu.metrics.semantic"}),
    ("import r360gpu.render.sort\n", {"r360gpu.render.sort"}),
    ("def f():\n    from ..report.html import x\n", {"r360gpu.report.html"}),
    ("from r360gpu import protocol, errors\n", {"r360gpu.protocol", "r360gpu.errors"}),
    ("from .. import __version__\nimport numpy\n", {"r360gpu.__version__"}),
])
def test_import_parser(src, expect):
    assert imports_in(src, ["r360gpu", "metrics"]) == expect


#: The data flow, stage by stage (docs/architecture.md): a package imports only its own stage and the
#: ones before it.  The runners (pipeline, synthetic, viewer, cli) sit above the flow; the only way
#: back up is the facade's lazy top-level names (``__init__``).
FLOW = [{"util", "gpu", "kernels"}, {"io", "bundle"}, {"render", "lift"}, {"probes"}, {"metrics"}, {"aggregate"},
        {"report"}]
RUNNERS = {"pipeline", "synthetic", "viewer", "cli", "__main__", "__init__"}


def edges_up_the_flow(allowed: dict[str, set[str]]) -> list[str]:
    """"src -> dst" of every allowed edge from a stage of FLOW to a later stage or to a runner."""
    stage = {pkg: i for i, pkgs in enumerate(FLOW) for pkg in pkgs}
    return sorted(f"{src} -> {dst}" for src, dsts in allowed.items() if src in stage for dst in dsts
                  if dst in RUNNERS or stage.get(dst, -1) > stage[src])


def test_no_allowed_edge_runs_up_the_flow():
    """ALLOWED itself (so every import, lazy ones inside functions too: imports_in walks the whole
    module) keeps to the flow; every package is in FLOW or a runner."""
    assert set(ALLOWED) - LEAVES == {p for pkgs in FLOW for p in pkgs} | RUNNERS
    assert edges_up_the_flow(ALLOWED) == []


def test_an_allowed_edge_up_the_flow_is_reported():
    assert edges_up_the_flow({**ALLOWED, "metrics": {"render", "aggregate"}, "probes": {"pipeline"}}) == [
        "metrics -> aggregate", "probes -> pipeline"]


def test_an_edge_up_the_flow_is_reported():
    edges = {"report": {"pipeline": ["report/html.py"]}, "pipeline": {"report": ["pipeline/evaluate.py"]}}
    assert violations(edges) == ["report -> pipeline (report/html.py)"]


def private_imports(source: str, pkg: list[str]) -> list[str]:
    """``module.name`` of every private name (``_x``, or anything in a ``_x`` module) that ``source``,
    a module of package ``pkg``, imports from ANOTHER r360gpu package (a package's private helpers
    are its own; another package gets a public name)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = pkg[: len(pkg) - (node.level - 1)] + (node.module.split(".") if node.module else [])
        else:
            base = (node.module or "").split(".")
        if base[0] != "r360gpu" or _unit(".".join(base + ["x"])) == _unit(".".join(pkg + ["x"])):
            continue
        for a in node.names:
            dotted = ".".join(base + [a.name])
            if any(p.startswith("_") and not p.startswith("__") for p in dotted.split(".")[1:]):
                out.append(dotted)
    return out


def test_no_private_name_is_imported_across_packages():
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        mod = _module_name(path)
        pkg = mod if path.name == "__init__.py" else mod[:-1]
        bad += [f"{path.relative_to(PKG)}: {d}" for d in private_imports(path.read_text(encoding="utf-8"), pkg)]
    assert not bad, "private names imported from another package (give them a public name):\n" + "\n".join(bad)


@pytest.mark.parametrize("pkg, src, expect", [
    ("report", "from ..metrics import _json\n", ["r360gpu.metrics._json"]),
    ("pipeline", "def f():\n    from ..bundle.load import _parse_source\n", ["r360gpu.bundle.load._parse_source"]),
    ("report", "from r360gpu.metrics._masks import where\n", ["r360gpu.metrics._masks.where"]),
    ("report", "from ..metrics import json_values\nfrom .. import __version__\n", []),
    ("metrics", "from ._masks import where\nfrom .semantic import _private\n", []),  # inside its own package
])
def test_private_import_parser(pkg, src, expect):
    assert private_imports(src, ["r360gpu", pkg]) == expect


# ---- private attributes: a package's ``_names`` are used inside it only -------------------------
# Imports are checked above; this checks attribute access (``renderer._prepare(...)``) and the
# overriding of another package's private methods in a subclass, which need no import of the name.

def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_definitions(sources: dict[str, list[str]]) -> dict[str, set[str]]:
    """{private name: packages defining it} over ``sources`` ({package: its modules' sources}):
    functions, classes, methods, assigned attributes and names."""
    out: dict[str, set[str]] = {}
    for unit, texts in sources.items():
        for text in texts:
            for node in ast.walk(ast.parse(text)):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    names = [node.name]
                elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                    names = [node.attr]
                elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                    names = [node.id]
                else:
                    continue
                for name in names:
                    if _private(name):
                        out.setdefault(name, set()).add(unit)
    return out


def _import_units(tree: ast.AST, pkg: list[str]) -> tuple[dict[str, str], set[str]]:
    """({local name: r360gpu package it was imported from}, {names bound by imports from outside r360gpu})."""
    ours, outside = {}, set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - (node.level - 1)] + (node.module.split(".") if node.module else [])
            else:
                base = (node.module or "").split(".")
            for a in node.names:
                if base[0] == "r360gpu":
                    ours[a.asname or a.name] = _unit(".".join(base + [a.name]))
                else:
                    outside.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] != "r360gpu":
                    outside.add(a.asname or a.name.split(".")[0])
    return ours, outside


def private_attributes(source: str, pkg: list[str], defined: dict[str, set[str]], unit: str) -> list[str]:
    """Uses, in ``source`` (a module of package ``pkg``, part ``unit`` of the table), of private attributes
    that another r360gpu package defines and this one does not (``line: name``), and methods of a subclass
    of another package's class that override a private name of that package (``line: overrides pkg.name``)."""
    tree = ast.parse(source)
    ours, outside = _import_units(tree, pkg)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            owners = defined.get(node.attr, set())
            if isinstance(node.value, ast.Name) and node.value.id in outside:
                continue  # e.g. os._exit: not an r360gpu name
            if owners and unit not in owners:
                out.append(f"{node.lineno}: {node.attr} (defined in {', '.join(sorted(owners))})")
        elif isinstance(node, ast.ClassDef):
            bases = {ours[b.id] for b in node.bases if isinstance(b, ast.Name) and b.id in ours} - {unit}
            for item in node.body:
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)) and _private(item.name):
                    for base in sorted(bases & defined.get(item.name, set())):
                        out.append(f"{item.lineno}: overrides {base}.{item.name}")
    return out


def _modules() -> dict[Path, tuple[list[str], str, str]]:
    """{path: (its package, its unit of the table, its source)} of every r360gpu module."""
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        mod = _module_name(path)
        out[path] = (mod if path.name == "__init__.py" else mod[:-1], _unit(".".join(mod)),
                     path.read_text(encoding="utf-8"))
    return out


def test_no_private_attribute_is_used_across_packages():
    files = _modules()
    by_unit: dict[str, list[str]] = {}
    for _, unit, text in files.values():
        by_unit.setdefault(unit, []).append(text)
    defined = private_definitions(by_unit)
    bad = [f"{path.relative_to(PKG)}:{use}" for path, (pkg, unit, text) in files.items()
           for use in private_attributes(text, pkg, defined, unit)]
    assert not bad, ("another package's private attributes used (give them a public name, or use the "
                     "package's public interface):\n" + "\n".join(bad))


_RENDERER = "class Renderer:\n    def _prepare(self):\n        self._frames = 1\n    def _record_tiles(self):\n        pass\n"


@pytest.mark.parametrize("pkg, src, expect", [
    ("lift", "def f(renderer):\n    return renderer._prepare()\n", ["2: _prepare (defined in render)"]),
    ("lift", "class L:\n    def g(self):\n        return self._frames\n", ["3: _frames (defined in render)"]),
    ("lift", "from ..render.renderer import Renderer\nclass L(Renderer):\n    def _record_tiles(self):\n        pass\n",
     ["3: overrides render._record_tiles"]),
    ("lift", "import os\ndef f():\n    os._exit(1)\n", []),  # not an r360gpu name
    ("lift", "class L:\n    def _prepare(self):\n        pass\n    def g(self):\n        return self._prepare()\n",
     []),  # lift's own _prepare
    ("render", "def f(r):\n    return r._record_tiles()\n", []),  # inside its own package
    ("lift", "def f(r):\n    return r._unknown_elsewhere\n", []),  # no r360gpu package defines it
])
def test_private_attribute_parser(pkg, src, expect):
    defined = private_definitions({"render": [_RENDERER], pkg: [src]})
    assert private_attributes(src, ["r360gpu", pkg], defined, pkg) == expect
