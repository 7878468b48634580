"""Everything ``r360gpu score`` writes to its output folder, in one call."""
from __future__ import annotations

from pathlib import Path

from ..protocol import AXES
from ..util.atomic import write_bytes
from .html import write_html
from .plots import view_axes_png
from .results_io import write_results
from .results_tables import write_tables


def method_plots(scene: str, records: dict) -> dict[str, bytes]:
    """PNG bytes of the per-view axes plot of each method of ``scene``; records: {method: [ViewRecord]}."""
    return {method: view_axes_png(recs, title=f"{scene} / {method}: per-view axes") for method, recs in records.items()}


def scene_records(scene_entry: dict) -> dict:
    """{method: [ViewRecord]} of a scene's results entry (what :func:`method_plots` draws)."""
    from ..metrics.record import ViewRecord

    return {method: [ViewRecord.from_dict(v) for v in m["views"]] for method, m in scene_entry["methods"].items()}


def write_outputs(results: dict, out, *, embed_cache=None, plots: dict | None = None) -> dict[str, Path]:
    """Write per-method plots, results.json, results.csv, tables.md/.tex and report.html.

    The plot paths are recorded in ``results`` (relative to ``out``) before
    results.json is written.  embed_cache: see :func:`.html.report_html`.
    plots: {scene: {method: PNG bytes}} drawn already (:func:`method_plots`, as
    the pipeline draws each scene's while the next one is scored); the others
    are drawn here.  Returns {"json", "csv", "md", "tex", "html": path}.
    """
    out = Path(out)
    for scene, s in results["scenes"].items():
        drawn = (plots or {}).get(scene) or {}
        if set(drawn) != set(s["methods"]):
            drawn = method_plots(scene, scene_records(s))
        for method, m in s["methods"].items():
            rel = Path("plots") / scene / f"{method}.png"
            write_bytes(out / rel, drawn[method])
            m["plot"] = rel.as_posix()
    js, csv = write_results(results, out)
    md, tex = write_tables(results, out)
    html = write_html(results, out, embed_cache=embed_cache)
    return {"json": js, "csv": csv, "md": md, "tex": tex, "html": html}


# The documents of one run: written all together or not at all (see util.atomic.all_or_nothing).
OUTPUT_DOCUMENTS = ("results.json", "results.csv", "tables.md", "tables.tex", "report.html")


def write_run_outputs(results: dict, out, *, embed_cache=None, plots: dict | None = None) -> dict[str, Path]:
    """:func:`write_outputs`, the documents replaced all together or not at all; a write
    error (disk full, read-only) is an InputError naming the file, with nothing changed."""
    from ..errors import InputError
    from ..util.atomic import all_or_nothing
    from ..util.outdir import os_error_reason

    out = Path(out)
    try:
        with all_or_nothing([out / name for name in OUTPUT_DOCUMENTS]):
            return write_outputs(results, out, embed_cache=embed_cache, plots=plots)
    except OSError as e:
        raise InputError(f"cannot write the results ({os_error_reason(e)}): none of {', '.join(OUTPUT_DOCUMENTS)} "
                         f"was changed; per-view results are cached, rerun to finish", e.filename or out) from None


def summary_lines(results: dict) -> list[str]:
    """A short plain-text summary for the terminal: overall axes, RQS and AvgRank per method."""
    agg = results.get("aggregate") or {}
    overall = agg.get("overall") or {}
    ranks = agg.get("ranks") or {}
    lines = []
    if overall:
        pooling = agg.get("overall_pooling", "")
        lines.append(f"overall ({pooling}):")
        lines.append(f"  {'method':<18}{'s_sem':>8}{'s_geo':>8}{'s_str':>8}{'RQS':>8}{'AvgRank':>9}")
        flagged = {a for a, scenes in (results.get("validity") or {}).items() if scenes}
        for m, ax in overall.items():
            def f(x, axis=None):
                mark = "!" if axis in flagged else " "
                return f"{x:7.3f}{mark}" if isinstance(x, (int, float)) else f"{'-':>7}{mark}"
            r = ranks.get(m, {}).get("avg_rank")
            lines.append(f"  {m:<18}{f(ax.get('s_sem'), 's_sem')}{f(ax.get('s_geo'), 's_geo')}"
                         f"{f(ax.get('s_str'), 's_str')}{f(ax.get('rqs'))}"
                         f"{(f'{r:9.2f}' if r is not None else f'{chr(45):>9}')}")
        if flagged:
            where = "; ".join(f"{a} in {', '.join(s)}" for a, s in results["validity"].items() if s)
            lines.append(f"  ! axis not 'ok' (weak or blind probe) in some scene: {where}")
    lines += ranking_certainty_lines(results)
    lines += control_lines(results)
    from .orbit_table import orbit_lines
    from .pruned_table import pruned_lines

    lines += target_lines(results)
    lines += orbit_lines(results)  # score --orbit N: each method from all around the target, never ranked
    lines += pruned_lines(results)  # score --prune-residuals: the unranked what-ifs beside their methods
    lines += expectation_lines(results)
    lines += no_depth_lines(results)
    t = results.get("timing") or {}
    if t:
        stages = ", ".join(f"{k} {v:.1f} s" for k, v in t.get("stages_s", {}).items())
        views = t.get("views", 0)
        total = t.get("total_s", 0.0) or 0.0
        rate = f", {views / total:.2f} views/s" if total > 0 and views else ""
        # The stage totals come from r360gpu.pipeline.run's timer: summed over the threads
        # that ran each stage, so together they can exceed the wall time.
        lines.append(f"time: {total:.1f} s wall for {views} views{rate}; "
                     f"per stage, summed over threads (stages overlap): {stages}")
    for note in results.get("notes", []):
        lines.append(f"note: {note}")
    return lines


