"""report.html: one self-contained page of the results.

Everything is inside the file: tables as HTML, pictures and plots as
``data:image/png;base64`` URIs, inline CSS; no external resource, no
JavaScript.  Layout, top to bottom:

1. summary: warnings (an overall axis below :data:`LOW_AXIS`, weight-free
   probes), the best method per axis, an overview chart and the main table;
2. the other tables (per-scene, per-axis, IoU, ranks, reliability,
   association, sensitivity), each collapsible;
3. per scene: its settings, warnings and axes table, then per method the
   per-view plot, per-probe readings, notes (excluded views, LPIPS) and the
   per-view contact sheets (collapsible);
4. run metadata: versions, options, GPU adapter, probes.

Every text from the results is escaped with :func:`html.escape`.  Pictures
are read from the paths stored in the results, relative to the output folder;
a path leaving that folder, a missing file or a file that is not a PNG is
not embedded, and the page says so.
"""
from __future__ import annotations

import base64
import html
import json
import math
import os
import warnings
from pathlib import Path

from ..errors import R360Warning
from ..metrics.semantic import SemanticView, semantic_summary
from ..metrics.structural import StructuralView, structural_summary
from ..util.atomic import write_text
from ..util.warning_log import format_record
from .plots import axes_overview_png, view_series
from .results_io import method_entry, method_names, number, scene_names, structural_mode
from .results_tables import (
    build_results_tables,
    main_table,
    overall_value,
    scene_value,
    structural_header,
)
from .tables import Cell, Table, _emphasis, _fmt, _number_cells

REPORT_HTML = "report.html"
#: An axis below this value gets a warning banner.
LOW_AXIS = 0.5
#: Default number of per-view pictures embedded per (scene, method).
MAX_VIEWS = 8
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;color:#1d1d1f;
 margin:0 auto;max-width:1240px;padding:16px 24px 48px;line-height:1.4;background:#fff}
