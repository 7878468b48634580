"""Tables of a results document: the paper's layouts, numbers and emphasis."""
from __future__ import annotations

import copy

import pytest

from r360gpu.report.results_tables import (
    axis_table,
    boundary_table,
    build_results_tables,
    iou_table,
    main_table,
    pooled_fidelity,
    structural_header,
    write_tables,
    xi_table,
)
from r360gpu.report.tables import Cell, Table, render_latex, render_markdown

from report_fake import fake_results


@pytest.fixture(scope="module")
def results():
    return fake_results()


def _row(table, label):
    return next(r for r in table.rows if r[0].text == label)


def _shown(cells):
    return [(c.text, c.emphasis) for c in cells]


def test_main_table_numbers_and_emphasis(results):
    t = main_table(results)
    assert [c.text for c in t.header] == ["Method", "IoU_drop", "acc_seg", "acc_depth", "sim_SAM", "RQS",
                                          "AvgRank (lower is better)", "PSNR", "SSIM", "LPIPS (lower is better)"]
    # clean: every view undetected (IoU_post 0.05) -> acc_seg 1; acc_depth mean of
    # (0.9, 0.85, 0.8) and (0.9, 0.85) pooled view-weighted = 0.8625, printed 0.862 (binary 0.86249...)
    assert _shown(_row(t, "clean")[1:]) == [
        ("0.815", "best"), ("1.000", "best"), ("0.862", "best"), ("0.800", "best"), ("0.884", "best"),
        ("1.17", "best"), ("26.00", "best"), ("0.800", "best"), ("0.200", "best")]
    # blurry: acc_seg (1/3 + 1/2) / 2 = 0.417, not underlined: clean and ghost share first place, so
    # 0.417 ranks third (and is the worst); LPIPS 0.4 is the worst (lower is better)
    assert _shown(_row(t, "blurry")[1:]) == [
        ("0.590", ""), ("0.417", ""), ("0.825", "second"), ("0.500", ""), ("0.556", "second"),
        ("2.67", ""), ("20.00", ""), ("0.600", ""), ("0.400", "")]
    # ghost ties clean on acc_seg (shares the bold), is second on LPIPS 0.3
    assert _shown(_row(t, "ghost")[1:3]) == [("0.765", "second"), ("1.000", "best")]
    assert _row(t, "ghost")[-1].emphasis == "second"
    assert t.vrule_before == frozenset({7})
    md = render_markdown(t)
    assert "| clean | **0.815** | **1.000** | **0.862** | **0.800** | **0.884** | **1.17** | **26.00** |" in md
    tex = render_latex(t)
    assert r"\begin{tabular}{lcccccc|ccc}" in tex
    assert r"blurry & 0.590 & 0.417 & \underline{0.825}" in tex


def test_main_table_without_references_drops_fidelity(results):
    r = copy.deepcopy(results)
    for s in r["scenes"].values():
        s["reference"] = False
        for e in s["methods"].values():
            for v in e["views"]:
                v["fidelity"] = None
                for sv in v["structural"].values():
                    sv["mode"] = "reference_free"
    t = main_table(r)
    assert [c.text for c in t.header][-2:] == ["RQS", "AvgRank (lower is better)"]
    assert t.header[4].text == "1 - sim_SAM" and t.vrule_before == frozenset()
    assert pooled_fidelity(r, "clean") == {"psnr": None, "ssim": None, "lpips": None, "n_views": 0}
    assert "axis_psnr" not in [x.key for x in build_results_tables(r)[0]]


def test_structural_header_by_mode(results):
    assert structural_header(results)[0] == "sim_SAM"
    r = copy.deepcopy(results)
    for v in r["scenes"]["garden"]["methods"]["clean"]["views"]:
        for sv in v["structural"].values():
            sv["mode"] = "reference_free"
    assert structural_header(r)[0] == "s_str"


def test_pooled_fidelity_skips_infinite_psnr(results):
    # clean PSNR per view: room 25, inf, 27; garden 25, 26, 27 -> finite mean 26
    f = pooled_fidelity(results, "clean")
    assert f["psnr"] == pytest.approx(26.0) and f["n_views"] == 6 and f["lpips"] == pytest.approx(0.2)


