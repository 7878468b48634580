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

import base64
import html
import json
import math
import os
import urllib.parse
import warnings
from pathlib import Path

from ..errors import R360Warning
from ..metrics.semantic import SemanticView, semantic_summary
from ..metrics.structural import StructuralView, structural_summary
from ..protocol import AXES
from ..util.atomic import write_text
from ..util.warning_log import format_record
from . import findings
from .embed import JPEG_QUALITY, sheet_jpeg
from .findings import LOW_AXIS
from .contact_sheets import sheet_panel, view_numbers
from .plots import axes_overview_png, view_series
from .results_io import method_entry, method_names, number, scene_names, structural_mode
from .results_tables import (
    build_results_tables,
    main_table,
    overall_value,
    scene_value,
    structural_header,
)
from .tables import Cell, Table, emphasis_marks, fmt_number, number_cells

REPORT_HTML = "report.html"
#: Default number of per-view pictures embedded per (scene, method): all.
MAX_VIEWS = None
#: Width (px) of the worst-view thumbnails on the first screen.
THUMB_WIDTH = 220
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

_CSS = """
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;color:#1d1d1f;
 margin:0 auto;max-width:1240px;padding:12px 20px 48px;line-height:1.4;background:#fff;overflow-wrap:anywhere}
h1{font-size:1.5em;margin:0.1em 0}h2{font-size:1.3em;border-bottom:2px solid #ddd;padding-bottom:4px;margin-top:1.4em}
h3{font-size:1.08em;margin:0.9em 0 0.3em}h4{font-size:1em;margin:0.8em 0 0.2em}.meta{color:#555;font-size:0.92em;margin:2px 0}
.warn{background:#fff4e5;border-left:5px solid #e67700;padding:6px 10px;margin:6px 0;font-size:0.95em}
.info{background:#eef5ff;border-left:5px solid #3b7dd8;padding:6px 10px;margin:6px 0;font-size:0.95em}
.info ul{margin:4px 0 0;padding-left:20px}ul.notes{padding-left:20px;margin:2px 0 6px}
.scroll{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;margin:6px 0 4px;font-size:0.88em}
caption{caption-side:top;text-align:left;font-weight:600;padding:4px 0}
th,td{padding:3px 8px;border-bottom:1px solid #e3e3e3;overflow-wrap:normal}td{white-space:nowrap}
th{background:#f4f4f6;border-bottom:2px solid #bbb;font-weight:600}td.num,th.num{text-align:right}
td.lab,th.lab{text-align:left}tr.rule td{border-top:2px solid #999}.vr{border-left:2px solid #999}
td.wrap{white-space:normal;min-width:12em}
td.doubt{background:#fff1d6}sup.doubt{color:#b35900;font-weight:700}
td.v-ok{background:#e6f4ea}td.v-weak{background:#fff1d6}td.v-blind{background:#fde2e1;font-weight:600}
td.caught{background:#e6f4ea}td.missed{background:#fde2e1}td.partly{background:#fff1d6}
.notes{color:#555;font-size:0.82em;margin:2px 0 10px;max-width:1100px}
details{margin:6px 0}summary{cursor:pointer;font-weight:600;padding:3px 0}
details.method{border:1px solid #ddd;border-radius:6px;padding:4px 12px;margin:10px 0}
.grid{display:flex;flex-wrap:wrap;gap:12px}figure{margin:0;max-width:100%}figcaption{font-size:0.82em;color:#333}
.thumbs{display:flex;flex-wrap:wrap;gap:10px}.thumbs figure{width:""" + str(THUMB_WIDTH) + """px}
.thumbs a{color:inherit;text-decoration:none}.thumbs figcaption b{display:block}
img{max-width:100%;height:auto;display:block}
code,pre{font-family:ui-monospace,"DejaVu Sans Mono",monospace;font-size:0.85em}
pre{white-space:pre-wrap;background:#f7f7f7;padding:6px;max-height:360px;overflow:auto}
table.kv td{white-space:normal;vertical-align:top;overflow-wrap:anywhere}table.kv td:first-child{color:#555;white-space:nowrap}
table.kv table.kv{margin:0;font-size:1em}
table.sortable th{cursor:pointer;user-select:none}table.sortable th[aria-sort=ascending]::after{content:" \\25B2"}
table.sortable th[aria-sort=descending]::after{content:" \\25BC"}
table.perview td{padding:2px 6px}table.perview th{white-space:normal;min-width:3.2em}
@media (max-width:900px){body{padding:8px 10px 40px}table{font-size:0.8em}th,td{padding:2px 4px}
 table.perview{font-size:0.76em}table.perview td,table.perview th{padding:2px 3px}}tr:target td{background:#ffe9a8}figure:target{outline:3px solid #e6a700}
ul.best{margin:4px 0 8px}nav a{margin-right:12px}
"""

