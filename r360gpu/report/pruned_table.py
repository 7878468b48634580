"""The pruned what-ifs (``score --prune-residuals Q``): each splat method beside itself without its
top residual Gaussians, on the console and in the tables.

The figures come from ``scenes.S.pruned`` (:mod:`r360gpu.pipeline.residuals`):
``METHOD+pruned`` is never among ``scenes.S.methods``, so it enters no axis
table, aggregate, rank or statistic; here it is shown, labelled, next to the
method it was made from.
"""
from __future__ import annotations

from ..protocol import AXES
from .tables import Cell, Table

#: The columns: the protocol's axes, then RQS.
COLUMNS = (*AXES, "rqs")
LABELS = {"s_sem": "s_sem", "s_geo": "s_geo", "s_str": "s_str", "rqs": "RQS"}
WHAT_IF = "what-if, never ranked"


def _fmt(x) -> str:
    return "—" if not isinstance(x, (int, float)) else f"{x:.3f}"


def _pairs(results: dict):
    """(scene, method entry name, method axes, pruned name, pruned entry) of every pruned what-if."""
    for s, e in results.get("scenes", {}).items():
        for name, p in (e.get("pruned") or {}).items():
            m = p.get("method")
            if m in e.get("methods", {}) and "axes" in p:
                yield s, m, e["methods"][m]["axes"], name, p


def pruned_table(results: dict) -> Table | None:
    """Scenes x methods: the method's axes | the same without its top residuals; None when no scene
    has a pruned what-if."""
    rows, notes = [], []
    for s, m, axes, name, p in _pairs(results):
        rows.append([Cell(s), Cell(m), Cell(f"{p['removed']} of {p['of']}")]
                    + [Cell(_fmt(axes.get(a))) for a in COLUMNS]
                    + [Cell(_fmt(p["axes"].get(a))) for a in COLUMNS])
    if not rows:
        return None
    notes.append(f"METHOD+pruned: the method scored again at the capture views without its top residual "
                 f"Gaussians (score --prune-residuals); a {WHAT_IF}: it enters no other table, aggregate or rank.")
    for s, e in results.get("scenes", {}).items():
        notes += [f"{s} / {name}: {p['note']}." for name, p in (e.get("pruned") or {}).items() if "note" in p]
        notes += [f"{s} / {name}: {p['removed']} of {p['asked']} asked removed: {p['fewer']}."
                  for name, p in (e.get("pruned") or {}).items() if "fewer" in p]
    return Table(
        key="pruned",
        title="Methods without their top residual Gaussians (what-if).",
        header=[Cell("Scene"), Cell("Method"), Cell("pruned")] + [Cell(LABELS[a]) for a in COLUMNS]
        + [Cell(f"+pruned {LABELS[a]}") for a in COLUMNS],
        rows=rows,
        notes=tuple(notes),
        label_columns=2,
    )


def pruned_lines(results: dict) -> list[str]:
    """Console lines: per scene and method, the axes with and without its top residuals."""
    lines = []
    for s, m, axes, name, p in _pairs(results):
        vals = "  ".join(f"{LABELS[a]} {_fmt(axes.get(a))} -> {_fmt(p['axes'].get(a))}" for a in COLUMNS)
        asked = f"; {p['asked']} asked: {p['fewer']}" if "fewer" in p else ""
        lines.append(f"  {s} / {name} ({p['removed']} of {p['of']} Gaussians removed{asked}): {vals}")
    for s, e in results.get("scenes", {}).items():
        lines += [f"  {s} / {name}: {p['note']}" for name, p in (e.get("pruned") or {}).items() if "note" in p]
    return [f"pruned residuals ({WHAT_IF}):"] + lines if lines else []
