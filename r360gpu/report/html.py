"""report.html: one self-contained page of the results.

Everything is inside the file: tables as HTML, pictures and plots as
``data:`` URIs, inline CSS and a few lines of inline JavaScript (sorting the
per-view tables; opening the collapsed section a link points into); no
external resource.  The page never scrolls sideways: wide tables scroll in
their own box, long texts wrap.  Layout, top to bottom:

1. first screen, "which method leaks, where": the Overall table (cells of an
   axis whose probe check is not "ok" in some scene marked), the probe
   verdicts and control scores when the results have them, and per method
   the view that leaks most as a thumbnail linked to its contact sheet;
2. summary: low-axis warnings, known failure modes and whether the axes
   caught them (bundles with ``[expected.METHOD]``, e.g. the synthetic demo),
   the weight-free probe note, the best method per axis, an overview chart;
3. the other tables (per-scene, per-axis, IoU, ranks, reliability,
   association, sensitivity);
4. per scene: its settings, axes table and a sortable per-view table (every
   axis per view and method, each row linked to its contact sheet), then per
   method the per-view plot, per-probe readings, notes, every view's contact
   sheet and the axis record as a table;
5. run metadata: versions, options, GPU adapter, probes.

Every text from the results is escaped with :func:`html.escape`.  Pictures
are read from the paths stored in the results, relative to the output folder;
a path leaving that folder, a missing file or a file that is not a PNG is
not embedded, and the page says so.
"""
from __future__ import annotations

import math
import os
import urllib.parse
import warnings
from pathlib import Path

from ..errors import R360Warning
from ..protocol import AXES, XI_DEFAULT
from ..util.atomic import write_text
from ..util.warning_log import format_record
from . import findings
from .findings import LOW_AXIS
from .contact_sheets import view_numbers
from .plots import axes_overview_png, view_series
from .results_io import method_entry, method_names, number, scene_names, structural_mode
from .results_tables import (
    build_results_tables,
    main_table,
    overall_value,
    structural_header,
)
from .tables import fmt_number
from .html_blocks import CSS, JS, embed_many, embed_picture, esc, img_tag, kv_table, pic_id, png_uri, scroll_box, table_html
from .html_sections import (best_per_axis, controls_html, doubt_flags, expectations_html, low_axis_message,
                            low_axis_warnings, probe_readings, probes_html, scene_table, verdicts_html,
                            weight_free_note, worst_views_html)

REPORT_HTML = "report.html"


#: Default number of per-view pictures embedded per (scene, method): all.
MAX_VIEWS = None


def _view_caption(rec: dict) -> str:
    return " | ".join(view_numbers(rec))


def pick_views(names: list[str], limit: int | None) -> list[str]:
    """At most ``limit`` of ``names``, evenly spaced along the list (first and last kept); all when
    ``limit`` is None or not exceeded."""
    if limit is None or len(names) <= limit:
        return list(names)
    if limit <= 0:
        return []
    if limit == 1:
        return [names[0]]
    idx = sorted({round(i * (len(names) - 1) / (limit - 1)) for i in range(limit)})
    return [names[i] for i in idx]


_VIEW_COLUMNS = (("iou_pre", "IoU_pre", 2), ("iou_post", "IoU_post", 2), ("s_sem", "s_sem", 0),
                 ("acc_depth", "acc_depth", 3), ("t_depth", "t_depth", 3), ("no_depth", "no depth", 0),
                 ("s_str", "s_str", 3),
                 ("psnr", "PSNR", 1), ("ssim", "SSIM", 3), ("lpips", "LPIPS", 3), ("leak", "mean", 3))