#: Sorting of the per-view tables (click a header; numbers numerically, missing values last) and
#: opening the collapsed sections an in-page link points into.
_JS = """
(function(){
function key(c){var v=c.getAttribute('data-v');if(v===null)v=c.textContent;var n=parseFloat(v);
 return isNaN(n)?{n:null,s:v}:{n:n,s:v};}
document.querySelectorAll('table.sortable').forEach(function(t){
 var hs=t.tHead.rows[0].cells;
 Array.prototype.forEach.call(hs,function(th,i){th.title='sort by this column';
  th.addEventListener('click',function(){
   var asc=th.getAttribute('aria-sort')!=='ascending';
   Array.prototype.forEach.call(hs,function(h){h.removeAttribute('aria-sort');});
   th.setAttribute('aria-sort',asc?'ascending':'descending');
   var tb=t.tBodies[0],rows=Array.prototype.slice.call(tb.rows);
   rows.sort(function(a,b){var x=key(a.cells[i]),y=key(b.cells[i]);
    if(x.n===null&&y.n===null)return asc?x.s.localeCompare(y.s):y.s.localeCompare(x.s);
    if(x.n===null)return 1;if(y.n===null)return -1;return asc?x.n-y.n:y.n-x.n;});
   rows.forEach(function(r){tb.appendChild(r);});});});});
function reveal(){var id=decodeURIComponent(location.hash.slice(1));if(!id)return;
 var el=document.getElementById(id);if(!el)return;
 for(var p=el.parentElement;p;p=p.parentElement){if(p.tagName==='DETAILS')p.open=true;}
 el.scrollIntoView();}
window.addEventListener('hashchange',reveal);reveal();
})();
"""


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _scroll(inner: str) -> str:
    """A box that scrolls sideways by itself when ``inner`` is wider than the page."""
    return f'<div class="scroll">{inner}</div>'


# -- tables --------------------------------------------------------------------

def table_html(table: Table, *, flags: dict[int, str] | None = None, caption: bool = True) -> str:
    """One table as an HTML ``<table>`` (caption = title) followed by its notes, in a box that
    scrolls sideways when the table is wider than the page.

    Best values are ``<strong>``, second best ``<u>``; a rule before a row is a
    thicker top border; label columns are left-aligned, numbers right-aligned.
    flags: {column index: reason}: body cells of those columns are marked
    (class ``doubt``, a dagger) with the reason as tooltip.  caption: False
    leaves the title out (when a ``<summary>`` already shows it).
    """
    n_label = table.label_columns
    flags = flags or {}

    def cell(c: Cell, j: int, tag: str) -> str:
        cls = ["lab" if j < n_label else "num"] + (["vr"] if j in table.vrule_before and j > 0 else [])
        body = _e(c.text)
        if c.emphasis == "best" and body:
            body = f"<strong>{body}</strong>"
        elif c.emphasis == "second" and body:
            body = f"<u>{body}</u>"
        title = ""
        if tag == "td" and j in flags:
            cls.append("doubt")
            body += '<sup class="doubt">&dagger;</sup>'
            title = f' title="{_e(flags[j])}"'
        return f'<{tag} class="{" ".join(cls)}"{title}>{body}</{tag}>'

    out = [f"<table><caption>{_e(table.title)}</caption>" if caption else "<table>",
           "<thead><tr>" + "".join(cell(c, j, "th") for j, c in enumerate(table.header)) + "</tr></thead><tbody>"]
    for i, row in enumerate(table.rows):
        cls = ' class="rule"' if i in table.rule_before else ""
        out.append(f"<tr{cls}>" + "".join(cell(c, j, "td") for j, c in enumerate(row)) + "</tr>")
    out.append("</tbody></table>")
    text = _scroll("\n".join(out))
    if table.notes:
        text += '\n<p class="notes">' + "<br>\n".join(_e(n) for n in table.notes) + "</p>"
    return text


