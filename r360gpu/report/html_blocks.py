"""The pieces report.html is built from: escaping, tables, embedded pictures, the page's CSS and script."""
from __future__ import annotations

import base64
import html
import json
import math
import os
from pathlib import Path

from .embed import sheet_jpeg
from .results_io import method_names, number, scene_names
from .tables import Cell, Table


#: Width (px) of the worst-view thumbnails on the first screen.
THUMB_WIDTH = 220


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


CSS = """
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
JS = """
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


def esc(text) -> str:
    return html.escape(str(text), quote=True)


def scroll_box(inner: str) -> str:
    """A box that scrolls sideways by itself when ``inner`` is wider than the page."""
    return f'<div class="scroll">{inner}</div>'


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
        body = esc(c.text)
        if c.emphasis == "best" and body:
            body = f"<strong>{body}</strong>"
        elif c.emphasis == "second" and body:
            body = f"<u>{body}</u>"
        title = ""
        if tag == "td" and j in flags:
            cls.append("doubt")
            body += '<sup class="doubt">&dagger;</sup>'
            title = f' title="{esc(flags[j])}"'
        return f'<{tag} class="{" ".join(cls)}"{title}>{body}</{tag}>'

    out = [f"<table><caption>{esc(table.title)}</caption>" if caption else "<table>",
           "<thead><tr>" + "".join(cell(c, j, "th") for j, c in enumerate(table.header)) + "</tr></thead><tbody>"]
    for i, row in enumerate(table.rows):
        cls = ' class="rule"' if i in table.rule_before else ""
        out.append(f"<tr{cls}>" + "".join(cell(c, j, "td") for j, c in enumerate(row)) + "</tr>")
    out.append("</tbody></table>")
    text = scroll_box("\n".join(out))
    if table.notes:
        text += '\n<p class="notes">' + "<br>\n".join(esc(n) for n in table.notes) + "</p>"
    return text


def png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def jpeg_uri(png: bytes, embed_cache: Path | None = None) -> str | None:
    jpeg = sheet_jpeg(png, embed_cache)
    return None if jpeg is None else "data:image/jpeg;base64," + base64.b64encode(jpeg).decode("ascii")


def embed_many(out_dir: Path, rels: list, embed_cache: Path | None = None) -> list[tuple[str | None, str | None]]:
    """:func:`embed_picture` of many contact sheets as photos, in threads (OpenCV's decode, resize
    and encode release the GIL, and a run has one sheet per method and view)."""
    from concurrent.futures import ThreadPoolExecutor

    def one(r):
        return embed_picture(out_dir, r, photo=True, embed_cache=embed_cache)

    if len(rels) < 2:
        return [one(r) for r in rels]
    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1), thread_name_prefix="r360-embed") as pool:
        return list(pool.map(one, rels))


def embed_picture(out_dir: Path, rel, *, photo: bool = False, embed_cache: Path | None = None
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
    if not data.startswith(PNG_SIGNATURE):
        return None, f"picture {rel!r} is not a PNG; not embedded"
    if photo:
        uri = jpeg_uri(data, embed_cache)
        if uri is None:
            return None, f"picture {rel!r} could not be decoded; not embedded"
        return uri, None
    return png_uri(data), None


def img_tag(uri: str, alt: str, width: int | None = None) -> str:
    w = f' width="{int(width)}"' if width else ""
    return f'<img src="{uri}" alt="{esc(alt)}"{w}>'


def pic_id(results: dict, scene: str, method: str, view: str) -> str:
    """Anchor of one contact sheet (indices, so any scene / method / view name is a valid id)."""
    si = scene_names(results).index(scene)
    mi = method_names(results).index(method)
    vi = list(((results.get("scenes") or {}).get(scene) or {}).get("views") or []).index(view) \
        if view in (((results.get("scenes") or {}).get(scene) or {}).get("views") or []) else view
    return f"pic-{si}-{mi}-{vi}"


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
            text = esc(", ".join(f"{kk}: {_value_text(vv)}" for kk, vv in v.items()))
        elif isinstance(v, dict) and v and depth < 3:
            text = kv_html(v, depth + 1)
        else:
            text = esc(_value_text(v) if not isinstance(v, dict) else json.dumps(v, ensure_ascii=False))
        rows.append(f'<tr><td class="lab">{esc(k)}</td><td class="lab">{text}</td></tr>')
    return '<table class="kv"><tbody>' + "".join(rows) + "</tbody></table>"


def kv_table(d: dict) -> str:
    return scroll_box(kv_html(d))