def per_view_table_html(results: dict, scene: str, rows: list[dict]) -> str:
    """Every view of every method of ``scene`` with its per-view axes, sortable, each row linked
    to its contact sheet."""
    rows = [r for r in rows if r["scene"] == scene]
    if not rows:
        return ""
    cols = [c for c in _VIEW_COLUMNS if any(r.get(c[0]) is not None for r in rows)]
    # The see-through-hole count is shown where the scene has a hole (a column of zeros says nothing).
    cols = [c for c in cols if c[0] != "no_depth" or any(r.get("no_depth") for r in rows)]
    mode = structural_mode(results, scene)
    label = {"s_str": "s_str (sim_SAM)" if mode == "reference" else "s_str (1 - sim_SAM)",
             "s_sem": "s_sem (not found)"}
    h = ['<table class="sortable perview"><caption>Per view (click a header to sort, a view for its contact sheet; s_sem is 1 when the '
         f'semantic probe no longer finds the object, IoU_post &lt; {XI_DEFAULT:g}; t_depth is the GHT threshold; '
         + ('no depth: pixels of the target with no depth after removal, a see-through hole that acc_depth counts '
            'as unchanged; ' if any(c[0] == "no_depth" for c in cols) else '')
         + 'mean = mean of s_sem, acc_depth, s_str)</caption><thead><tr><th class="lab">Method</th><th class="lab">View</th>'
         + "".join(f'<th class="num">{esc(label.get(k, name))}</th>' for k, name, _ in cols)
         + "</tr></thead><tbody>"]
    for r in rows:
        anchor = pic_id(results, scene, r["method"], r["view"])
        cells = []
        for k, _, dec in cols:
            v = r.get(k)
            text = fmt_number(v, dec) if v is None or math.isfinite(v) else ("inf" if v > 0 else "-inf")
            data = "" if v is None else (repr(float(v)) if math.isfinite(v) else ("1e308" if v > 0 else "-1e308"))
            cells.append(f'<td class="num" data-v="{data}">{esc(text)}</td>')
        # The view name links to its contact sheet (no column of its own: the table fits 800 px).
        view = f'<a href="#{anchor}" title="contact sheet">{esc(r["view"])}</a>' if r.get("picture") else esc(r["view"])
        ex = " (excluded)" if r.get("excluded") else ""
        h.append(f'<tr id="row-{anchor}"><td class="lab">{esc(r["method"])}</td>'
                 f'<td class="lab">{view}{ex}</td>{"".join(cells)}</tr>')
    h.append("</tbody></table>")
    return scroll_box("\n".join(h))


def _method_section(results: dict, out_dir: Path, scene: str, method: str, problems: list[str],
                    max_views: int | None, embed_cache: Path | None = None) -> str:
    entry = method_entry(results, scene, method) or {}
    axes = entry.get("axes") or {}
    rqs = number(axes.get("rqs"))
    h = [f'<details class="method" open><summary>{esc(method)} &mdash; RQS {esc(fmt_number(rqs, 3))}</summary>']
    mode = structural_mode(results, scene)
    lows = [f"{a} = {number(axes.get(a)):.3f} -- {low_axis_message(a, mode)}" for a in AXES
            if number(axes.get(a)) is not None and number(axes.get(a)) < LOW_AXIS]
    for line in lows:
        h.append(f'<div class="warn">{esc(line)}</div>')
    plot = entry.get("plot")
    if plot is not None:
        uri, why = embed_picture(out_dir, plot)
        if uri:
            h.append(img_tag(uri, f"per-view axes of {method} on {scene}"))
        else:
            h.append(f'<div class="warn">{esc(why)}</div>')
            problems.append(f"{scene}/{method}: {why}")
    readings = probe_readings(results, scene, method)
    if readings:
        t = ['<table><thead><tr><th class="lab">Probe</th><th class="lab">Axis</th><th class="lab">Readings</th>'
             '<th class="num">Views scored</th></tr></thead><tbody>']
        for p, kind, vals, n in readings:
            t.append(f'<tr><td class="lab">{esc(p)}</td><td class="lab">{esc(kind)}</td>'
                     f'<td class="lab wrap">{esc(vals)}</td><td class="num">{esc(n)}</td></tr>')
        t.append("</tbody></table>")
        h.append(scroll_box("".join(t)))
    notes = []
    series = view_series(entry.get("views") or [])
    excluded = [n for n, ex in zip(series["names"], series["excluded"]) if ex]
    if excluded:
        notes.append(f"Excluded views (empty target mask, not in the means): {', '.join(excluded)}.")
    n_geo = axes.get("n_geo_excluded")
    if isinstance(n_geo, int) and n_geo:
        notes.append(f"{n_geo} view(s) excluded from acc_depth.")
    fids = [r.get("fidelity") or {} for r in entry.get("views") or []]
    reasons = sorted({str(f["lpips_reason"]) for f in fids if f.get("lpips") is None and f.get("lpips_reason")})
    if reasons:
        notes.append("LPIPS not computed: " + "; ".join(reasons) + ".")
    for n in notes:
        h.append(f'<p class="notes">{esc(n)}</p>')
    pics = entry.get("pictures") or {}
    if pics:
        shown = pick_views(list(pics), max_views)
        count = f"{len(pics)} views" if len(shown) == len(pics) else f"{len(shown)} of {len(pics)} views"
        h.append(f"<details><summary>Per-view contact sheets ({esc(count)})</summary>")
        if len(shown) < len(pics):
            h.append(f'<p class="notes">Evenly spaced along the camera path; every view\'s picture is in the '
                     f'{esc(os.path.dirname(str(next(iter(pics.values())))) or ".")} folder.</p>')
        h.append('<div class="grid">')
        by_view = {str(r.get("view")): r for r in entry.get("views") or []}
        for view, (uri, why) in zip(shown, embed_many(out_dir, [pics[v] for v in shown], embed_cache)):
            cap = f"{view}: {_view_caption(by_view.get(str(view), {}))}"
            fid = pic_id(results, scene, method, str(view))
            back = f' <a href="#row-{fid}">(row)</a>'
            if uri:
                # The embedded copy is shrunk for the page; the link opens the full-size PNG beside it.
                full = esc(urllib.parse.quote(str(pics[view]).replace(os.sep, "/")))
                img = f'<a href="{full}" title="full-size picture">{img_tag(uri, f"{scene} / {method} / {view}")}</a>'
                h.append(f'<figure id="{fid}">{img}<figcaption>{esc(cap)}{back} '
                         f'<a href="{full}">(full size)</a></figcaption></figure>')
            else:
                h.append(f'<figure id="{fid}"><div class="warn">{esc(why)}</div><figcaption>{esc(cap)}</figcaption>'
                         "</figure>")
                problems.append(f"{scene}/{method}/{view}: {why}")
        h.append("</div></details>")
    h.append("<details><summary>Axis record</summary>" + kv_table(axes) + "</details>")
    h.append("</details>")
    return "\n".join(h)