def scene_table(results: dict, scene: str) -> Table:
    """One scene's axes per method (removal axes, RQS, then fidelity when present; LPIPS only
    when computed); best and second best per column emphasised."""
    methods = [m for m in method_names(results) if method_entry(results, scene, m) is not None]
    str_md = "sim_SAM" if structural_mode(results, scene) == "reference" else "1 - sim_SAM"
    cols = [("iou_drop", "IoU_drop", 3, True), ("s_sem", "acc_seg", 3, True), ("s_geo", "acc_depth", 3, True),
            ("s_str", str_md, 3, True), ("rqs", "RQS", 3, True)]
    if any(scene_value(results, scene, m, k) is not None for m in methods for k in ("psnr", "ssim")):
        cols += [("psnr", "PSNR", 2, True), ("ssim", "SSIM", 3, True)]
    if any(scene_value(results, scene, m, "lpips") is not None for m in methods):
        cols.append(("lpips", "LPIPS (lower is better)", 3, False))
    rows = [[Cell(m)] + [Cell("")] * len(cols) for m in methods]
    for j, (key, _, dec, higher) in enumerate(cols, start=1):
        for row, c in zip(rows, number_cells([scene_value(results, scene, m, key) for m in methods], dec, True,
                                              higher)):
            row[j] = c
    return Table(key=f"scene-{scene}", title=f"Scene {scene}: axes per method.",
                 header=[Cell("Method")] + [Cell(h) for _, h, _, _ in cols], rows=rows,
                 notes=("Best and second best per column are emphasised.",))


def _doubt_flags(results: dict, table: Table) -> tuple[dict[int, str], list[str]]:
    """Columns of the Overall table whose axis has a probe verdict other than "ok" in some scene:
    ({column: reason}, note lines)."""
    doubtful = findings.doubtful_axes(results)
    if not doubtful:
        return {}, []
    header = [c.text for c in table.header]
    columns = {"s_sem": "acc_seg", "s_geo": "acc_depth", "s_str": structural_header(results)[0]}
    verdict = {(v.scene, v.axis): v.verdict for v in findings.probe_verdicts(results)}
    flags, notes = {}, []
    for axis, scenes in doubtful.items():
        if columns[axis] not in header:
            continue
        where = ", ".join(f"{s} ({verdict[s, axis]})" for s in scenes)
        flags[header.index(columns[axis])] = f"the {axis} probe check is not ok in: {where}"
        notes.append(f"\u2020 {columns[axis]} ({axis}): the probe check is not ok in scene(s) {where}; "
                     "see the probe verdicts.")
    return flags, notes


# -- pictures ------------------------------------------------------------------

def _png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _jpeg_uri(png: bytes, embed_cache: Path | None = None) -> str | None:
    jpeg = sheet_jpeg(png, embed_cache)
    return None if jpeg is None else "data:image/jpeg;base64," + base64.b64encode(jpeg).decode("ascii")


def _embed_many(out_dir: Path, rels: list, embed_cache: Path | None = None) -> list[tuple[str | None, str | None]]:
    """:func:`_embed` of many contact sheets as photos, in threads (OpenCV's decode, resize
    and encode release the GIL, and a run has one sheet per method and view)."""
    from concurrent.futures import ThreadPoolExecutor

    def one(r):
        return _embed(out_dir, r, photo=True, embed_cache=embed_cache)

    if len(rels) < 2:
        return [one(r) for r in rels]
    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1), thread_name_prefix="r360-embed") as pool:
        return list(pool.map(one, rels))


