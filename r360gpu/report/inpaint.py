"""Tables, CSV and HTML of the inpainting benchmarks' scores (the ``inpaint`` command).

Three tables: per method the mean over scenes (the row a paper's table shows), per scene and
method the scene means as the benchmark's script prints them, and per scene the values of every
view.  Markdown and LaTeX come from `r360gpu.report.tables`, HTML from
`r360gpu.report.html_blocks`, so they look like the Remove360 tables beside them.
"""
from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence

from ..metrics.inpainting import METRICS, SET_METRICS, InpaintScene, overall_means
from .html_blocks import CSS, esc, table_html
from .tables import Cell, Table, number_cells, render_latex, render_markdown

#: Column headers of the metrics (Markdown/HTML text, LaTeX).
HEADERS = {
    "psnr": ("PSNR", r"PSNR$\uparrow$"),
    "ssim": ("SSIM", r"SSIM$\uparrow$"),
    "masked_psnr": ("masked PSNR", r"PSNR$_{\mathrm{obj}}\uparrow$"),
    "masked_ssim": ("masked SSIM", r"SSIM$_{\mathrm{obj}}\uparrow$"),
    "lpips": ("LPIPS", r"LPIPS$\downarrow$"),
    "masked_lpips": ("masked LPIPS", r"LPIPS$_{\mathrm{obj}}\downarrow$"),
    "fid": ("FID", r"FID$\downarrow$"),
    "kid_mean": ("KID", r"KID$\downarrow$"),
}
#: Decimals shown per metric (the script prints 4; its short line 3).
DECIMALS = {"psnr": 3, "ssim": 4, "masked_psnr": 3, "masked_ssim": 4, "lpips": 4, "masked_lpips": 4, "fid": 2,
            "kid_mean": 4}


def _header(first: Sequence[str], metrics=METRICS) -> list[Cell]:
    return [Cell(t) for t in first] + [Cell(HEADERS[m][0], latex=HEADERS[m][1]) for m, _ in metrics]


def _shown(x: float | None) -> float | None:
    """Values a table can print: NaN and inf are shown as missing (the JSON keeps them)."""
    return x if x is not None and math.isfinite(x) else None


def _fill(rows: list[list[Cell]], columns: dict[str, list[float | None]], offset: int, emphasise: bool,
          metrics=METRICS) -> None:
    for j, (name, higher) in enumerate(metrics):
        for row, cell in zip(rows, number_cells([_shown(v) for v in columns[name]], DECIMALS[name], emphasise,
                                                higher)):
            row[offset + j] = cell


_ALL = METRICS + SET_METRICS


def not_computed_notes(results: Sequence[InpaintScene], metrics: tuple = _ALL) -> tuple[str, ...]:
    """One sentence per metric of ``metrics`` that no (scene, method) has a value of, with the reason
    (a blank column then reads "not computed", never 0)."""
    notes = []
    for name, _ in metrics:
        if name in dict(SET_METRICS):
            if results and all(getattr(r, name) is None for r in results):
                notes.append(f"{HEADERS[name][0]}: not computed ({results[0].set_reason}).")
        elif results and all(r.means[name].mean is None for r in results):
            notes.append(f"{HEADERS[name][0]}: not computed ({results[0].means[name].reason}).")
    return tuple(notes)


def overall_table(results: Sequence[InpaintScene], methods: Sequence[str], protocol_name: str, mode: str) -> Table:
    rows = [[Cell(m)] + [Cell("")] * len(_ALL) for m in methods]
    means = [overall_means(results, m) for m in methods]
    _fill(rows, {name: [mm[name] for mm in means] for name, _ in _ALL}, 1, emphasise=True, metrics=_ALL)
    n_scenes = len({r.scene for r in results})
    return Table("inpaint_overall", f"{protocol_name}: inpainting quality, mean over {n_scenes} scene(s) ({mode} mode)",
                 _header(["method"], _ALL), rows,
                 notes=("Each value is the mean over scenes of the per-scene means over views (FID and KID: of "
                        "the per-scene values between the photographs and the renders); masked = inside the "
                        "object mask. Higher is better for PSNR and SSIM, lower for LPIPS, FID and KID.",
                        *not_computed_notes(results)))


def scene_table(results: Sequence[InpaintScene], protocol_name: str, *, key: str = "inpaint_scenes",
                title: str | None = None, notes: tuple = (), metrics: tuple = _ALL) -> Table:
    set_metrics = [name for name, _ in SET_METRICS if (name, _) in metrics]
    rows = [[Cell(r.scene), Cell(r.method)] + [Cell("")] * len(metrics) for r in results]
    _fill(rows, {**{name: [r.means[name].mean for r in results] for name, _ in METRICS},
                 **{name: [getattr(r, name) for r in results] for name in set_metrics}}, 2, emphasise=False,
          metrics=metrics)
    rule = frozenset(i for i in range(1, len(results)) if results[i].scene != results[i - 1].scene)
    return Table(key, title or f"{protocol_name}: per-scene means over the test views",
                 _header(["scene", "method"], metrics), rows, rule_before=rule, label_columns=2,
                 notes=(*notes, *not_computed_notes(results, metrics)))


