"""The capture-vs-orbit table (``score --orbit N``): each method's axes where the capture looked
and from all around the target, side by side, and the orbit's worst views.

The orbit's figures come from ``scenes.S.orbit`` (:mod:`r360gpu.pipeline.orbit`),
a scene entry of its own: they never enter the capture-view axes, the
aggregate tables or any rank.
"""
from __future__ import annotations

from ..protocol import AXES, XI_DEFAULT
from .tables import Cell, Table

#: The columns: the protocol's axes, then RQS.
COLUMNS = (*AXES, "rqs")
LABELS = {"s_sem": "s_sem", "s_geo": "s_geo", "s_str": "s_str", "rqs": "RQS"}
#: Worst orbit views listed per method.
WORST_VIEWS = 3


def _fmt(x) -> str:
    return "—" if x is None else f"{x:.3f}"


def _marked(text: str, verdict) -> str:
    """``text`` with a dagger when the axis' probe check there is not "ok" (weak or blind)."""
    return text + "†" if verdict not in (None, "ok") and text != "—" else text


def doubts(entry: dict) -> str:
    """The not-ok verdicts of a scene entry (the capture's or the orbit's own controls), as
    "s_str weak, s_sem blind" ("" when every axis is ok or unchecked)."""
    return ", ".join(f"{a} {v}" for a, v in (entry.get("validity") or {}).items() if v not in (None, "ok"))


def worst_views(orbit: dict, method: str, xis, k: int = WORST_VIEWS) -> list[tuple[str, float]]:
    """The ``k`` orbit views of ``method`` with the lowest single-view RQS, as (view, rqs)."""
    from ..aggregate.results import per_view_axes

    out = [(v, float(axes["rqs"])) for v, axes in per_view_axes(orbit["methods"][method]["views"], xis=xis).items()
           if axes.get("rqs") is not None]
    return sorted(out, key=lambda t: t[1])[:k]


def orbit_table(results: dict) -> Table | None:
    """Scenes x methods: capture axes | orbit axes; None when no scene has an orbit."""
    scenes = [s for s, e in results.get("scenes", {}).items() if "orbit" in e]
    if not scenes:
        return None
    xis = tuple(results.get("options", {}).get("xis") or (XI_DEFAULT,))
    rows, notes = [], []
    for s in scenes:
        entry, orbit = results["scenes"][s], results["scenes"][s]["orbit"]
        for m, axes in entry["methods"].items():
            checked, around_checked = entry.get("validity") or {}, orbit.get("validity") or {}
            capture = [_marked(_fmt(axes["axes"].get(a)), checked.get(a)) for a in COLUMNS]
            if m in orbit.get("methods", {}):
                o = orbit["methods"][m]["axes"]
                around = [_marked(_fmt(o.get(a)), around_checked.get(a)) for a in COLUMNS]
                worst = worst_views(orbit, m, xis)
                if worst:
                    notes.append(f"{s} / {m}: worst orbit views " + ", ".join(f"{v} (RQS {r:.3f})" for v, r in worst))
            else:
                why = orbit.get("no_orbit", {}).get(m) or orbit.get("note") or "no orbit"
                around = [why] + [""] * (len(COLUMNS) - 1)
            rows.append([Cell(s), Cell(m)] + [Cell(c) for c in capture] + [Cell(c) for c in around])
        dropped = orbit.get("dropped") or {}
        notes.append(f"{s}: {orbit.get('kept', 0)} of {orbit.get('requested', 0)} orbit poses scored"
                     + (" (dropped: " + ", ".join(f"{k} {v}" for k, v in sorted(dropped.items())) + ")"
                        if dropped else ""))
        for where, e in (("capture", entry), ("orbit", orbit)):
            if doubts(e):
                notes.append(f"† {s} {where}: {doubts(e)} (the probe check of its controls): read that axis "
                             f"there with care")
    notes.append("Orbit cameras ring the lifted target at the capture's distance and elevations; their "
                 "scores are a separate scene entry, never mixed into the capture-view axes or ranks.")
    return Table(
        key="orbit",
        title="Capture views vs orbit around the target.",
        header=[Cell("Scene"), Cell("Method")] + [Cell(f"capture {LABELS[a]}") for a in COLUMNS]
        + [Cell(f"orbit {LABELS[a]}") for a in COLUMNS],
        rows=rows,
        notes=tuple(notes),
        label_columns=2,
    )


def orbit_lines(results: dict) -> list[str]:
    """Console lines: per scene how many orbit poses were scored (and why the others were dropped),
    then per method the axes at the capture views and from the orbit, as in `orbit_table`."""
    lines = []
    for s, entry in results.get("scenes", {}).items():
        orbit = entry.get("orbit")
        if orbit is None:
            continue
        dropped = orbit.get("dropped") or {}
        lines.append(f"  {s}: {orbit.get('kept', 0)} of {orbit.get('requested', 0)} poses scored"
                     + (" (dropped: " + ", ".join(f"{k} {v}" for k, v in sorted(dropped.items())) + ")"
                        if dropped else "") + (f"; at the orbit {doubts(orbit)}" if doubts(orbit) else ""))
        for m, capture in entry.get("methods", {}).items():
            if m in orbit.get("methods", {}):
                around = orbit["methods"][m]["axes"]
                vals = "  ".join(f"{LABELS[a]} {_fmt(capture['axes'].get(a))} -> {_fmt(around.get(a))}"
                                 for a in COLUMNS)
                lines.append(f"  {s} / {m}: {vals}")
            else:
                lines.append(f"  {s} / {m}: {orbit.get('no_orbit', {}).get(m) or orbit.get('note') or 'no orbit'}")
    head = "orbit around the target (capture -> orbit; a separate scene entry, never ranked):"
    return [head] + lines if lines else []
