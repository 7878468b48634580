"""The console summary (r360gpu.report.outputs.summary_lines): the known-failure check and the time line."""
from __future__ import annotations

from r360gpu.report.findings import expectation_checks
from r360gpu.report.outputs import expectation_lines, no_depth_lines, ranking_certainty_lines, summary_lines
from tests.report_fake import VIEWS, add_expected, fake_results, no_depth


def test_expectation_summary_on_the_console():
    results = add_expected(fake_results(pictures=False))
    checks = expectation_checks(results)
    lines = expectation_lines(results)
    n_ok = sum(c.outcome in ("caught", "passes") for c in checks)
    assert lines[0].endswith(f"{n_ok} of {len(checks)} as expected")
    missed = [c for c in checks if c.outcome not in ("caught", "passes")]
    assert missed, "the fake results should hold a method that is not as expected"
    assert len(lines) == 1 + len(missed)
    for c, line in zip(missed, lines[1:]):
        assert line.startswith(f"  {c.scene}/{c.method}: {c.outcome} (")
        for axis, value, _ in c.checks:
            assert f"{axis} {value:.3f}" in line
    assert "\n".join(lines) in "\n".join(summary_lines(results))
    assert expectation_lines(fake_results(pictures=False)) == []  # no [expected] tables: no lines


def test_time_line_says_wall_and_summed_over_threads():
    results = fake_results(pictures=False)
    results["timing"] = {"stages_s": {"render": 30.0, "probe": 70.0}, "total_s": 50.0, "views": 10}
    line = [x for x in summary_lines(results) if x.startswith("time:")][0]
    assert line == ("time: 50.0 s wall for 10 views, 0.20 views/s; per stage, summed over threads "
                    "(stages overlap): render 30.0 s, probe 70.0 s")


def test_see_through_holes_on_the_console():
    """Views with pixels of M that have no depth after removal: per (scene, method), how many views and
    pixels, and the view with the most; nothing for a method without any."""
    results = fake_results(pictures=False)
    lines = no_depth_lines(results)
    counts = [no_depth("room", "ghost", v) for v in VIEWS]
    holed = [v for v, n in zip(VIEWS, counts) if n]
    worst = max(holed, key=lambda v: no_depth("room", "ghost", v))
    assert lines == ["no depth after removal in the target (see-through holes; acc_depth counts them as unchanged):",
                     f"  room/ghost: {len(holed)} of {len(VIEWS)} views, {sum(counts)} px in all "
                     f"(most: {worst}, {no_depth('room', 'ghost', worst)} px)"]
    assert "\n".join(lines) in "\n".join(summary_lines(results))
    for scene in results["scenes"].values():
        for entry in scene["methods"].values():
            for rec in entry["views"]:
                rec["geometric"]["n_no_depth_in_mask"] = 0
    assert no_depth_lines(results) == []


def test_ranking_certainty_on_the_console():
    """Enough scenes: per method the mean RQS, its bootstrap interval and P(beats best), as report.html."""
    from tests.report_fake import add_ranked_reliability

    results = add_ranked_reliability(fake_results(pictures=False))
    agg = results["aggregate"]
    lines = ranking_certainty_lines(results)
    assert lines[0] == "how sure is the ranking (scene-macro mean RQS, paired scene bootstrap):"
    assert lines[1].split() == ["method", "mean", "95%", "CI", f"P(beats", f"{agg['reliability_best']})"]
    for m, line in zip(agg["reliability"], lines[2:]):
        r = agg["reliability"][m]
        p = "-" if r["p_beats_best"] is None else f"{r['p_beats_best']:.3f}"
        assert line.split() == [m, f"{r['mean']:.3f}", f"[{r['ci_low']:.3f},", f"{r['ci_high']:.3f}]", p]
    assert "\n".join(lines) in "\n".join(summary_lines(results))


def test_too_few_scenes_on_the_console():
    """The fake's two scenes: one plain sentence, no interval and no probability."""
    results = fake_results(pictures=False)
    assert ranking_certainty_lines(results) == [
        "how sure is the ranking: too few scenes to rank with confidence (2 scenes; at least 5 needed)"]
    text = "\n".join(summary_lines(results))
    assert "too few scenes to rank with confidence" in text and "P(beats" not in text