def _embed(out_dir: Path, rel, *, photo: bool = False, embed_cache: Path | None = None
           ) -> tuple[str | None, str | None]:
    """(data URI, None) for a PNG inside ``out_dir``, else (None, reason).

    photo: embed as JPEG (contact sheets of renders; from ``embed_cache`` when
    it holds the sheet's JPEG, see :mod:`.embed`); plots stay PNG."""
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
        uri = _jpeg_uri(data, embed_cache)
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
        for axis in AXES:
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
        marks = emphasis_marks(vals, dec, higher)
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
        vals = (f"mIoU_pre {fmt_number(s.iou_pre, 3)}, mIoU_post {fmt_number(s.iou_post, 3)}, IoU_drop {fmt_number(s.iou_drop, 3)}, "
                f"acc_seg(0.3) {fmt_number(s.s_sem, 3)}")
        out.append((p, "semantic", vals, f"{s.n_scored}/{s.n_views}"))
    for p, views in struct.items():
        s = structural_summary(views, include_empty_targets=include)
        label = "sim_SAM(I_post, I_ref)" if s.mode == "reference" else "sim_SAM(I_pre, I_post)"
        out.append((p, "structural", f"{label} {fmt_number(s.sim_sam, 3)}, s_str {fmt_number(s.s_str, 3)}",
                    f"{s.n_scored}/{s.n_views}"))
    return out


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


def _pic_id(results: dict, scene: str, method: str, view: str) -> str:
    """Anchor of one contact sheet (indices, so any scene / method / view name is a valid id)."""
    si = scene_names(results).index(scene)
    mi = method_names(results).index(method)
    vi = list(((results.get("scenes") or {}).get(scene) or {}).get("views") or []).index(view) \
        if view in (((results.get("scenes") or {}).get(scene) or {}).get("views") or []) else view
    return f"pic-{si}-{mi}-{vi}"


# -- readable records -------------------------------------------------------------

def _value_text(v) -> str:
    n = number(v)
    if n is not None and not isinstance(v, int):
        if not math.isfinite(n):
            return str(n)
        # 3 decimals like the tables; tiny and large values keep 4 significant digits
        return f"{n:.3f}" if n == 0 or 0.01 <= abs(n) < 1000 else f"{n:.4g}"
    if isinstance(v, (list, tuple)):
        if v and all(not isinstance(x, (dict, list)) for x in v):
            distinct = list(dict.fromkeys(str(x) for x in v))
            if len(distinct) == 1 and len(v) > 4:  # e.g. the same probe name once per view
                return f"{distinct[0]} (x{len(v)})"
            return ", ".join(_value_text(x) for x in v)
        return json.dumps(v, sort_keys=True, ensure_ascii=False)
    return str(v)


def kv_html(d: dict, depth: int = 0) -> str:
    """A dict as a two-column table that wraps: numbers to 3 decimals, flat dicts on one line
    ("0.3: 1.000, 0.5: 1.000"), nested dicts as nested tables, repeated list items counted."""
    rows = []
    for k, v in d.items():
        if isinstance(v, dict) and v and all(not isinstance(x, (dict, list)) for x in v.values()) \
                and (len(v) <= 6 or depth >= 2):
            text = _e(", ".join(f"{kk}: {_value_text(vv)}" for kk, vv in v.items()))
        elif isinstance(v, dict) and v and depth < 3:
            text = kv_html(v, depth + 1)
        else:
            text = _e(_value_text(v) if not isinstance(v, dict) else json.dumps(v, ensure_ascii=False))
        rows.append(f'<tr><td class="lab">{_e(k)}</td><td class="lab">{text}</td></tr>')
    return '<table class="kv"><tbody>' + "".join(rows) + "</tbody></table>"


def _kv_table(d: dict) -> str:
    return _scroll(kv_html(d))


# -- first screen -------------------------------------------------------------------

