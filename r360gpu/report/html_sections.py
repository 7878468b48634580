"""report.html's first screen and summary: leaks and their thumbnails, probe verdicts, controls,
expected failures, low-axis warnings, the best method per axis, the probe descriptions."""
from __future__ import annotations

import base64
import math
from pathlib import Path

from ..metrics.semantic import SemanticView, semantic_summary
from ..metrics.structural import StructuralView, structural_summary
from ..protocol import AXES, XI_DEFAULT
from . import findings
from .embed import JPEG_QUALITY
from .findings import LOW_AXIS
from .contact_sheets import sheet_panel, view_numbers
from .results_io import method_entry, method_names, number, scene_names, structural_mode
from .results_tables import (
    overall_value,
    scene_value,
    structural_header,
)
from .tables import Cell, Table, emphasis_marks, fmt_number, number_cells
from .html_blocks import THUMB_WIDTH, embed_picture, esc, img_tag, kv_table, pic_id, scroll_box

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


def doubt_flags(results: dict, table: Table) -> tuple[dict[int, str], list[str]]:
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


def low_axis_message(axis: str, mode: str) -> str:
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
                out.append(f"{m}: {axis} = {v:.3f} < {threshold:g} -- {low_axis_message(axis, mode)}.")
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
                f"acc_seg({XI_DEFAULT:g}) {fmt_number(s.s_sem, 3)}")
        out.append((p, "semantic", vals, f"{s.n_scored}/{s.n_views}"))
    for p, views in struct.items():
        s = structural_summary(views, include_empty_targets=include)
        label = "sim_SAM(I_post, I_ref)" if s.mode == "reference" else "sim_SAM(I_pre, I_post)"
        out.append((p, "structural", f"{label} {fmt_number(s.sim_sam, 3)}, s_str {fmt_number(s.s_str, 3)}",
                    f"{s.n_scored}/{s.n_views}"))
    return out


def _thumbnail(out_dir: Path, row: dict, problems: list[str]) -> str | None:
    """Data URI of the I_post panel of a view's contact sheet (whole sheet when the panel cannot be
    cut out), JPEG at most :data:`THUMB_WIDTH` * 2 px wide; None when the sheet is not embeddable."""
    import cv2
    import numpy as np

    rel = row.get("picture")
    if not rel:
        return None
    uri, why = embed_picture(out_dir, rel)
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
         f"is below {findings.LOW_AXIS:g} (s_sem 0/1 at xi = {XI_DEFAULT:g}, acc_depth, s_str), the one with the lowest "
         "mean of those axes; I_post with the target outlined in green. Click for the contact sheet.</p>",
         '<div class="thumbs">']
    clean = [m for m in method_names(results) if m in scored and m not in worst]
    for m in method_names(results):
        row = worst.get(m)
        if row is None:
            continue
        anchor = pic_id(results, row["scene"], m, row["view"])
        uri = _thumbnail(out_dir, row, problems)
        img = img_tag(uri, f"worst view of {m}: {row['scene']} / {row['view']}") if uri else ""
        cap = (f"<b>{esc(m)}</b>{esc(row['scene'])} / {esc(row['view'])}: {esc(_row_summary(row))} "
               f"(mean {row['leak']:.2f})")
        h.append(f'<figure><a href="#{anchor}">{img}<figcaption>{cap}</figcaption></a></figure>')
    h.append("</div>")
    if clean:
        h.append(f'<p class="notes">No view leaks (every axis at or above {findings.LOW_AXIS:g} in every view): '
                 + ", ".join(f"<b>{esc(m)}</b>" for m in clean) + ".</p>")
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
            cells.append(f'<td class="lab {cls}">{esc(text)}</td>')
        t.append(f'<tr><td class="lab">{esc(s)}</td>{"".join(cells)}</tr>')
    t.append("</tbody></table>")
    h.append(scroll_box("".join(t)))
    sentences = [v for v in verdicts if v.sentence]
    if sentences:
        h.append('<ul class="notes">' + "".join(f"<li><strong>{esc(v.scene)}:</strong> {esc(v.sentence)}</li>"
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
        t.append(f'<tr><td class="lab">{esc(s)}</td><td class="lab">{esc(name)}</td>'
                 + "".join(f'<td class="num">{esc(fmt_number(number(axes.get(k)), 3))}</td>' for k in keys) + "</tr>")
    t.append("</tbody></table>")
    return ("<details><summary>Controls behind the probe checks</summary>"
            '<p class="notes">identity = the pre scene scored as a method (nothing removed: every axis should be '
            "low); reference = the reference scored as a method (the true removal: every axis should be high).</p>"
            + scroll_box("".join(t)) + "</details>")


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
        h.append(f'<tr><td class="lab">{esc(c.scene)}</td><td class="lab">{esc(c.method)}</td>'
                 f'<td class="lab wrap">{esc(c.failure)}</td>'
                 f'<td class="lab">{esc(", ".join(c.caught_by) or "nothing (no failure)")}</td>'
                 f'<td class="lab wrap {cls}"><strong>{esc(c.outcome)}</strong>: {esc(detail)}</td></tr>')
    h.append("</tbody></table>")
    return h[0] + h[1] + scroll_box("\n".join(h[2:]))


def probes_html(results: dict) -> str:
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
            out.append(f"<h4>{esc(p.get('name', '?'))} ({esc(kind)})</h4>" + kv_table(info))
    if not out:
        return "<p>No probe descriptions in the results.</p>"
    return "\n".join(out)


def weight_free_note(results: dict) -> str:
    free = _weight_free_probes(results)
    if not free:
        return ""
    names = ", ".join(f"{p.get('name', '?')} ({p['kind']})" for p in free)
    items = "".join(f"<li><strong>{esc(p.get('name', '?'))}</strong> ({esc(p['kind'])}): {esc(p['limitations'])}</li>"
                    for p in free if p.get("limitations"))
    return (f'<div class="info"><strong>Note:</strong> weight-free built-in probes: {esc(names)}. They are '
            "weaker than the learned probes of the paper (GroundedSAM2 / SAM): compare methods under the same "
            "probes only, not with published numbers." + (f" Limitations:<ul>{items}</ul>" if items else "")
            + "</div>")
