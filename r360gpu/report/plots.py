"""Plots of the results (matplotlib, Agg, no pyplot state): per-view axes along the
camera path, and an overview of the overall axes per method.

Rendering is deterministic: matplotlib's default style with fixed sizes and
fonts (the bundled DejaVu Sans), a fixed DPI and no PNG metadata (no
timestamps, no version string), so the same values give the same bytes with
the same matplotlib.
"""
from __future__ import annotations

import io
import math
import os
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

import matplotlib
import matplotlib.style
from matplotlib.figure import Figure

from ..protocol import XI_DEFAULT
from ..util.atomic import write_bytes
from .results_io import number

_RC = {
    "font.family": "DejaVu Sans",
    "font.size": 8,
    "axes.titlesize": 9,
    "legend.fontsize": 7,
    "figure.dpi": 100,
    "savefig.dpi": 100,
    "path.simplify": False,
}
_DPI = 100
#: Colours of the axes (matplotlib's tab10 entries, fixed).
AXIS_COLORS = {"s_sem": "#1f77b4", "s_geo": "#ff7f0e", "s_str": "#2ca02c", "rqs": "#7f7f7f"}
_PROBE_STYLES = ("-", "--", ":", "-.")


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI, metadata={"Software": None})
    return buf.getvalue()


@contextmanager
def _style():
    """Context: matplotlib's default style plus the fixed settings above
    (so a user's matplotlibrc or style cannot change the pictures)."""
    with matplotlib.style.context("default"), matplotlib.rc_context(rc=_RC):
        yield


def _record(rec) -> dict:
    return rec.to_dict() if hasattr(rec, "to_dict") else rec


def _nan(x) -> float:
    v = number(x)
    return math.nan if v is None else v


def view_series(views: Sequence) -> dict:
    """Per-view series of one (scene, method) from its view records.

    views: ViewRecord objects or their ``to_dict()`` dicts, in camera-path order.

    Returns {"names": [view], "iou_post": {probe: [float]}, "sim_sam": {probe: [float]},
    "acc_depth": [float], "excluded": [bool], "mode": str | None}; missing values
    and every value of a view whose target mask is empty are NaN; ``excluded``
    marks those views (excluded from the means).
    """
    recs = [_record(r) for r in views]
    sem_probes: list[str] = []
    str_probes: list[str] = []
    for r in recs:
        sem_probes += [p for p in (r.get("semantic") or {}) if p not in sem_probes]
        str_probes += [p for p in (r.get("structural") or {}) if p not in str_probes]
    def reading(rec: dict, axis: str, probe: str, key: str) -> float:
        v = (rec.get(axis) or {}).get(probe) or {}
        # An empty target makes the reading meaningless (IoU 0, sim 1 by convention): not plotted.
        return math.nan if v.get("empty_target") else _nan(v.get(key))

    iou = {p: [reading(r, "semantic", p, "iou_post") for r in recs] for p in sem_probes}
    sim = {p: [reading(r, "structural", p, "sim_sam") for r in recs] for p in str_probes}
    depth, excluded, modes = [], [], []
    for r in recs:
        geo = r.get("geometric") or {}
        ex = bool(geo.get("excluded")) or any(
            bool(v.get("empty_target")) for v in list((r.get("semantic") or {}).values())
            + list((r.get("structural") or {}).values()))
        excluded.append(ex)
        depth.append(math.nan if geo.get("excluded") else _nan(geo.get("acc_depth")))
        modes += [v.get("mode") for v in (r.get("structural") or {}).values() if v.get("mode")]
    mode = modes[0] if modes and all(m == modes[0] for m in modes) else None
    return {"names": [str(r.get("view", i)) for i, r in enumerate(recs)], "iou_post": iou, "sim_sam": sim,
            "acc_depth": depth, "excluded": excluded, "mode": mode}


