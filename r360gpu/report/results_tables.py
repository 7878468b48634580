"""The paper's tables built from a results document (results.json).

Each builder returns a :class:`~r360gpu.report.tables.Table`, rendered by
:func:`~r360gpu.report.tables.render_markdown` / ``render_latex`` (and by the
HTML page).  Layouts follow the Remove360 paper:

* :func:`main_table` -- tab:main_results: IoU_drop, acc_seg, acc_depth,
  sim_SAM (``1 - sim_SAM`` without a reference), RQS, AvgRank | PSNR, SSIM,
  LPIPS, over all scenes (view-weighted);
* :func:`axis_table` -- tab:supp_iou_drop / supp_accseg / supp_depth /
  supp_sam / supp_psnr ...: scenes x methods for one axis with an Overall row;
* :func:`iou_table` -- tab:supp_remove360_iou: ``mIoU_pre -> mIoU_post [drop]``;
* :func:`xi_table` -- tab:supp_remove360_thresholds;
* :func:`boundary_table` -- tab:supp_boundary_compact (E15 .. D15);
* the aggregate tables of :mod:`r360gpu.report.tables` (per-scene RQS,
  scene-macro means, rank aggregation, reliability, axis association).

Best and second best are emphasised per row (per scene, and in the Overall
row) or per column (main table) as in the paper; the boundary table bolds the
unperturbed column instead.  :func:`write_tables` writes them all to
``tables.md`` and ``tables.tex``.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

from ..metrics.fidelity import FidelityView, fidelity_summary
from ..protocol import XI_DEFAULT
from ..util.atomic import write_text
from .results_io import method_entry, method_names, number, scene_names, structural_modes
from .tables import (
    Cell,
    Table,
    emphasis_marks,
    fmt_number,
    number_cells,
    build_tables,
    render_latex,
    render_markdown,
)

TABLES_MD = "tables.md"
TABLES_TEX = "tables.tex"

# (key in the method's "axes", Markdown header, LaTeX header, decimals, higher is better)
_AXIS_SPECS = {
    "iou_drop": ("IoU_drop", r"IoU$_{\mathrm{drop}}\uparrow$", 3, True),
    "s_sem": (f"acc_seg (xi={XI_DEFAULT:g})", rf"acc$_{{\mathrm{{seg}},{XI_DEFAULT:g}}}\uparrow$", 3, True),
    "s_geo": ("acc_depth", r"acc$_{\Delta\mathrm{depth}}\uparrow$", 3, True),
    "psnr": ("PSNR (dB)", r"PSNR$\uparrow$", 2, True),
    "ssim": ("SSIM", r"SSIM$\uparrow$", 3, True),
    "lpips": ("LPIPS (lower is better)", r"LPIPS$\downarrow$", 3, False),
}
_BOUNDARY_ROWS = {
    "iou_pre": ("mIoU_pre", r"mIoU$_{\mathrm{pre}}$"),
    "iou_post": ("mIoU_post", r"mIoU$_{\mathrm{post}}$"),
    "iou_drop": ("IoU_drop", r"IoU$_{\mathrm{drop}}\uparrow$"),
    "acc_depth": ("acc_depth", r"acc$_{\Delta\mathrm{depth}}\uparrow$"),
    "s_geo": ("acc_depth", r"acc$_{\Delta\mathrm{depth}}\uparrow$"),
    "sim_sam": ("sim_SAM", r"sim$_{\mathrm{SAM}}$"),
    "s_str": ("s_str", r"$s_{\mathrm{str}}\uparrow$"),
    "s_sem": ("s_sem", r"$s_{\mathrm{sem}}\uparrow$"),
}
_BOUNDARY_ORDER = ("iou_drop", "iou_pre", "iou_post", "s_sem", "acc_depth", "s_geo", "sim_sam", "s_str")


def structural_header(results: dict) -> tuple[str, str, str]:
    """(Markdown header, LaTeX header, one-line meaning) of the s_str column.

    sim_SAM(I_post, I_ref) when every scene has a reference, ``1 - sim_SAM``
    (I_pre vs I_post) when none has, "s_str" when the scenes mix both.
    """
    modes = structural_modes(results)
    if modes == {"reference"}:
        return "sim_SAM", r"sim$_{\mathrm{SAM}}\uparrow$", "s_str = sim_SAM(I_post, I_ref)"
    if modes == {"reference_free"}:
        return ("1 - sim_SAM", r"$(1-\mathrm{sim}_{\mathrm{SAM}})\uparrow$",
                "s_str = 1 - sim_SAM(I_pre, I_post) (no post-removal reference)")
    return ("s_str", r"$s_{\mathrm{str}}\uparrow$",
            "s_str = sim_SAM(I_post, I_ref) on scenes with a reference, 1 - sim_SAM(I_pre, I_post) on the others")


def axis_spec(results: dict, key: str) -> tuple[str, str, int, bool]:
    """(Markdown header, LaTeX header, decimals, higher is better) of one axis key."""
    if key == "s_str":
        md, tex, _ = structural_header(results)
        return md, tex, 3, True
    if key == "rqs":
        return "RQS", r"RQS$\uparrow$", 3, True
    return _AXIS_SPECS[key]


def scene_value(results: dict, scene: str, method: str, key: str) -> float | None:
    """``axes[key]`` of one (scene, method) as a float (None when absent)."""
    entry = method_entry(results, scene, method)
    return None if entry is None else number((entry.get("axes") or {}).get(key))


def pooled_fidelity(results: dict, method: str) -> dict[str, float | None]:
    """PSNR / SSIM / LPIPS of one method pooled over every view of every scene.

    All views with a fidelity record are pooled (view-weighted, as the
    paper's Overall row) with :func:`r360gpu.metrics.fidelity.fidelity_summary`:
    PSNR averages the views with a finite value, LPIPS is None unless computed
    for every pooled view.  Returns {"psnr", "ssim", "lpips", "n_views"}.
    """
    views = []
    for s in scene_names(results):
        entry = method_entry(results, s, method)
        for rec in (entry or {}).get("views") or []:
            if rec.get("fidelity"):
                views.append(FidelityView.from_dict(rec["fidelity"]))
    summ = fidelity_summary(views)
    if not views:
        return {"psnr": None, "ssim": None, "lpips": None, "n_views": 0}
    return {"psnr": summ.psnr, "ssim": summ.ssim, "lpips": summ.lpips, "n_views": len(views)}


def overall_value(results: dict, method: str, key: str) -> float | None:
    """The Overall (all scenes) value of one axis for one method.

    Removal axes and RQS come from ``aggregate.overall`` (view-weighted unless
    the aggregate says otherwise), AvgRank from ``aggregate.ranks``, fidelity
    from :func:`pooled_fidelity`.
    """
    agg = results.get("aggregate") or {}
    if key in ("psnr", "ssim", "lpips"):
        return pooled_fidelity(results, method)[key]
    if key == "avg_rank":
        return number(((agg.get("ranks") or {}).get(method) or {}).get("avg_rank"))
    return number(((agg.get("overall") or {}).get(method) or {}).get(key))


def _pooling(results: dict) -> str:
    return "view-weighted" if (results.get("aggregate") or {}).get("overall_pooling") == "view-weighted" \
        else "scene-macro"


def has_fidelity(results: dict) -> bool:
    """Whether any view of any method has a fidelity record (a reference exists somewhere)."""
    return any(pooled_fidelity(results, m)["n_views"] for m in method_names(results))


def has_lpips(results: dict) -> bool:
    """Whether an LPIPS value exists for some method (an LPIPS model ran): else no LPIPS column."""
    return any(pooled_fidelity(results, m)["lpips"] is not None for m in method_names(results))


def doubt_mark(results: dict, key: str, cell: Cell) -> Cell:
    """``cell`` with a dagger when axis ``key`` is not "ok" (weak or blind probe) in some scene
    (``results["validity"]``, from r360gpu.aggregate.validity); other cells unchanged."""
    if not (results.get("validity") or {}).get(key) or cell.text in ("", "--"):
        return cell
    from dataclasses import replace

    return replace(cell, text=cell.text + "†", latex=_latex_number(cell.text) + r"$^{\dagger}$")


def _latex_number(text: str) -> str:
    return text.replace("-", "$-$") if text.startswith("-") else text


def doubt_notes(results: dict, only: str | None = None) -> list[str]:
    """One sentence per axis that carries the dagger, naming its scenes."""
    out = []
    for axis, scenes in (results.get("validity") or {}).items():
        if scenes and (only is None or axis == only):
            out.append(f"† {axis}: the probe check is not ok (weak or blind) in {', '.join(scenes)}; "
                       "see each scene's validity notes before reading this axis as evidence of removal.")
    return out


def main_table(results: dict, *, doubt_marks: bool = True) -> Table:
    """tab:main_results: removal axes, RQS, AvgRank | pixel fidelity, one row per method.

    doubt_marks: a dagger on the cells of an axis that is weak or blind in some
    scene, and a note naming the scenes (report.html marks them its own way).

    The fidelity columns are left out when no scene has a reference, LPIPS
    when no LPIPS model ran.
    """
    methods = method_names(results)
    str_md, str_tex, str_note = structural_header(results)
    cols: list[tuple[str, Cell, int, bool]] = [
        ("iou_drop", Cell("IoU_drop", r"IoU$_{\mathrm{drop}}\uparrow$"), 3, True),
        ("s_sem", Cell("acc_seg", r"acc$_{\mathrm{seg}}\uparrow$"), 3, True),
        ("s_geo", Cell("acc_depth", r"acc$_{\Delta depth}\uparrow$"), 3, True),
        ("s_str", Cell(str_md, str_tex), 3, True),
        ("rqs", Cell("RQS", r"RQS$\uparrow$"), 3, True),
        ("avg_rank", Cell("AvgRank (lower is better)", r"AvgRank$\downarrow$"), 2, False),
    ]
    fidelity = has_fidelity(results)
    if fidelity:
        cols += [
            ("psnr", Cell("PSNR", r"PSNR$\uparrow$"), 2, True),
            ("ssim", Cell("SSIM", r"SSIM$\uparrow$"), 3, True),
        ]
        if has_lpips(results):
            cols.append(("lpips", Cell("LPIPS (lower is better)", r"LPIPS$\downarrow$"), 3, False))
    rows = [[Cell(m)] + [Cell("")] * len(cols) for m in methods]
    for j, (key, _, decimals, higher) in enumerate(cols, start=1):
        values = [overall_value(results, m, key) for m in methods]
        for row, cell in zip(rows, number_cells(values, decimals, True, higher)):
            row[j] = doubt_mark(results, key, cell) if doubt_marks else cell
    notes = [
        f"acc_seg = s_sem (IoU threshold {XI_DEFAULT:g}); acc_depth = s_geo; {str_note}.",
        f"RQS is the geometric mean of the three {_pooling(results)} pooled axes; AvgRank is the mean of the "
        "per-axis ranks. IoU_drop is a diagnostic and enters neither.",
    ]
    if fidelity:
        what = "PSNR / SSIM / LPIPS" if has_lpips(results) else "PSNR / SSIM"
        notes.append(f"{what} compare I_post with the post-removal reference rendering I_ref, "
                     "pooled over every view with a reference; they are diagnostics outside RQS and AvgRank.")
    notes.append("Best and second best per column are emphasised.")
    notes += doubt_notes(results) if doubt_marks else []
    return Table(
        key="main_results",
        title="Overall evaluation: removal axes, RQS and AvgRank"
              + ("; right of the bar: pixel fidelity against the reference." if fidelity else "."),
        header=[Cell("Method")] + [c for _, c, _, _ in cols],
        rows=rows,
        notes=tuple(notes),
        vrule_before=frozenset({7}) if fidelity else frozenset(),
    )


def axis_table(results: dict, key: str) -> Table:
    """One axis as scenes x methods with an Overall row (the Supp. per-scene tables).

    key: "iou_drop", "s_sem" (acc_seg at 0.3), "s_geo" (acc_depth), "s_str",
    "rqs", "psnr", "ssim" or "lpips" (lower is better).
    """
    methods, scenes = method_names(results), scene_names(results)
    md, tex, decimals, higher = axis_spec(results, key)
    rows = [[Cell(s)] + number_cells([scene_value(results, s, m, key) for m in methods], decimals, True, higher)
            for s in scenes]
    overall = [overall_value(results, m, key) for m in methods]
    label = "Overall (pooled views)" if key in ("psnr", "ssim", "lpips") else f"Overall ({_pooling(results)})"
    rows.append([Cell(label)] + [doubt_mark(results, key, c) for c in number_cells(overall, decimals, True, higher)])
    notes = ["Best and second best per row are emphasised"
             + (" (lowest is best)." if not higher else ".")] + doubt_notes(results, only=key)
    if key == "s_str":
        notes.insert(0, structural_header(results)[2] + ".")
    if key in ("iou_drop", "psnr", "ssim", "lpips"):
        notes.insert(0, "A diagnostic: it enters neither RQS nor AvgRank.")
    return Table(
        key=f"axis_{key}",
        title=f"Per-scene {md}.",
        header=[Cell("Scene")] + [Cell(m) for m in methods],
        rows=rows,
        rule_before=frozenset({len(scenes)}),
        notes=tuple(notes),
    )


def iou_table(results: dict) -> Table:
    """tab:supp_remove360_iou: ``mIoU_pre -> mIoU_post [IoU_drop]`` per scene and method.

    The largest and second-largest drop of each scene are emphasised.
    """
    methods, scenes = method_names(results), scene_names(results)
    rows = []
    for s in scenes:
        drops, cells = [], []
        for m in methods:
            pre, post = scene_value(results, s, m, "iou_pre"), scene_value(results, s, m, "iou_post")
            drop = scene_value(results, s, m, "iou_drop")
            if drop is None and pre is not None and post is not None:
                drop = pre - post
            drops.append(drop)
            if pre is None or post is None:
                cells.append(("--", "--"))
            else:
                d = fmt_number(drop, 2)
                cells.append((f"{pre:.2f} → {post:.2f} [{d}]", rf"{pre:.2f}$\rightarrow${post:.2f} [{d}]"))
        marks = emphasis_marks(drops, 2, higher_is_better=True)
        rows.append([Cell(s)] + [Cell(t, x, e) for (t, x), e in zip(cells, marks)])
    return Table(
        key="iou_pre_post",
        title="Semantic probe: target IoU before and after removal (mIoU_pre -> mIoU_post [IoU_drop]).",
        header=[Cell("Scene")] + [Cell(m) for m in methods],
        rows=rows,
        notes=("Means over the scored views of each scene. The largest and second-largest drop per scene "
               "are emphasised."
               + (" mIoU_pre of a method with its own pre-removal renders is measured on them."
                  if any((sc.get("sources") or {}).get("method_pres") for sc in (results.get("scenes") or {}).values())
                  else ""),),
    )


def xi_table(results: dict) -> Table | None:
    """tab:supp_remove360_thresholds: acc_seg at each IoU threshold ξ, or None without a sweep."""
    xi = (results.get("sensitivity") or {}).get("xi") or {}
    methods = [m for m in method_names(results) if m in xi] + [m for m in xi if m not in method_names(results)]
    if not methods:
        return None
    keys = sorted({k for m in methods for k in (xi[m] or {})}, key=float)
    header = [Cell("Method")] + [
        Cell(f"xi={k}" if i == 0 else k, rf"$\xi_{{\mathrm{{IoU}}}}={k}$" if i == 0 else f"${k}$")
        for i, k in enumerate(keys)
    ]
    rows = [[Cell(m)] + [Cell(fmt_number(number((xi[m] or {}).get(k)), 3)) for k in keys] for m in methods]
    pooling = (results.get("sensitivity") or {}).get("pooling")
    return Table(
        key="xi_sensitivity",
        title="Sensitivity of acc_seg to the IoU threshold xi.",
        header=header,
        rows=rows,
        notes=((f"Values are {pooling} averages. " if isinstance(pooling, str) else "")
               + f"s_sem uses xi = {XI_DEFAULT:g}; higher thresholds count fewer views as detected.",),
    )


def _boundary_label_order(labels: list[str]) -> list[str]:
    def key(lab: str):
        if lab == "Original":
            return 0
        if lab[:1] in "ED" and lab[1:].isdigit():
            return -int(lab[1:]) if lab[0] == "E" else int(lab[1:])
        return math.inf
    return sorted(labels, key=key)


def boundary_table(results: dict) -> Table | None:
    """tab:supp_boundary_compact: each axis after eroding (E) / dilating (D) the target
    masks, one row per (axis, method); None without a boundary sweep.

    The unperturbed ("Original") column is bold, as in the paper (it marks the
    reference value, not the best one).
    """
    bnd = (results.get("sensitivity") or {}).get("boundary") or {}
    methods = [m for m in method_names(results) if m in bnd] + [m for m in bnd if m not in method_names(results)]
    if not methods:
        return None
    axes_present = {a for m in methods for a in (bnd[m] or {})}
    axes = [a for a in _BOUNDARY_ORDER if a in axes_present]
    axes += sorted(a for a in axes_present if a not in axes)
    labels = _boundary_label_order(sorted({lab for m in methods for a in (bnd[m] or {})
                                           for lab in ((bnd[m] or {}).get(a) or {})}))
    rows, rules = [], set()
    for a in axes:
        md, tex = _BOUNDARY_ROWS.get(a, (a, None))
        if a.startswith("acc_seg@"):
            md, tex = f"acc_seg (xi={a[8:]})", rf"acc$_{{\mathrm{{seg}},{a[8:]}}}$"
        first = True
        for m in methods:
            vals = (bnd[m] or {}).get(a)
            if vals is None:
                continue
            if first and rows:
                rules.add(len(rows))
            row = [Cell(md, tex) if first else Cell(""), Cell(m)]
            row += [Cell(fmt_number(number(vals.get(lab)), 3), emphasis="best" if lab == "Original" else "")
                    for lab in labels]
            rows.append(row)
            first = False
    return Table(
        key="boundary_sensitivity",
        title="Mask-boundary sensitivity: axes after eroding (E) or dilating (D) the target masks by r px.",
        header=[Cell("Metric"), Cell("Method")] + [Cell(lab) for lab in labels],
        rows=rows,
        rule_before=frozenset(rules),
        notes=("Bold marks the unperturbed result, not the best value.",),
        label_columns=2,
    )


def build_results_tables(results: dict) -> tuple[list[Table], list[str]]:
    """Every table of a results document, in display order, and notes on tables left out.

    Order: main results, per-scene RQS, per-axis tables (IoU_drop, acc_seg,
    acc_depth, s_str, then PSNR / SSIM (and LPIPS when a model ran) when a reference exists),
    IoU pre -> post, scene-macro means, rank aggregation, reliability, axis
    association, ξ sweep, boundary sweep.
    """
    tables: list[Table] = [main_table(results)]
    notes: list[str] = list(results.get("notes") or [])  # e.g. which methods the cross-scene tables leave out
    agg = results.get("aggregate")
    agg_tables: dict[str, Table] = {}
    if agg:
        built, agg_notes = build_tables(agg)
        agg_tables = {t.key: t for t in built}
        notes += agg_notes
    else:
        notes.append("aggregate tables omitted: the results have no 'aggregate' section")
    if "rqs_per_scene" in agg_tables:
        tables.append(agg_tables["rqs_per_scene"])
    else:
        tables.append(axis_table(results, "rqs"))
    for key in ("iou_drop", "s_sem", "s_geo", "s_str"):
        tables.append(axis_table(results, key))
    if has_fidelity(results):
        tables += [axis_table(results, k) for k in ("psnr", "ssim")]
        if has_lpips(results):
            tables.append(axis_table(results, "lpips"))
        else:
            notes.append("LPIPS omitted: no LPIPS model ran (score with --lpips MODEL.onnx)")
    tables.append(iou_table(results))
    for key in ("scene_macro", "rank_agg", "reliability", "axis_association"):
        if key in agg_tables:
            tables.append(agg_tables[key])
    from .orbit_table import orbit_table

    orbit = orbit_table(results)  # score --orbit N: capture vs orbit, never in the axes above
    if orbit is not None:
        tables.append(orbit)
    from .pruned_table import pruned_table

    pruned = pruned_table(results)  # score --prune-residuals Q: METHOD+pruned what-ifs, never ranked
    if pruned is not None:
        tables.append(pruned)
    for build, what in ((xi_table, "threshold (xi) sweep"), (boundary_table, "mask-boundary sweep")):
        t = build(results)
        if t is None:
            notes.append(f"{what} omitted: not in the results")
        else:
            tables.append(t)
    return tables, notes


def write_tables(results: dict, out_dir: str | os.PathLike) -> tuple[Path, Path]:
    """Write ``OUT/tables.md`` and ``OUT/tables.tex`` (atomically); returns both paths.

    The LaTeX file is a sequence of ``table`` floats to ``\\input``; it needs
    ``\\usepackage{booktabs}``.
    """
    tables, notes = build_results_tables(results)
    out = Path(out_dir)
    md = ["# r360gpu results", ""]
    md += [render_markdown(t) for t in tables]
    md = "\n".join(md)
    if notes:
        md += "\n" + "".join(f"Note: {n}\n" for n in notes)
    tex = ["% r360gpu results tables; needs \\usepackage{booktabs}", ""]
    tex += [render_latex(t) for t in tables]
    tex = "\n".join(tex)
    if notes:
        tex += "\n" + "".join(f"% Note: {n}\n" for n in notes)
    md_path, tex_path = out / TABLES_MD, out / TABLES_TEX
    write_text(md_path, md)
    write_text(tex_path, tex)
    return md_path, tex_path