def _thumbnail(out_dir: Path, row: dict, problems: list[str]) -> str | None:
    """Data URI of the I_post panel of a view's contact sheet (whole sheet when the panel cannot be
    cut out), JPEG at most :data:`THUMB_WIDTH` * 2 px wide; None when the sheet is not embeddable."""
    import cv2
    import numpy as np

    rel = row.get("picture")
    if not rel:
        return None
    uri, why = _embed(out_dir, rel)
    if uri is None:
        problems.append(f"{row['scene']}/{row['method']}/{row['view']}: {why}")
        return None
    png = base64.b64decode(uri.split(",", 1)[1])
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        return None
    rec = row.get("record") or {}
    panel = sheet_panel(img, 1, n_lines=len(view_numbers(rec)))
    img = panel if panel is not None else img
    w = THUMB_WIDTH * 2
    if img.shape[1] > w:
        img = cv2.resize(img, (w, max(1, round(img.shape[0] * w / img.shape[1]))), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii") if ok else None


def _row_summary(row: dict) -> str:
    parts = []
    if row.get("iou_post") is not None:
        parts.append(f"IoU_post {row['iou_post']:.2f} ({'found' if row.get('s_sem') == 0.0 else 'not found'})")
    if row.get("acc_depth") is not None:
        parts.append(f"acc_depth {row['acc_depth']:.2f}")
    if row.get("s_str") is not None:
        parts.append(f"s_str {row['s_str']:.2f}")
    return ", ".join(parts)


def worst_views_html(results: dict, out_dir: Path, rows: list[dict], problems: list[str]) -> str:
    """Per method, the view that leaks most (lowest mean of its per-view axes) as a thumbnail of
    I_post linked to its contact sheet."""
    worst = findings.worst_views(results, rows)
    scored = list(dict.fromkeys(r["method"] for r in rows if r["leak"] is not None))
    if not scored:
        return ""
    h = ['<h3>Where each method leaks most</h3><p class="notes">Per method, among the views where an axis '
         f"is below {findings.LOW_AXIS:g} (s_sem 0/1 at xi = 0.3, acc_depth, s_str), the one with the lowest "
         "mean of those axes; I_post with the target outlined in green. Click for the contact sheet.</p>",
         '<div class="thumbs">']
    clean = [m for m in method_names(results) if m in scored and m not in worst]
    for m in method_names(results):
        row = worst.get(m)
        if row is None:
            continue
        anchor = _pic_id(results, row["scene"], m, row["view"])
        uri = _thumbnail(out_dir, row, problems)
        img = _img(uri, f"worst view of {m}: {row['scene']} / {row['view']}") if uri else ""
        cap = (f"<b>{_e(m)}</b>{_e(row['scene'])} / {_e(row['view'])}: {_e(_row_summary(row))} "
               f"(mean {row['leak']:.2f})")
        h.append(f'<figure><a href="#{anchor}">{img}<figcaption>{cap}</figcaption></a></figure>')
    h.append("</div>")
    if clean:
        h.append(f'<p class="notes">No view leaks (every axis at or above {findings.LOW_AXIS:g} in every view): '
                 + ", ".join(f"<b>{_e(m)}</b>" for m in clean) + ".</p>")
    return "\n".join(h)


def verdicts_html(results: dict) -> str:
    """Probe verdicts per scene and axis with one sentence per verdict that is not "ok"; empty when
    the results have none."""
    verdicts = findings.probe_verdicts(results)
    if not verdicts:
        return ""
    h = ["<h3>Probe checks</h3>",
         '<p class="notes">Can each axis see this scene\'s object? "ok": its probe separates the unchanged scene '
         'from the true removal; "weak": only partly; "blind": not at all (scores of both controls below).</p>']
    scenes = list(dict.fromkeys(v.scene for v in verdicts))
    by = {(v.scene, v.axis): v for v in verdicts}
    t = ['<table><thead><tr><th class="lab">Scene</th>'
         + "".join(f'<th class="lab">{a}</th>' for a in AXES) + "</tr></thead><tbody>"]
    for s in scenes:
        cells = []
        for a in AXES:
            v = by.get((s, a))
            text = v.verdict if v is not None and v.verdict else "--"
            cls = f"v-{text}" if text in findings.VERDICTS else ""
            cells.append(f'<td class="lab {cls}">{_e(text)}</td>')
        t.append(f'<tr><td class="lab">{_e(s)}</td>{"".join(cells)}</tr>')
    t.append("</tbody></table>")
    h.append(_scroll("".join(t)))
    sentences = [v for v in verdicts if v.sentence]
    if sentences:
        h.append('<ul class="notes">' + "".join(f"<li><strong>{_e(v.scene)}:</strong> {_e(v.sentence)}</li>"
                                               for v in sentences) + "</ul>")
    return "\n".join(h)


def controls_html(results: dict) -> str:
    """The control scores (``scenes.S.controls``) as a collapsed table; empty without controls."""
    ctrl = findings.controls(results)
    if not ctrl:
        return ""
    keys = ("s_sem", "s_geo", "s_str", "rqs")
    t = ['<table><thead><tr><th class="lab">Scene</th><th class="lab">Control</th>'
         + "".join(f'<th class="num">{k}</th>' for k in keys) + "</tr></thead><tbody>"]
    for s, name, axes in ctrl:
        t.append(f'<tr><td class="lab">{_e(s)}</td><td class="lab">{_e(name)}</td>'
                 + "".join(f'<td class="num">{_e(fmt_number(number(axes.get(k)), 3))}</td>' for k in keys) + "</tr>")
    t.append("</tbody></table>")
    return ("<details><summary>Controls behind the probe checks</summary>"
            '<p class="notes">identity = the pre scene scored as a method (nothing removed: every axis should be '
            "low); reference = the reference scored as a method (the true removal: every axis should be high).</p>"
            + _scroll("".join(t)) + "</details>")


def expectations_html(results: dict) -> str:
    """Known failure modes (``scenes.S.expected``): per method the axes that should catch its failure
    and whether they did (axis below :data:`LOW_AXIS`); empty without expectations."""
    checks = findings.expectation_checks(results)
    if not checks:
        return ""
    n_ok = sum(c.outcome in ("caught", "passes") for c in checks)
    h = ["<h3>Known failure modes: caught?</h3>",
         f'<p class="notes">These scenes state each method\'s simulated failure and the axes that should catch it '
         f"(scene.toml [expected.METHOD]). An axis catches a failure when it falls below {LOW_AXIS:g}; a method "
         f"without a failure passes when every axis stays at or above it. {n_ok} of {len(checks)} as expected.</p>",
         '<table><thead><tr><th class="lab">Scene</th><th class="lab">Method</th><th class="lab">Known failure</th>'
         '<th class="lab">Should be caught by</th><th class="lab">Result</th></tr></thead><tbody>']
    for c in checks:
        if c.caught_by:
            detail = ", ".join(f"{a} {fmt_number(v, 3)} {'caught' if ok else 'missed' if ok is not None else 'n/a'}"
                               for a, v, ok in c.checks)
        else:
            a, v, ok = c.checks[0]
            detail = f"lowest axis {a} {fmt_number(v, 3)}"
        cls = {"caught": "caught", "passes": "caught", "missed": "missed", "false alarm": "missed",
               "partly": "partly"}.get(c.outcome, "")
        h.append(f'<tr><td class="lab">{_e(c.scene)}</td><td class="lab">{_e(c.method)}</td>'
                 f'<td class="lab wrap">{_e(c.failure)}</td>'
                 f'<td class="lab">{_e(", ".join(c.caught_by) or "nothing (no failure)")}</td>'
                 f'<td class="lab wrap {cls}"><strong>{_e(c.outcome)}</strong>: {_e(detail)}</td></tr>')
    h.append("</tbody></table>")
    return h[0] + h[1] + _scroll("\n".join(h[2:]))


# -- per scene ---------------------------------------------------------------------------

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
         'semantic probe no longer finds the object, IoU_post &lt; 0.3; t_depth is the GHT threshold; '
         + ('no depth: pixels of the target with no depth after removal, a see-through hole that acc_depth counts '
            'as unchanged; ' if any(c[0] == "no_depth" for c in cols) else '')
         + 'mean = mean of s_sem, acc_depth, s_str)</caption><thead><tr><th class="lab">Method</th><th class="lab">View</th>'
         + "".join(f'<th class="num">{_e(label.get(k, name))}</th>' for k, name, _ in cols)
         + "</tr></thead><tbody>"]
    for r in rows:
        anchor = _pic_id(results, scene, r["method"], r["view"])
        cells = []
        for k, _, dec in cols:
            v = r.get(k)
            text = fmt_number(v, dec) if v is None or math.isfinite(v) else ("inf" if v > 0 else "-inf")
            data = "" if v is None else (repr(float(v)) if math.isfinite(v) else ("1e308" if v > 0 else "-1e308"))
            cells.append(f'<td class="num" data-v="{data}">{_e(text)}</td>')
        # The view name links to its contact sheet (no column of its own: the table fits 800 px).
        view = f'<a href="#{anchor}" title="contact sheet">{_e(r["view"])}</a>' if r.get("picture") else _e(r["view"])
        ex = " (excluded)" if r.get("excluded") else ""
        h.append(f'<tr id="row-{anchor}"><td class="lab">{_e(r["method"])}</td>'
                 f'<td class="lab">{view}{ex}</td>{"".join(cells)}</tr>')
    h.append("</tbody></table>")
    return _scroll("\n".join(h))