def target_lines(results: dict) -> list[str]:
    """Per scene with a lifted ``[target]``: how many of pre's Gaussians it is and what it came from
    (its masks' views, its indices or its box), and for how many views its masks were rendered."""
    lines = []
    for scene, s in results.get("scenes", {}).items():
        t = s.get("target")
        if not t:
            continue
        of = f" of {t['of']}" if t.get("of") is not None else ""
        source = {"indices": "its indices", "box": "its box"}.get(t.get("source"), "its masks")
        if t.get("lifted_from") and t.get("source") == "masks":
            source = f"the masks of views {', '.join(t['lifted_from'])}"
        n_rendered = len(t.get("rendered") or [])
        n_views = n_rendered + len(t.get("given") or [])
        lines.append(f"{scene}: [target] lifted onto {t.get('gaussians')}{of} Gaussians of pre (from {source}); "
                     f"masks rendered for {n_rendered} of {n_views} views")
    return lines


def ranking_certainty_lines(results: dict) -> list[str]:
    """How sure the ranking is, as report.html's first screen says it: per method the mean RQS over
    scenes, its bootstrap interval and P(beats best); with too few scenes, the sentence saying so."""
    agg = results.get("aggregate") or {}
    rel = agg.get("reliability")
    if not rel:
        why = (agg.get("notes") or {}).get("reliability")
        return [f"how sure is the ranking: {why}"] if why else []
    best = agg.get("reliability_best", "best")
    level = (agg.get("settings") or {}).get("ci_level")
    ci = f"{level:.0%} CI" if isinstance(level, (int, float)) else "CI"
    lines = ["how sure is the ranking (scene-macro mean RQS, paired scene bootstrap):",
             f"  {'method':<18}{'mean':>8}  {ci:<18}P(beats {best})"]

    def f(x):
        return f"{x:.3f}" if isinstance(x, (int, float)) else "-"

    for m, r in rel.items():
        interval = f"[{f(r.get('ci_low'))}, {f(r.get('ci_high'))}]"
        lines.append(f"  {m:<18}{f(r.get('mean')):>8}  {interval:<18}{f(r.get('p_beats_best'))}")
    return lines


def no_depth_lines(results: dict) -> list[str]:
    """The views with pixels of M that have no depth after removal (``n_no_depth_in_mask`` > 0: a
    see-through hole, which acc_depth counts as unchanged), per (scene, method): how many views,
    how many pixels, and the view with the most.  Nothing when no view has such a pixel."""
    from .findings import view_rows

    by: dict = {}
    for row in view_rows(results):
        by.setdefault((row["scene"], row["method"]), []).append(row)
    holed = {k: [r for r in rows if r.get("no_depth")] for k, rows in by.items()}
    if not any(holed.values()):
        return []
    lines = ["no depth after removal in the target (see-through holes; acc_depth counts them as unchanged):"]
    for (scene, method), rows in holed.items():
        if not rows:
            continue
        n_views = len(by[scene, method])
        worst = max(rows, key=lambda r: r["no_depth"])
        lines.append(f"  {scene}/{method}: {len(rows)} of {n_views} views, {sum(int(r['no_depth']) for r in rows)} px "
                     f"in all (most: {worst['view']}, {int(worst['no_depth'])} px)")
    return lines


def expectation_lines(results: dict) -> list[str]:
    """The known-failure check of bundles with ``[expected.METHOD]`` tables (as in the HTML
    report): how many methods came out as expected, and one line per method that did not."""
    from .findings import LOW_AXIS, expectation_checks

    checks = expectation_checks(results)
    if not checks:
        return []
    n_ok = sum(c.outcome in ("caught", "passes") for c in checks)
    lines = [f"expected failures (scene.toml [expected.*]; caught = axis < {LOW_AXIS:g}): "
             f"{n_ok} of {len(checks)} as expected"]
    for c in checks:
        if c.outcome in ("caught", "passes"):
            continue
        detail = ", ".join(f"{a} {'-' if v is None else f'{v:.3f}'}" + ("" if caught is None else
                                                                        (" low" if caught else " not low"))
                           for a, v, caught in c.checks)
        should = ", ".join(c.caught_by) if c.caught_by else "no axis (no failure)"
        lines.append(f"  {c.scene}/{c.method}: {c.outcome} ({detail}; expected low: {should})")
    return lines


def control_lines(results: dict) -> list[str]:
    """Per scene: the controls' axes (never ranked) and every axis whose verdict is not "ok"."""
    lines = []
    for scene, s in results.get("scenes", {}).items():
        controls = s.get("controls") or {}
        validity = s.get("validity") or {}
        if not controls and not validity:
            continue
        verdicts = ", ".join(f"{a} {v}" for a, v in validity.items() if v is not None)
        lines.append(f"{scene}: validity {verdicts}" if verdicts else f"{scene}:")
        for c, entry in controls.items():
            ax = entry.get("axes") or {}
            vals = "  ".join(f"{a} {ax[a]:.3f}" if isinstance(ax.get(a), (int, float)) else f"{a} -"
                             for a in AXES)
            lines.append(f"  control {c:<10} {vals}")
        for note in (s.get("validity_notes") or {}).values():
            lines.append(f"  {note}")
    return lines