def orbit_table(results: Sequence[InpaintScene], kept: dict[str, int], against: str) -> Table:
    """The metrics at the orbit poses (``kept[scene]`` poses per scene), marked ``against``; FID and
    KID are not among them (a handful of poses is no image set)."""
    return scene_table(results, "", key="inpaint_orbit",
                       title=f"The same metrics at orbit poses, {against}",
                       notes=("Per scene and method, the mean over the orbit poses kept ("
                              + ", ".join(f"{s}: {k}" for s, k in kept.items())
                              + "); the reference reconstruction's render stands for the photograph; masked = "
                                "inside the lifted target's mask.",), metrics=METRICS)


def view_table(result: InpaintScene) -> Table:
    rows = [[Cell(v.view)] + [Cell("")] * len(METRICS) for v in result.views]
    _fill(rows, {name: [getattr(v, name) for v in result.views] for name, _ in METRICS}, 1, emphasise=False)
    key = "inpaint_views_" + "".join(ch if ch.isalnum() else "_" for ch in f"{result.scene}_{result.method}")
    return Table(key, f"{result.scene}, {result.method}: every test view", _header(["view"]), rows)


def tables(results: Sequence[InpaintScene], methods: Sequence[str], protocol_name: str, mode: str,
           orbit: Table | None = None) -> list[Table]:
    """The overall and per-scene tables (then ``orbit``, when given), then one per-view table each."""
    return [overall_table(results, methods, protocol_name, mode), scene_table(results, protocol_name),
            *([orbit] if orbit is not None else []), *(view_table(r) for r in results)]


def markdown(tables_: Sequence[Table]) -> str:
    return "\n".join(render_markdown(t) for t in tables_)


def latex(tables_: Sequence[Table]) -> str:
    return "\n".join(render_latex(t) for t in tables_)


def html_page(tables_: Sequence[Table], title: str, notes: Sequence[str], warnings: Sequence[str]) -> str:
    """A self-contained report.html: the overall and per-scene tables, then per-view tables folded."""
    parts = [f"<!doctype html><html><head><meta charset=\"utf-8\"><title>{esc(title)}</title>",
             f"<style>{CSS}</style></head><body><h1>{esc(title)}</h1>"]
    if notes:
        parts.append("<ul>" + "".join(f"<li>{esc(n)}</li>" for n in notes) + "</ul>")
    shown = 3 if len(tables_) > 2 and tables_[2].key == "inpaint_orbit" else 2
    parts += [table_html(t) for t in tables_[:shown]]
    for t in tables_[shown:]:
        parts.append(f"<details><summary>{esc(t.title)}</summary>{table_html(t, caption=False)}</details>")
    if warnings:
        parts.append("<h2>Warnings</h2><ul>" + "".join(f"<li>{esc(w)}</li>" for w in warnings) + "</ul>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


CSV_COLUMNS = ("scene", "method", "view", *(name for name, _ in METRICS), "mask_pixels", "fid", "kid_mean", "kid_std")


def _csv_value(x) -> str:
    return "" if x is None else repr(x)


def csv_text(results: Sequence[InpaintScene]) -> str:
    """results.csv: one row per (scene, method, view); a value not computed is empty, inf/nan as Python writes them.
    FID and KID belong to the (scene, method), not to a view: every row of it repeats them."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in results:
        for v in r.views:
            w.writerow([r.scene, r.method, v.view, *(_csv_value(getattr(v, n)) for n, _ in METRICS),
                        "" if v.mask_pixels is None else v.mask_pixels,
                        *(_csv_value(getattr(r, n)) for n in ("fid", "kid_mean", "kid_std"))])
    return buf.getvalue()


def script_lines(result: InpaintScene) -> list[str]:
    """The scene's means printed as the benchmark's script prints them (4 decimals, then 3); a metric
    not computed prints nan."""
    m = {k: (float("nan") if v.mean is None else v.mean) for k, v in result.means.items()}
    m["fid"] = float("nan") if result.fid is None else result.fid
    return [f"Method Name:  {result.method}",
            f"PSNR: {m['psnr']:.4f}, SSIM: {m['ssim']:.4f}, LPIPS: {m['lpips']:.4f}, FID: {m['fid']:.4f}",
            f"PSNR OBJECT: {m['masked_psnr']:.4f}, SSIM OBJECT: {m['masked_ssim']:.4f}, "
            f"LPIPS OBJECT: {m['masked_lpips']:.4f}",
            f"{m['psnr']:.3f}, {m['ssim']:.3f}, {m['lpips']:.3f}, {m['fid']:.3f}",
            f"{m['masked_psnr']:.3f}, {m['masked_ssim']:.3f}, {m['masked_lpips']:.3f}"]