def _method_section(results: dict, out_dir: Path, scene: str, method: str, problems: list[str],
                    max_views: int | None, embed_cache: Path | None = None) -> str:
    entry = method_entry(results, scene, method) or {}
    axes = entry.get("axes") or {}
    rqs = number(axes.get("rqs"))
    h = [f'<details class="method" open><summary>{_e(method)} &mdash; RQS {_e(fmt_number(rqs, 3))}</summary>']
    mode = structural_mode(results, scene)
    lows = [f"{a} = {number(axes.get(a)):.3f} -- {_low_axis_message(a, mode)}" for a in AXES
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
        t = ['<table><thead><tr><th class="lab">Probe</th><th class="lab">Axis</th><th class="lab">Readings</th>'
             '<th class="num">Views scored</th></tr></thead><tbody>']
        for p, kind, vals, n in readings:
            t.append(f'<tr><td class="lab">{_e(p)}</td><td class="lab">{_e(kind)}</td>'
                     f'<td class="lab wrap">{_e(vals)}</td><td class="num">{_e(n)}</td></tr>')
        t.append("</tbody></table>")
        h.append(_scroll("".join(t)))
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
        h.append(f"<details><summary>Per-view contact sheets ({_e(count)})</summary>")
        if len(shown) < len(pics):
            h.append(f'<p class="notes">Evenly spaced along the camera path; every view\'s picture is in the '
                     f'{_e(os.path.dirname(str(next(iter(pics.values())))) or ".")} folder.</p>')
        h.append('<div class="grid">')
        by_view = {str(r.get("view")): r for r in entry.get("views") or []}
        for view, (uri, why) in zip(shown, _embed_many(out_dir, [pics[v] for v in shown], embed_cache)):
            cap = f"{view}: {_view_caption(by_view.get(str(view), {}))}"
            fid = _pic_id(results, scene, method, str(view))
            back = f' <a href="#row-{fid}">(row)</a>'
            if uri:
                # The embedded copy is shrunk for the page; the link opens the full-size PNG beside it.
                full = _e(urllib.parse.quote(str(pics[view]).replace(os.sep, "/")))
                img = f'<a href="{full}" title="full-size picture">{_img(uri, f"{scene} / {method} / {view}")}</a>'
                h.append(f'<figure id="{fid}">{img}<figcaption>{_e(cap)}{back} '
                         f'<a href="{full}">(full size)</a></figcaption></figure>')
            else:
                h.append(f'<figure id="{fid}"><div class="warn">{_e(why)}</div><figcaption>{_e(cap)}</figcaption>'
                         "</figure>")
                problems.append(f"{scene}/{method}/{view}: {why}")
        h.append("</div></details>")
    h.append("<details><summary>Axis record</summary>" + _kv_table(axes) + "</details>")
    h.append("</details>")
    return "\n".join(h)


def _probes_html(results: dict) -> str:
    """One block per probe: axis, name, models, weight-free, parameters and notes as a wrapping table."""
    probes = results.get("probes") or {}
    out = []
    for kind in ("semantic", "structural"):
        for p in probes.get(kind) or []:
            if not isinstance(p, dict):
                continue
            models = p.get("models") or {}
            info = {"axis": kind,
                    "models": ", ".join(f"{f} (sha256 {str(h)[:12]})" for f, h in models.items()) or "none",
                    "weight-free": "yes" if p.get("weight_free") else "no"}
            info.update({k: p[k] for k in ("limitations", "prompt_use", "fit", "varies_by_scene") if p.get(k)})
            info["parameters"] = p.get("params") or {}
            out.append(f"<h4>{_e(p.get('name', '?'))} ({_e(kind)})</h4>" + _kv_table(info))
    if not out:
        return "<p>No probe descriptions in the results.</p>"
    return "\n".join(out)


def _weight_free_note(results: dict) -> str:
    free = _weight_free_probes(results)
    if not free:
        return ""
    names = ", ".join(f"{p.get('name', '?')} ({p['kind']})" for p in free)
    items = "".join(f"<li><strong>{_e(p.get('name', '?'))}</strong> ({_e(p['kind'])}): {_e(p['limitations'])}</li>"
                    for p in free if p.get("limitations"))
    return (f'<div class="info"><strong>Note:</strong> weight-free built-in probes: {_e(names)}. They are '
            "weaker than the learned probes of the paper (GroundedSAM2 / SAM): compare methods under the same "
            "probes only, not with published numbers." + (f" Limitations:<ul>{items}</ul>" if items else "")
            + "</div>")


# -- the page ------------------------------------------------------------------

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
         "<title>r360gpu report</title>", f"<style>{_CSS}</style></head><body>"]
    meta = [f"r360gpu {results.get('r360gpu_version', '?')}"]
    if results.get("created"):
        meta.append(f"created {results['created']}")
    meta.append(f"{len(scenes)} scene(s), {len(methods)} method(s)")
    h.append("<header><h1>Remove360 evaluation report</h1>"
             f'<p class="meta">{_e(" | ".join(meta))}</p></header>')
    nav = ['<a href="#leaks">Leaks</a>', '<a href="#summary">Summary</a>', '<a href="#tables">Tables</a>']
    nav += [f'<a href="#scene-{i}">{_e(s)}</a>' for i, s in enumerate(scenes)]
    nav.append('<a href="#metadata">Run metadata</a>')
    h.append("<nav>" + "".join(nav) + "</nav>")

    # First screen: which method leaks, where
    h.append('<section id="leaks"><h2>Which method leaks, where</h2>')
    main = main_table(results, doubt_marks=False)  # marked below, with the reasons as tooltips
    flags, doubt_notes = _doubt_flags(results, main)
    h.append(table_html(main, flags=flags))
    for n in doubt_notes:
        h.append(f'<p class="notes">{_e(n)}</p>')
    tables, table_notes = build_results_tables(results)
    reliability = next((t for t in tables if t.key == "reliability"), None)
    if reliability is not None:  # how sure the ranking is, next to the ranking itself
        h.append('<h3>How sure is the ranking</h3>' + table_html(reliability))
    h.append(verdicts_html(results))
    h.append(worst_views_html(results, out, rows, problems))
    h.append(controls_html(results))
    h.append("</section>")

    # Summary
    h.append('<section id="summary"><h2>Summary</h2>')
    for line in low_axis_warnings(results):
        h.append(f'<div class="warn"><strong>Warning:</strong> {_e(line)}</div>')
    input_warnings = results.get("warnings") or []  # recorded by r360gpu.util.warning_log
    for w in input_warnings[:50]:
        h.append(f'<div class="warn"><strong>Input warning:</strong> {_e(format_record(w))}</div>')
    if len(input_warnings) > 50:
        h.append(f'<div class="warn">... and {len(input_warnings) - 50} more input warnings in results.json</div>')
    h.append(expectations_html(results))
    h.append(_weight_free_note(results))
    best = best_per_axis(results)
    if best:
        h.append('<h3>Best method per axis</h3><ul class="best">')
        for label, ms, v, dec in best:
            h.append(f"<li>{_e(label)}: <strong>{_e(', '.join(ms))}</strong> ({_e(fmt_number(v, dec))})</li>")
        h.append("</ul>")
    overall = {m: {k: overall_value(results, m, k) for k in ("s_sem", "s_geo", "s_str", "rqs")} for m in methods}
    if any(v is not None for d in overall.values() for v in d.values()):
        h.append(_img(_png_uri(axes_overview_png(overall, title="Overall axes per method", low=LOW_AXIS,
                                                 str_label=str_md)), "overall axes per method"))
    h.append("</section>")

    # Tables
    h.append('<section id="tables"><h2>Tables</h2>')
    for t in tables[1:]:
        if t is reliability:
            continue  # on the first screen
        h.append(f"<details open><summary>{_e(t.title)}</summary>{table_html(t, caption=False)}</details>")
    for n in table_notes:
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
        h.append(per_view_table_html(results, s, rows))
        for m in methods:
            if method_entry(results, s, m) is not None:
                h.append(_method_section(results, out, s, m, problems, max_views, embed_cache))
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
    h.append(f"</section><script>{_JS}</script></body></html>")
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