def view_axes_png(views: Sequence, *, title: str | None = None, xi: float = XI_DEFAULT) -> bytes:
    """PNG bytes (800 x 300 px) of the per-view axes along the camera path.

    Lines: IoU_post per semantic probe (below ``xi`` the object counts as not
    detected; dashed line), acc_depth, and sim_SAM per structural probe, against
    the view index (view names as tick labels for up to 24 views).  Views with an
    empty target mask (excluded from the means) are shaded grey and marked x.
    """
    s = view_series(views)
    n = len(s["names"])
    xs = list(range(n))
    with _style():
        fig = Figure(figsize=(8.0, 3.0), dpi=_DPI)
        ax = fig.add_axes((0.07, 0.2, 0.66, 0.68))
        multi_sem = len(s["iou_post"]) > 1
        for k, (p, ys) in enumerate(s["iou_post"].items()):
            ax.plot(xs, ys, _PROBE_STYLES[k % 4], marker="o", ms=3, lw=1.2, color=AXIS_COLORS["s_sem"],
                    label="IoU_post" + (f" ({p})" if multi_sem else ""))
        if any(not math.isnan(v) for v in s["acc_depth"]):
            ax.plot(xs, s["acc_depth"], "-", marker="s", ms=3, lw=1.2, color=AXIS_COLORS["s_geo"], label="acc_depth")
        sim_label = {"reference": "sim_SAM(post, ref)",
                     "reference_free": "sim_SAM(pre, post)"}.get(s["mode"], "sim_SAM")
        multi_str = len(s["sim_sam"]) > 1
        for k, (p, ys) in enumerate(s["sim_sam"].items()):
            ax.plot(xs, ys, _PROBE_STYLES[k % 4], marker="^", ms=3, lw=1.2, color=AXIS_COLORS["s_str"],
                    label=sim_label + (f" ({p})" if multi_str else ""))
        ax.axhline(xi, color="#1f77b4", lw=0.8, ls=(0, (4, 3)), alpha=0.7, label=f"xi = {xi:g} (IoU_post)")
        ex = [i for i, e in enumerate(s["excluded"]) if e]
        for i in ex:
            ax.axvspan(i - 0.5, i + 0.5, color="#bbbbbb", alpha=0.5, lw=0)
        if ex:
            ax.plot(ex, [0.0] * len(ex), "x", color="#555555", ms=6, mew=1.5, ls="none",
                    label="excluded (empty target)")
        ax.set_xlim(-0.5, max(n - 0.5, 0.5))
        ax.set_ylim(-0.04, 1.04)
        ax.set_ylabel("per-view value")
        if 0 < n <= 24:
            ax.set_xticks(xs)
            ax.set_xticklabels([nm if len(nm) <= 12 else nm[:11] + "~" for nm in s["names"]], rotation=45,
                               ha="right", fontsize=6)
        else:
            ax.set_xlabel("view index along the camera path")
        ax.grid(True, axis="y", lw=0.4, alpha=0.5)
        if title:
            ax.set_title(title, loc="left")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        return _png(fig)


def view_axes_plot(path: str | os.PathLike, views: Sequence, *, title: str | None = None, xi: float = XI_DEFAULT) -> Path:
    """Write :func:`view_axes_png` to ``path`` (atomically); returns the path."""
    path = Path(path)
    write_bytes(path, view_axes_png(views, title=title, xi=xi))
    return path


def axes_overview_png(overall: Mapping[str, Mapping[str, object]], *, title: str | None = None,
                      low: float = 0.5, str_label: str = "s_str") -> bytes:
    """PNG bytes of grouped bars: s_sem, s_geo, s_str and RQS per method.

    overall: {method: {"s_sem", "s_geo", "s_str", "rqs"}} (e.g. ``aggregate["overall"]``);
        missing values are left out.
    low: a dashed line marks this level (axes below it are flagged in the report).
    str_label: legend text of s_str (e.g. "sim_SAM" or "1 - sim_SAM").
    Width grows with the number of methods (about 140 px each, 420 px at least).
    """
    methods = list(overall)
    keys = [("s_sem", "s_sem (acc_seg)"), ("s_geo", "s_geo (acc_depth)"), ("s_str", f"s_str ({str_label})"),
            ("rqs", "RQS")]
    with _style():
        w_in = max(4.2, 1.0 + 1.4 * len(methods)) + 1.6
        fig = Figure(figsize=(w_in, 2.8), dpi=_DPI)
        ax = fig.add_axes((0.9 / w_in, 0.22, 1.0 - 2.6 / w_in, 0.66))
        bw = 0.8 / len(keys)
        for k, (key, label) in enumerate(keys):
            xs, ys = [], []
            for i, m in enumerate(methods):
                v = number((overall[m] or {}).get(key))
                if v is not None and not math.isnan(v):
                    xs.append(i - 0.4 + bw * (k + 0.5))
                    ys.append(v)
            ax.bar(xs, ys, width=bw * 0.92, color=AXIS_COLORS[key], label=label)
        ax.axhline(low, color="#d62728", lw=0.8, ls=(0, (4, 3)), label=f"low ({low:g})")
        ax.set_xticks(range(len(methods)))
        ax.set_xticklabels([m if len(m) <= 16 else m[:15] + "~" for m in methods], rotation=20, ha="right")
        ax.set_xlim(-0.6, len(methods) - 0.4)
        ax.set_ylim(0, 1.0)
        ax.grid(True, axis="y", lw=0.4, alpha=0.5)
        if title:
            ax.set_title(title, loc="left")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        return _png(fig)