def report_html(results: dict, out_dir: str | os.PathLike, *, max_views: int | None = MAX_VIEWS,
                embed_cache: str | os.PathLike | None = None) -> tuple[str, list[str]]:
    """The page's HTML text and the list of pictures that could not be embedded.

    out_dir: the folder the picture paths in ``results`` are relative to.
    max_views: per (scene, method), embed at most this many per-view pictures
        (evenly spaced, :func:`pick_views`); None (default) embeds all.
    embed_cache: folder of the contact sheets' embedding JPEGs (:mod:`.embed`):
        used where it has a sheet's, filled where it lacks one; the page is the
        same with or without it.
    """
    out = Path(out_dir)
    problems: list[str] = []
    scenes, methods = scene_names(results), method_names(results)
    str_md = structural_header(results)[0]
    rows = findings.view_rows(results)
    for r in rows:  # the record, for the thumbnail's layout (its numbers lines)
        entry = method_entry(results, r["scene"], r["method"]) or {}
        r["record"] = next((v for v in entry.get("views") or [] if str(v.get("view")) == r["view"]), None)
    h = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
         '<meta name="viewport" content="width=device-width, initial-scale=1">',
         "<title>r360gpu report</title>", f"<style>{CSS}</style></head><body>"]
    meta = [f"r360gpu {results.get('r360gpu_version', '?')}"]
    if results.get("created"):
        meta.append(f"created {results['created']}")
    meta.append(f"{len(scenes)} scene(s), {len(methods)} method(s)")
    h.append("<header><h1>Remove360 evaluation report</h1>"
             f'<p class="meta">{esc(" | ".join(meta))}</p></header>')
    nav = ['<a href="#leaks">Leaks</a>', '<a href="#summary">Summary</a>', '<a href="#tables">Tables</a>']
    nav += [f'<a href="#scene-{i}">{esc(s)}</a>' for i, s in enumerate(scenes)]
    nav.append('<a href="#metadata">Run metadata</a>')
    h.append("<nav>" + "".join(nav) + "</nav>")

    # First screen: which method leaks, where
    h.append('<section id="leaks"><h2>Which method leaks, where</h2>')
    main = main_table(results, doubt_marks=False)  # marked below, with the reasons as tooltips
    flags, doubt_notes = doubt_flags(results, main)
    h.append(table_html(main, flags=flags))
    for n in doubt_notes:
        h.append(f'<p class="notes">{esc(n)}</p>')
    tables, table_notes = build_results_tables(results)
    reliability = next((t for t in tables if t.key == "reliability"), None)
    unsure = ((results.get("aggregate") or {}).get("notes") or {}).get("reliability")
    if reliability is not None:  # how sure the ranking is, next to the ranking itself
        h.append('<h3>How sure is the ranking</h3>' + table_html(reliability))
    elif unsure:  # too few scenes: said in words, instead of intervals that look more certain than they are
        h.append(f'<h3>How sure is the ranking</h3><p class="notes">{esc(unsure)}</p>')
        table_notes = [n for n in table_notes if n != unsure]
    h.append(verdicts_html(results))
    h.append(worst_views_html(results, out, rows, problems))
    h.append(controls_html(results))
    h.append("</section>")

    # Summary
    h.append('<section id="summary"><h2>Summary</h2>')
    for line in low_axis_warnings(results):
        h.append(f'<div class="warn"><strong>Warning:</strong> {esc(line)}</div>')
    input_warnings = results.get("warnings") or []  # recorded by r360gpu.util.warning_log
    for w in input_warnings[:50]:
        h.append(f'<div class="warn"><strong>Input warning:</strong> {esc(format_record(w))}</div>')
    if len(input_warnings) > 50:
        h.append(f'<div class="warn">... and {len(input_warnings) - 50} more input warnings in results.json</div>')
    h.append(expectations_html(results))
    h.append(weight_free_note(results))
    best = best_per_axis(results)
    if best:
        h.append('<h3>Best method per axis</h3><ul class="best">')
        for label, ms, v, dec in best:
            h.append(f"<li>{esc(label)}: <strong>{esc(', '.join(ms))}</strong> ({esc(fmt_number(v, dec))})</li>")
        h.append("</ul>")
    overall = {m: {k: overall_value(results, m, k) for k in ("s_sem", "s_geo", "s_str", "rqs")} for m in methods}
    if any(v is not None for d in overall.values() for v in d.values()):
        h.append(img_tag(png_uri(axes_overview_png(overall, title="Overall axes per method", low=LOW_AXIS,
                                                 str_label=str_md)), "overall axes per method"))
    h.append("</section>")

    # Tables
    h.append('<section id="tables"><h2>Tables</h2>')
    for t in tables[1:]:
        if t is reliability:
            continue  # on the first screen
        h.append(f"<details open><summary>{esc(t.title)}</summary>{table_html(t, caption=False)}</details>")
    for n in table_notes:
        h.append(f'<p class="notes">Note: {esc(n)}</p>')
    h.append("</section>")

    # Scenes
    for i, s in enumerate(scenes):
        sd = (results.get("scenes") or {}).get(s) or {}
        mode = structural_mode(results, s)
        h.append(f'<section id="scene-{i}"><h2>Scene {esc(s)}</h2>')
        facts = [f"prompt: {sd.get('prompt', '?')}", f"views: {sd.get('n_views', '?')}",
                 "reference: " + ("yes" if sd.get("reference") else "no"),
                 "structural axis: " + ("sim_SAM(I_post, I_ref)" if mode == "reference"
                                        else "1 - sim_SAM(I_pre, I_post)")]
        h.append(f'<p class="meta">{esc(" | ".join(facts))}</p>')
        ex = sd.get("excluded_views")
        if ex:
            items = ex.items() if isinstance(ex, dict) else [("views", ex)]
            text = "; ".join(f"{k}: {', '.join(map(str, v)) if isinstance(v, (list, tuple)) else v}" for k, v in items)
            h.append(f'<p class="notes">Excluded views: {esc(text)}</p>')
        h.append(table_html(scene_table(results, s)))
        h.append(per_view_table_html(results, s, rows))
        for m in methods:
            if method_entry(results, s, m) is not None:
                h.append(_method_section(results, out, s, m, problems, max_views, embed_cache))
        h.append("</section>")

    # Metadata
    h.append('<section id="metadata"><h2>Run metadata</h2>')
    h.append(kv_table({"r360gpu version": results.get("r360gpu_version", "?"), "schema": results.get("schema", "?"),
                        "created": results.get("created", "?")}))
    if results.get("options"):
        h.append("<h3>Options</h3>" + kv_table(results["options"]))
    if results.get("adapter"):
        h.append("<h3>GPU adapter</h3>" + kv_table(results["adapter"]))
    h.append("<h3>Probes</h3>" + probes_html(results))
    h.append(f"</section><script>{JS}</script></body></html>")
    return "\n".join(x for x in h if x) + "\n", problems


def write_html(results: dict, out_dir: str | os.PathLike, *, max_views: int | None = MAX_VIEWS,
               embed_cache: str | os.PathLike | None = None) -> Path:
    """Write ``OUT/report.html`` (atomically) and return its path.

    max_views: per (scene, method), the number of per-view contact sheets
    embedded (evenly spaced along the path; None: all, the default).  The
    sheets are embedded as JPEG (:data:`.embed.JPEG_QUALITY`, at most
    :data:`.embed.EMBED_WIDTH` px wide); the lossless PNGs stay in the pictures
    folder.  embed_cache: as in :func:`report_html`.

    Pictures that cannot be embedded are named on the page and in one
    :class:`~r360gpu.errors.R360Warning`.
    """
    out = Path(out_dir)
    text, problems = report_html(results, out, max_views=max_views, embed_cache=embed_cache)
    path = out / REPORT_HTML
    write_text(path, text)
    if problems:
        warnings.warn(f"{path}: {len(problems)} picture(s) not embedded: " + "; ".join(problems), R360Warning,
                      stacklevel=2)
    return path
