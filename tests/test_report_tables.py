"""Markdown / LaTeX rendering of the aggregate tables."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.aggregate import AxisCells, aggregate_tables, read_axes_csv
from r360gpu.report.tables import Cell, Table, build_tables, render_latex, render_markdown, render_tables

from remove360_paper import AXES_CSV


@pytest.fixture(scope="module")
def paper_result():
    return aggregate_tables(read_axes_csv(AXES_CSV), n_boot=2000, n_perm=200)


def test_table_model_renders_in_both_formats():
    t = Table(key="demo", title="Demo 50% & more", header=[Cell("Name"), Cell("x_1", r"$x_1$")],
              rows=[[Cell("a|b"), Cell("0.5", emphasis="best")], [Cell("c_d"), Cell("0.4", emphasis="second")]],
              rule_before=frozenset({1}), notes=("a note",))
    md = render_markdown(t)
    assert md.splitlines()[0] == "**Demo 50% & more**"
    assert "| Name | x_1 |" in md and "|:---|---:|" in md
    assert r"| a\|b | **0.5** |" in md and "| c_d | _0.4_ |" in md
    assert "|  |  |" in md  # the rule before row 1
    assert md.rstrip().endswith("a note")
    tex = render_latex(t)
    assert r"\caption{Demo 50\% \& more a note}" in tex and r"\label{tab:r360_demo}" in tex
    assert r"Name & $x_1$ \\" in tex
    assert r"a|b & \textbf{0.5} \\" in tex and r"c\_d & \underline{0.4} \\" in tex
    lines = tex.splitlines()
    assert lines[lines.index(r"c\_d & \underline{0.4} \\") - 1] == r"\midrule"
    assert r"\begin{tabular}{lc}" in tex and tex.count(r"\toprule") == 1


def test_latex_text_keeps_double_hyphens_and_angle_brackets():
    """An option named in a note (--lpips-model) must not become an en dash, nor "<=" an inverted mark."""
    t = Table(key="k", title="t", header=[Cell("a")], rows=[[Cell("x <= 1 --- y > 2")]],
              notes=("LPIPS: not computed (--lpips-model)",))
    tex = render_latex(t)
    assert r"(-{}-lpips-model)" in tex and "(--lpips" not in tex
    assert r"x \textless{}= 1 -{}-{}- y \textgreater{} 2" in tex


def test_paper_tables_all_present_with_paper_emphasis(paper_result):
    tables, notes = build_tables(paper_result)
    assert [t.key for t in tables] == ["rqs_per_scene", "overall", "scene_macro", "rank_agg", "reliability",
                                       "axis_association"]
    assert notes == []
    rqs = tables[0]
    stroller = next(r for r in rqs.rows if r[0].text == "Stroller")
    # tab:supp_rqs: GC best (0.911), AF+i second (0.883) on Stroller
    assert [(c.text, c.emphasis) for c in stroller[1:]] == [
        ("0.911", "best"), ("0.807", ""), ("0.883", "second"), ("0.867", ""), ("0.871", ""), ("0.718", "")]
    assert rqs.rows[-1][0].text == "Overall (scene-macro)"
    rel = tables[4]
    # the bootstrap percentile interval of 2,000 resamples, seed 0 (the paper prints the normal
    # approximation [0.561, 0.768]; tests/test_aggregate_reliability.py checks both readings)
    assert [c.text for c in rel.rows[0][:5]] == ["GC", "0.664", "0.175", "0.371-0.911", "[0.568, 0.759]"]
    assert rel.rows[4][5].text == "--"  # the best method has no P(beats best)


def test_emphasis_ties_share_best_at_printed_precision():
    cells = AxisCells(("x",), ("A", "B", "C"), np.array([[1.0, 0.99999, 0.5]]), np.full((1, 3), 0.5),
                      np.full((1, 3), 0.5))
    tables, _ = build_tables(aggregate_tables(cells))
    overall = next(t for t in tables if t.key == "overall")
    sem = [row[1] for row in overall.rows]
    assert [(c.text, c.emphasis) for c in sem] == [("1.000", "best"), ("1.000", "best"), ("0.500", "")]


def test_second_best_never_marks_the_worst():
    from r360gpu.report.tables import emphasis_marks

    # garden acc_seg of the demo: four methods at 1.000, one at 0.000 -> nothing underlined
    assert emphasis_marks([1.0, 0.0, 1.0, 1.0, 1.0], 3, True) == ["best", "", "best", "best", "best"]
    # a single best: the next distinct value is second, unless it is also the worst
    assert emphasis_marks([0.9, 0.5, 0.7, 0.7], 3, True) == ["best", "", "second", "second"]
    assert emphasis_marks([0.9, 0.5], 3, True) == ["best", ""]
    assert emphasis_marks([0.2, 0.3, 0.4], 3, False) == ["best", "second", ""]
    assert emphasis_marks([0.9, None, 0.8, 0.1], 3, True) == ["best", "", "second", ""]


def test_render_tables_md_and_latex(paper_result):
    md = render_tables(paper_result, "md")
    for title in ("Per-scene Removal Quality Score", "Overall evaluation", "Scene-macro means",
                  "Rank aggregation", "Reliability", "Association between the three axes"):
        assert title in md
    assert "| Deckchair | 0.697 | 0.689 | **0.779** | 0.739 | _0.745_ | 0.468 |" in md
    assert "-0.07 +/- 0.45" in md
    tex = render_tables(paper_result, "latex")
    assert tex.count(r"\begin{table}") == 6
    assert r"Deckchair & 0.697 & 0.689 & \textbf{0.779} & 0.739 & \underline{0.745} & 0.468 \\" in tex
    assert r"$-0.07 \pm 0.45$" in tex
    assert r"0.371--0.911" in tex
    with pytest.raises(ValueError):
        render_tables(paper_result, "html")


def test_render_tables_notes_for_omitted_tables():
    cells = AxisCells(("only",), ("A", "B"), np.array([[0.2, 0.4]]), np.array([[0.5, 0.5]]),
                      np.array([[0.9, 0.1]]))
    result = aggregate_tables(cells)
    md = render_tables(result, "md")
    assert "Reliability" not in md
    assert "Note: too few scenes to rank with confidence (1 scene; at least 5 needed)" in md
    tex = render_tables(result, "latex")
    assert "% Note: axis association omitted" in tex and tex.count(r"\begin{table}") == 4