def _axes(sem, geo, stru, rqs):
    return {"s_sem": sem, "s_geo": geo, "s_str": stru, "rqs": rqs}


def test_orbit_axes_per_method_on_the_console():
    """--orbit: the poses scored and dropped, then each method's capture -> orbit axes, or why it has no
    orbit."""
    from r360gpu.report.orbit_table import orbit_lines

    doc = {"scenes": {"garden": {
        "methods": {"clean": {"axes": _axes(1.0, 0.9, 0.8, 0.9)}, "gc": {"axes": _axes(0.5, 0.4, 0.3, 0.4)}},
        "orbit": {"requested": 12, "kept": 9, "dropped": {"target occluded": 1, "inside geometry": 2},
                  "no_orbit": {"gc": "no orbit (renderings only)"},
                  "methods": {"clean": {"axes": _axes(0.75, 0.5, None, 0.25)}}}}}}
    assert orbit_lines(doc) == [
        "orbit around the target (capture -> orbit; a separate scene entry, never ranked):",
        "  garden: 9 of 12 poses scored (dropped: inside geometry 2, target occluded 1)",
        "  garden / clean: s_sem 1.000 -> 0.750  s_geo 0.900 -> 0.500  s_str 0.800 -> —  RQS 0.900 -> 0.250",
        "  garden / gc: no orbit (renderings only)"]
    assert "\n".join(orbit_lines(doc)) in "\n".join(summary_lines(doc))
    assert orbit_lines({"scenes": {"garden": {"methods": {}}}}) == []


def test_lifted_target_on_the_console():
    from r360gpu.report.outputs import target_lines

    doc = {"scenes": {"room": {"target": {"source": "masks", "gaussians": 1984, "of": 20000, "given": ["00", "03"],
                                          "rendered": ["01", "02", "04"], "lifted_from": ["00", "03"]}},
                      "hall": {"target": {"source": "box", "gaussians": 7, "of": 90, "given": [],
                                          "rendered": ["00"], "lifted_from": []}},
                      "plain": {}}}
    assert target_lines(doc) == [
        "room: [target] lifted onto 1984 of 20000 Gaussians of pre (from the masks of views 00, 03); "
        "masks rendered for 3 of 5 views",
        "hall: [target] lifted onto 7 of 90 Gaussians of pre (from its box); masks rendered for 1 of 1 views"]
    assert "\n".join(target_lines(doc)) in "\n".join(summary_lines(doc))


def test_pruned_what_if_says_why_fewer_than_asked():
    from r360gpu.pipeline.residuals import why_fewer
    from r360gpu.report.pruned_table import pruned_lines, pruned_table

    assert why_fewer(100, 5000, 4000) is None  # all removed
    assert why_fewer(2000, 5000, 1037).startswith("only 1037 Gaussians have a residual above 0")
    assert why_fewer(2000, 1500, 1500) == "the method has only 1500 Gaussians"
    assert why_fewer(2000, 1500, 1037).startswith("only 1037 Gaussians")  # the tighter limit is the reason
    fewer = why_fewer(2000, 5000, 1037)
    doc = {"scenes": {"room": {
        "methods": {"floaters": {"axes": _axes(0.4, 0.25, 0.125, 0.2)}},
        "pruned": {"floaters+pruned": {"method": "floaters", "removed": 1037, "of": 5000, "asked": 2000,
                                       "fewer": fewer, "axes": _axes(1.0, 0.5, 0.5, 0.625)}}}}}
    assert pruned_lines(doc) == [
        "pruned residuals (what-if, never ranked):",
        f"  room / floaters+pruned (1037 of 5000 Gaussians removed; 2000 asked: {fewer}): s_sem 0.400 -> 1.000  "
        "s_geo 0.250 -> 0.500  s_str 0.125 -> 0.500  RQS 0.200 -> 0.625"]
    assert f"room / floaters+pruned: 1037 of 2000 asked removed: {fewer}." in pruned_table(doc).notes