def test_axis_tables_per_scene_with_overall(results):
    t = axis_table(results, "s_geo")
    assert [c.text for c in t.header] == ["Scene", "clean", "blurry", "ghost"]
    # garden: blurry 0.95 beats clean (0.9 + 0.85) / 2
    assert _shown(_row(t, "garden")[1:]) == [("0.875", "second"), ("0.950", "best"), ("0.225", "")]
    assert _shown(_row(t, "room")[1:]) == [("0.850", "best"), ("0.700", "second"), ("0.250", "")]
    assert t.rows[-1][0].text == "Overall (view-weighted)" and t.rule_before == frozenset({2})
    lp = axis_table(results, "lpips")
    assert _shown(_row(lp, "room")[1:]) == [("0.200", "best"), ("0.400", ""), ("0.300", "second")]
    assert lp.rows[-1][0].text == "Overall (pooled views)"
    sem = axis_table(results, "s_sem")
    # ties fill first place: the worst value is not underlined
    assert _shown(_row(sem, "room")[1:]) == [("1.000", "best"), ("0.333", ""), ("1.000", "best")]


def test_iou_table(results):
    t = iou_table(results)
    room = _row(t, "room")
    assert _shown(room[1:]) == [("0.87 → 0.05 [0.82]", "best"), ("0.87 → 0.30 [0.57]", ""),
                                ("0.87 → 0.10 [0.77]", "second")]
    assert room[1].latex == r"0.87$\rightarrow$0.05 [0.82]"
    assert r"\textbf{0.87$\rightarrow$0.05 [0.82]}" in render_latex(t)


def test_sensitivity_tables(results):
    xi = xi_table(results)
    assert [c.text for c in xi.header] == ["Method", "xi=0.3", "0.5", "0.7", "0.9"]
    assert [c.text for c in _row(xi, "blurry")[1:]] == ["0.417", "1.000", "1.000", "1.000"]
    b = boundary_table(results)
    assert [c.text for c in b.header] == ["Metric", "Method", "E15", "E10", "E5", "Original", "D5", "D10", "D15"]
    first = b.rows[0]
    assert [first[0].text, first[1].text] == ["IoU_drop", "clean"]
    assert [(c.text, c.emphasis) for c in first[2:]] == [
        ("0.845", ""), ("0.835", ""), ("0.825", ""), ("0.815", "best"), ("0.775", ""), ("0.735", ""), ("0.695", "")]
    assert b.rows[3][0].text == "acc_depth" and b.rule_before == frozenset({3})
    assert r"\begin{tabular}{llccccccc}" in render_latex(b)
    assert "|:---|:---|---:|" in render_markdown(b)
    r = copy.deepcopy(results)
    del r["sensitivity"]
    assert xi_table(r) is None and boundary_table(r) is None
    tables, notes = build_results_tables(r)
    assert "threshold (xi) sweep omitted: not in the results" in notes


def test_write_tables(results, tmp_path):
    md_path, tex_path = write_tables(results, tmp_path)
    md, tex = md_path.read_text(), tex_path.read_text()
    tables, notes = build_results_tables(results)
    assert [t.key for t in tables] == [  # two scenes: no reliability table, a note instead
        "main_results", "rqs_per_scene", "axis_iou_drop", "axis_s_sem", "axis_s_geo", "axis_s_str", "axis_psnr",
        "axis_ssim", "axis_lpips", "iou_pre_post", "scene_macro", "rank_agg", "axis_association",
        "xi_sensitivity", "boundary_sensitivity"]
    assert "too few scenes to rank with confidence (2 scenes; at least 5 needed)" in notes
    assert "Note: too few scenes to rank with confidence" in md
    for t in tables:
        assert t.title in md
        assert rf"\label{{tab:r360_{t.key}}}" in tex
    assert tex.count(r"\begin{table}") == len(tables)
    assert "| room | **0.879** | 0.489 | _0.531_ |" in md
    assert r"room & \textbf{0.879} & 0.489 & \underline{0.531} \\" in tex
    assert "needs \\usepackage{booktabs}" in tex


def test_table_model_extensions_render():
    t = Table(key="x", title="T", header=[Cell("a"), Cell("b"), Cell("c"), Cell("d")],
              rows=[[Cell("1"), Cell("2"), Cell("3"), Cell("4")]], vrule_before=frozenset({3}), label_columns=2)
    assert r"\begin{tabular}{ll|cc}" in render_latex(Table(**{**t.__dict__, "vrule_before": frozenset({2})}))
    assert r"\begin{tabular}{llc|c}" in render_latex(t)
    assert "|:---|:---|---:|---:|" in render_markdown(t)