h1{font-size:1.6em;margin:0.2em 0}h2{font-size:1.3em;border-bottom:2px solid #ddd;padding-bottom:4px;margin-top:1.6em}
h3{font-size:1.08em;margin:1.1em 0 0.4em}.meta{color:#555;font-size:0.92em}
.warn{background:#fff4e5;border-left:5px solid #e67700;padding:6px 10px;margin:6px 0;font-size:0.95em}
.info{background:#eef5ff;border-left:5px solid #3b7dd8;padding:6px 10px;margin:6px 0;font-size:0.95em}
table{border-collapse:collapse;margin:6px 0 4px;font-size:0.88em}
caption{caption-side:top;text-align:left;font-weight:600;padding:4px 0}
th,td{padding:3px 9px;border-bottom:1px solid #e3e3e3;white-space:nowrap}
th{background:#f4f4f6;border-bottom:2px solid #bbb}td.num,th.num{text-align:right}
td.lab,th.lab{text-align:left}tr.rule td{border-top:2px solid #999}.vr{border-left:2px solid #999}
.notes{color:#555;font-size:0.82em;margin:2px 0 10px;max-width:1100px}
details{margin:6px 0}summary{cursor:pointer;font-weight:600;padding:3px 0}
details.method{border:1px solid #ddd;border-radius:6px;padding:4px 12px;margin:10px 0}
.grid{display:flex;flex-wrap:wrap;gap:12px}figure{margin:0}figcaption{font-size:0.82em;color:#333}
img{max-width:100%;height:auto;display:block}.kv td:first-child{color:#555}
code,pre{font-family:ui-monospace,"DejaVu Sans Mono",monospace;font-size:0.85em}
pre{white-space:pre-wrap;word-break:break-all;background:#f7f7f7;padding:6px;max-height:360px;overflow:auto}
ul.best{margin:4px 0 8px}nav a{margin-right:12px}
"""


def _e(text) -> str:
    return html.escape(str(text), quote=True)


# -- tables --------------------------------------------------------------------

def table_html(table: Table) -> str:
    """One table as an HTML ``<table>`` (caption = title) followed by its notes.

    Best values are ``<strong>``, second best ``<u>``; a rule before a row is a
    thicker top border; label columns are left-aligned, numbers right-aligned.
    """
    n_label = table.label_columns

    def cell(c: Cell, j: int, tag: str) -> str:
        cls = ["lab" if j < n_label else "num"] + (["vr"] if j in table.vrule_before and j > 0 else [])
        body = _e(c.text)
        if c.emphasis == "best" and body:
            body = f"<strong>{body}</strong>"
        elif c.emphasis == "second" and body:
            body = f"<u>{body}</u>"
        return f'<{tag} class="{" ".join(cls)}">{body}</{tag}>'

    out = [f"<table><caption>{_e(table.title)}</caption>",
           "<thead><tr>" + "".join(cell(c, j, "th") for j, c in enumerate(table.header)) + "</tr></thead><tbody>"]
    for i, row in enumerate(table.rows):
        cls = ' class="rule"' if i in table.rule_before else ""
        out.append(f"<tr{cls}>" + "".join(cell(c, j, "td") for j, c in enumerate(row)) + "</tr>")
    out.append("</tbody></table>")
    if table.notes:
        out.append('<p class="notes">' + " ".join(_e(n) for n in table.notes) + "</p>")
    return "\n".join(out)


def scene_table(results: dict, scene: str) -> Table:
    """One scene's axes per method (removal axes, RQS, then fidelity when present);
    best and second best per column emphasised."""
    methods = [m for m in method_names(results) if method_entry(results, scene, m) is not None]
    str_md = "sim_SAM" if structural_mode(results, scene) == "reference" else "1 - sim_SAM"
    cols = [("iou_drop", "IoU_drop", 3, True), ("s_sem", "acc_seg", 3, True), ("s_geo", "acc_depth", 3, True),
            ("s_str", str_md, 3, True), ("rqs", "RQS", 3, True)]
    if any(scene_value(results, scene, m, k) is not None for m in methods for k in ("psnr", "ssim")):
        cols += [("psnr", "PSNR", 2, True), ("ssim", "SSIM", 3, True), ("lpips", "LPIPS (lower is better)", 3, False)]
    rows = [[Cell(m)] + [Cell("")] * len(cols) for m in methods]
    for j, (key, _, dec, higher) in enumerate(cols, start=1):
        for row, c in zip(rows, _number_cells([scene_value(results, scene, m, key) for m in methods], dec, True,
                                              higher)):
            row[j] = c
    return Table(key=f"scene-{scene}", title=f"Scene {scene}: axes per method.",
                 header=[Cell("Method")] + [Cell(h) for _, h, _, _ in cols], rows=rows,
                 notes=("Best and second best per column are emphasised.",))


# -- pictures ------------------------------------------------------------------

def _png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


#: Contact sheets (photographic renders) are embedded as JPEG of this quality,
#: at most EMBED_WIDTH pixels wide: a few per cent of the PNG's size, which
#: keeps a report with dozens of views in the low megabytes.  The lossless
#: full-size PNGs stay beside the report.
JPEG_QUALITY = 80
EMBED_WIDTH = 960


def _jpeg_uri(png: bytes) -> str | None:
    import cv2
    import numpy as np

    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        return None
    if img.shape[1] > EMBED_WIDTH:
        h = max(1, round(img.shape[0] * EMBED_WIDTH / img.shape[1]))
        img = cv2.resize(img, (EMBED_WIDTH, h), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii") if ok else None


def _embed(out_dir: Path, rel, *, photo: bool = False) -> tuple[str | None, str | None]:
    """(data URI, None) for a PNG inside ``out_dir``, else (None, reason).

    photo: embed as JPEG (contact sheets of renders); plots stay PNG."""
    if not isinstance(rel, str) or not rel:
        return None, "no picture path"
    root = out_dir.resolve()
    p = (root / rel).resolve()
    try:
        p.relative_to(root)
    except ValueError:
        return None, f"picture path {rel!r} leaves the output folder; not embedded"
    try:
        data = p.read_bytes()
    except OSError:
        return None, f"picture {rel!r} not found"
    if not data.startswith(_PNG_SIGNATURE):
        return None, f"picture {rel!r} is not a PNG; not embedded"
    if photo:
        uri = _jpeg_uri(data)
        if uri is None:
            return None, f"picture {rel!r} could not be decoded; not embedded"
        return uri, None
    return _png_uri(data), None


def _img(uri: str, alt: str, width: int | None = None) -> str:
    w = f' width="{int(width)}"' if width else ""
    return f'<img src="{uri}" alt="{_e(alt)}"{w}>'


# -- summary pieces ------------------------------------------------------------

def _low_axis_message(axis: str, mode: str) -> str:
    if axis == "s_sem":
        return "the semantic probe still finds the object in many views"
    if axis == "s_geo":
        return "geometry barely changed inside the target region"
    if mode == "reference":
        return "the structure disagrees with the post-removal reference"
    if mode == "reference_free":
        return "the structure of the target region barely changed"
    return "weak structural score"


def low_axis_warnings(results: dict, threshold: float = LOW_AXIS) -> list[str]:
    """One line per (method, axis) whose Overall value is below ``threshold``."""
    modes = {structural_mode(results, s) for s in scene_names(results)}
    mode = modes.pop() if len(modes) == 1 else "mixed"
    out = []
    for m in method_names(results):
        for axis in ("s_sem", "s_geo", "s_str"):
            v = overall_value(results, m, axis)
            if v is not None and not math.isnan(v) and v < threshold:
                out.append(f"{m}: {axis} = {v:.3f} < {threshold:g} -- {_low_axis_message(axis, mode)}.")
    return out


def best_per_axis(results: dict) -> list[tuple[str, list[str], float, int]]:
    """(axis label, best methods, value, decimals) for each Overall axis; ties at the
    printed precision (``decimals``) share the first place, lowest AvgRank is best."""
    methods = method_names(results)
    str_md = structural_header(results)[0]
    specs = [("s_sem (acc_seg)", "s_sem", True, 3), ("s_geo (acc_depth)", "s_geo", True, 3),
             (f"s_str ({str_md})", "s_str", True, 3), ("RQS", "rqs", True, 3), ("AvgRank", "avg_rank", False, 2),
             ("IoU_drop (diagnostic)", "iou_drop", True, 3)]
    out = []
    for label, key, higher, dec in specs:
        vals = [overall_value(results, m, key) for m in methods]
        vals = [None if v is None or math.isnan(v) else v for v in vals]
        marks = _emphasis(vals, dec, higher)
        best = [m for m, mk in zip(methods, marks) if mk == "best"]
        if not best and sum(v is not None for v in vals) == 1:
            best = [m for m, v in zip(methods, vals) if v is not None]
        if best:
            out.append((label, best, next(v for m, v in zip(methods, vals) if m == best[0]), dec))
    return out


def _weight_free_probes(results: dict) -> list[dict]:
    probes = results.get("probes") or {}
    out = []
    for kind in ("semantic", "structural"):
        for p in probes.get(kind) or []:
            if isinstance(p, dict) and p.get("weight_free"):
                out.append({**p, "kind": p.get("kind", kind)})
    return out


# -- per-method pieces -----------------------------------------------------------

def probe_readings(results: dict, scene: str, method: str) -> list[tuple[str, str, str, str]]:
    """(probe, axis, values, views scored) per probe, recomputed from the view records
    with the metric summaries (empty targets excluded unless ``options.include_empty_targets``)."""
    entry = method_entry(results, scene, method) or {}
    recs = entry.get("views") or []
    include = bool((results.get("options") or {}).get("include_empty_targets", False))
    out = []
    sem: dict[str, list[SemanticView]] = {}
    struct: dict[str, list[StructuralView]] = {}
    for r in recs:
        for p, v in (r.get("semantic") or {}).items():
            sem.setdefault(p, []).append(SemanticView.from_dict(v))
        for p, v in (r.get("structural") or {}).items():
            struct.setdefault(p, []).append(StructuralView.from_dict(v))
    for p, views in sem.items():
        s = semantic_summary(views, include_empty_targets=include)
        vals = (f"mIoU_pre {_fmt(s.iou_pre, 3)}, mIoU_post {_fmt(s.iou_post, 3)}, IoU_drop {_fmt(s.iou_drop, 3)}, "
                f"acc_seg(0.3) {_fmt(s.s_sem, 3)}")
        out.append((p, "semantic", vals, f"{s.n_scored}/{s.n_views}"))
    for p, views in struct.items():
        s = structural_summary(views, include_empty_targets=include)
        label = "sim_SAM(I_post, I_ref)" if s.mode == "reference" else "sim_SAM(I_pre, I_post)"
        out.append((p, "structural", f"{label} {_fmt(s.sim_sam, 3)}, s_str {_fmt(s.s_str, 3)}",
                    f"{s.n_scored}/{s.n_views}"))
    return out


def _view_caption(rec: dict) -> str:
    parts = []
    for p, v in (rec.get("semantic") or {}).items():
        pre, post = number(v.get("iou_pre")), number(v.get("iou_post"))
        if pre is not None and post is not None:
            parts.append(f"IoU {pre:.2f}->{post:.2f}")
    geo = rec.get("geometric") or {}
    if geo:
        parts.append("acc_depth excluded" if geo.get("excluded")
                     else f"acc_depth {_fmt(number(geo.get('acc_depth')), 2)}")
    for p, v in (rec.get("structural") or {}).items():
        parts.append(f"sim {_fmt(number(v.get('sim_sam')), 2)}")
    fid = rec.get("fidelity") or {}
    if fid:
        parts.append(f"PSNR {_fmt(number(fid.get('psnr')), 1)}")
    return ", ".join(parts)


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


def _method_section(results: dict, out_dir: Path, scene: str, method: str, problems: list[str],
                    max_views: int | None) -> str:
    entry = method_entry(results, scene, method) or {}
    axes = entry.get("axes") or {}
    rqs = number(axes.get("rqs"))
    h = [f'<details class="method" open><summary>{_e(method)} &mdash; RQS {_e(_fmt(rqs, 3))}</summary>']
    mode = structural_mode(results, scene)
    lows = [f"{a} = {number(axes.get(a)):.3f} -- {_low_axis_message(a, mode)}" for a in ("s_sem", "s_geo", "s_str")
            if number(axes.get(a)) is not None and number(axes.get(a)) < LOW_AXIS]
    for line in lows:
        h.append(f'<div class="warn">{_e(line)}</div>')
    plot = entry.get("plot")
    if plot is not None:
        uri, why = _embed(out_dir, plot)
        if uri:
            h.append(_img(uri, f"per-view axes of {method} on {scene}"))
        else:
            h.append(f'<div class="warn">{_e(why)}</div>')
            problems.append(f"{scene}/{method}: {why}")
    readings = probe_readings(results, scene, method)
    if readings:
        h.append('<table><thead><tr><th class="lab">Probe</th><th class="lab">Axis</th><th class="lab">Readings</th>'
                 '<th class="num">Views scored</th></tr></thead><tbody>')
        for p, kind, vals, n in readings:
            h.append(f'<tr><td class="lab">{_e(p)}</td><td class="lab">{_e(kind)}</td><td class="lab">{_e(vals)}</td>'
                     f'<td class="num">{_e(n)}</td></tr>')
        h.append("</tbody></table>")
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
        h.append(f'<p class="notes">{_e(n)}</p>')
    pics = entry.get("pictures") or {}
    if pics:
        shown = pick_views(list(pics), max_views)
        count = f"{len(pics)} views" if len(shown) == len(pics) else f"{len(shown)} of {len(pics)} views"
        h.append(f"<details><summary>Per-view pictures ({_e(count)})</summary>")
        if len(shown) < len(pics):
            h.append(f'<p class="notes">Evenly spaced along the camera path; every view\'s picture is in the '
                     f'{_e(os.path.dirname(str(next(iter(pics.values())))) or ".")} folder.</p>')
        h.append('<div class="grid">')
        by_view = {str(r.get("view")): r for r in entry.get("views") or []}
        for view in shown:
            rel = pics[view]
            uri, why = _embed(out_dir, rel, photo=True)
            cap = f"{view}: {_view_caption(by_view.get(str(view), {}))}"
            if uri:
                img = _img(uri, f"{scene} / {method} / {view}")
                h.append(f"<figure>{img}<figcaption>{_e(cap)}</figcaption></figure>")
            else:
                h.append(f'<figure><div class="warn">{_e(why)}</div><figcaption>{_e(cap)}</figcaption></figure>')
                problems.append(f"{scene}/{method}/{view}: {why}")
        h.append("</div></details>")
    h.append("<details><summary>Axis record (as stored)</summary><pre>"
             + _e(json.dumps(axes, indent=1, sort_keys=True, ensure_ascii=False)) + "</pre></details>")
    h.append("</details>")
    return "\n".join(h)


def _kv_table(d: dict) -> str:
    rows = []
    for k, v in d.items():
        if isinstance(v, (list, tuple)) and all(not isinstance(x, (dict, list)) for x in v):
            text = ", ".join(str(x) for x in v)
        elif isinstance(v, (dict, list)):
            text = json.dumps(v, sort_keys=True, ensure_ascii=False)
        else:
            text = str(v)
        rows.append(f'<tr><td class="lab">{_e(k)}</td><td class="lab"><code>{_e(text)}</code></td></tr>')
    return '<table class="kv"><tbody>' + "".join(rows) + "</tbody></table>"


def _probes_html(results: dict) -> str:
    probes = results.get("probes") or {}
    rows = []
    for kind in ("semantic", "structural"):
        for p in probes.get(kind) or []:
            if not isinstance(p, dict):
                continue
            models = p.get("models") or {}
            mtext = ", ".join(f"{f} (sha256 {str(h)[:12]})" for f, h in models.items()) or "none"
            rows.append(
                f'<tr><td class="lab">{_e(kind)}</td><td class="lab">{_e(p.get("name", "?"))}</td>'
                f'<td class="lab">{_e(mtext)}</td><td class="lab">{"yes" if p.get("weight_free") else "no"}</td>'
                f'<td class="lab"><code>{_e(json.dumps(p.get("params", {}), sort_keys=True))}</code></td></tr>')
    if not rows:
        return "<p>No probe descriptions in the results.</p>"
    return ('<table><thead><tr><th class="lab">Axis</th><th class="lab">Probe</th><th class="lab">Models</th>'
            '<th class="lab">Weight-free</th><th class="lab">Parameters</th></tr></thead><tbody>'
            + "".join(rows) + "</tbody></table>")


# -- the page ------------------------------------------------------------------

def report_html(results: dict, out_dir: str | os.PathLike, *,
                max_views: int | None = MAX_VIEWS) -> tuple[str, list[str]]:
    """The page's HTML text and the list of pictures that could not be embedded.

    out_dir: the folder the picture paths in ``results`` are relative to.
    max_views: per (scene, method), embed at most this many per-view pictures
        (evenly spaced, :func:`pick_views`); None embeds all.
    """
    out = Path(out_dir)
    problems: list[str] = []
    scenes, methods = scene_names(results), method_names(results)
    str_md = structural_header(results)[0]
    h = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
         '<meta name="viewport" content="width=device-width, initial-scale=1">',
         "<title>r360gpu report</title>", f"<style>{_CSS}</style></head><body>"]
    meta = [f"r360gpu {results.get('r360gpu_version', '?')}"]
    if results.get("created"):
        meta.append(f"created {results['created']}")
    meta.append(f"{len(scenes)} scene(s), {len(methods)} method(s)")
    h.append("<header><h1>Remove360 evaluation report</h1>"
             f'<p class="meta">{_e(" | ".join(meta))}</p></header>')
    nav = ['<a href="#summary">Summary</a>', '<a href="#tables">Tables</a>']
    nav += [f'<a href="#scene-{i}">{_e(s)}</a>' for i, s in enumerate(scenes)]
    nav.append('<a href="#metadata">Run metadata</a>')
    h.append("<nav>" + "".join(nav) + "</nav>")

    # Summary
    h.append('<section id="summary"><h2>Summary</h2>')
    for line in low_axis_warnings(results):
        h.append(f'<div class="warn"><strong>Warning:</strong> {_e(line)}</div>')
    input_warnings = results.get("warnings") or []  # recorded by r360gpu.util.warning_log
    for w in input_warnings[:50]:
        h.append(f'<div class="warn"><strong>Input warning:</strong> {_e(format_record(w))}</div>')
    if len(input_warnings) > 50:
        h.append(f'<div class="warn">... and {len(input_warnings) - 50} more input warnings in results.json</div>')
    free = _weight_free_probes(results)
    if free:
        names = ", ".join(f"{p.get('name', '?')} ({p['kind']})" for p in free)
        lims = " ".join(f"{p.get('name', '?')}: {p['limitations']}" for p in free if p.get("limitations"))
        h.append(f'<div class="info"><strong>Note:</strong> weight-free built-in probes: {_e(names)}. They are '
                 "weaker than the learned probes of the paper (GroundedSAM2 / SAM): compare methods under the same "
                 "probes only, not with published numbers." + (f" Limitations: {_e(lims)}" if lims else "")
                 + "</div>")
    best = best_per_axis(results)
    if best:
        h.append('<h3>Best method per axis</h3><ul class="best">')
        for label, ms, v, dec in best:
            h.append(f"<li>{_e(label)}: <strong>{_e(', '.join(ms))}</strong> ({_e(_fmt(v, dec))})</li>")
        h.append("</ul>")
    overall = {m: {k: overall_value(results, m, k) for k in ("s_sem", "s_geo", "s_str", "rqs")} for m in methods}
    if any(v is not None for d in overall.values() for v in d.values()):
        h.append(_img(_png_uri(axes_overview_png(overall, title="Overall axes per method", low=LOW_AXIS,
                                                 str_label=str_md)), "overall axes per method"))
    h.append(table_html(main_table(results)))
    h.append("</section>")

    # Tables
    tables, notes = build_results_tables(results)
    h.append('<section id="tables"><h2>Tables</h2>')
    for t in tables[1:]:
        h.append(f"<details><summary>{_e(t.title)}</summary>{table_html(t)}</details>")
    for n in notes:
        h.append(f'<p class="notes">Note: {_e(n)}</p>')
    h.append("</section>")

    # Scenes
    for i, s in enumerate(scenes):
        sd = (results.get("scenes") or {}).get(s) or {}
        mode = structural_mode(results, s)
        h.append(f'<section id="scene-{i}"><h2>Scene {_e(s)}</h2>')
        facts = [f"prompt: {sd.get('prompt', '?')}", f"views: {sd.get('n_views', '?')}",
                 "reference: " + ("yes" if sd.get("reference") else "no"),
                 "structural axis: " + ("sim_SAM(I_post, I_ref)" if mode == "reference"
                                        else "1 - sim_SAM(I_pre, I_post)")]
        h.append(f'<p class="meta">{_e(" | ".join(facts))}</p>')
        ex = sd.get("excluded_views")
        if ex:
            items = ex.items() if isinstance(ex, dict) else [("views", ex)]
            text = "; ".join(f"{k}: {', '.join(map(str, v)) if isinstance(v, (list, tuple)) else v}" for k, v in items)
            h.append(f'<p class="notes">Excluded views: {_e(text)}</p>')
        h.append(table_html(scene_table(results, s)))
        for m in methods:
            if method_entry(results, s, m) is not None:
                h.append(_method_section(results, out, s, m, problems, max_views))
        h.append("</section>")

    # Metadata
    h.append('<section id="metadata"><h2>Run metadata</h2>')
    h.append(_kv_table({"r360gpu version": results.get("r360gpu_version", "?"), "schema": results.get("schema", "?"),
                        "created": results.get("created", "?")}))
    if results.get("options"):
        h.append("<h3>Options</h3>" + _kv_table(results["options"]))
    if results.get("adapter"):
        h.append("<h3>GPU adapter</h3>" + _kv_table(results["adapter"]))
    h.append("<h3>Probes</h3>" + _probes_html(results))
    h.append("</section></body></html>")
    return "\n".join(h) + "\n", problems


def write_html(results: dict, out_dir: str | os.PathLike, *, max_views: int | None = MAX_VIEWS) -> Path:
    """Write ``OUT/report.html`` (atomically) and return its path.

    max_views: per (scene, method), the number of per-view contact sheets
    embedded (evenly spaced along the path; None: all).  Each sheet is a few
    hundred kB, so embedding every view of a long path would make the page
    heavy; the sheets not embedded stay in the pictures folder.

    Pictures that cannot be embedded are named on the page and in one
    :class:`~r360gpu.errors.R360Warning`.
    """
    out = Path(out_dir)
    text, problems = report_html(results, out, max_views=max_views)
    path = out / REPORT_HTML
    write_text(path, text)
    if problems:
        warnings.warn(f"{path}: {len(problems)} picture(s) not embedded: " + "; ".join(problems), R360Warning,
                      stacklevel=2)
    return path
