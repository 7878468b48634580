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
