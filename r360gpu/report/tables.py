"""Aggregate tables in the paper's layouts, rendered as Markdown or LaTeX.

One small table model (:class:`Table` of :class:`Cell`) is built from the
dict returned by :func:`r360gpu.aggregate.aggregate_tables` (or the same dict
read back from its JSON), and two renderers turn any table into text:
:func:`render_markdown` and :func:`render_latex` (booktabs).  Emphasis marks
the best (bold) and second-best (Markdown italics, LaTeX underline) values,
compared at the printed precision so that printed ties share the emphasis.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

from ..protocol import AXES, CI_LEVEL, XI_DEFAULT

FORMATS = ("md", "latex")
_NONE = "--"

_AXIS_HEADERS = {
    "s_sem": ("s_sem", r"$s_{\mathrm{sem}}$"),
    "s_geo": ("s_geo", r"$s_{\mathrm{geo}}$"),
    "s_str": ("s_str", r"$s_{\mathrm{str}}$"),
}
_AXES_NOTE = (f"s_sem = acc_seg at IoU threshold {XI_DEFAULT:g}; s_geo = acc_depth; s_str = sim_SAM(post, ref), "
              "or 1 - sim_SAM(pre, post) without a post-removal reference.")
_PAIR_HEADERS = {
    "sem-geo": ("s_sem vs s_geo", r"$s_{\mathrm{sem}}$ vs.\ $s_{\mathrm{geo}}$"),
    "sem-str": ("s_sem vs s_str", r"$s_{\mathrm{sem}}$ vs.\ $s_{\mathrm{str}}$"),
    "geo-str": ("s_geo vs s_str", r"$s_{\mathrm{geo}}$ vs.\ $s_{\mathrm{str}}$"),
}


@dataclass(frozen=True)
class Cell:
    """One table cell.

    Attributes:
        text: plain text (used for Markdown, and for LaTeX after escaping).
        latex: LaTeX source used verbatim instead of the escaped ``text``.
        emphasis: "" (none), "best" or "second".
    """

    text: str
    latex: str | None = None
    emphasis: str = ""


@dataclass(frozen=True)
class Table:
    """A rectangular table: a header row, body rows, and rules before some rows.

    Attributes:
        key: short identifier (also the LaTeX label suffix ``tab:r360_<key>``).
        title: one-line caption.
        header: the column headers.
        rows: body rows, each as long as ``header``.
        rule_before: body-row indices preceded by a horizontal rule.
        notes: sentences appended to the caption.
        vrule_before: column indices preceded by a vertical rule (LaTeX only,
            e.g. the bar between the removal axes and pixel fidelity).
        label_columns: how many leading columns hold labels (left-aligned);
            the others hold numbers (right-aligned in Markdown, centred in LaTeX).
    """

    key: str
    title: str
    header: Sequence[Cell]
    rows: Sequence[Sequence[Cell]]
    rule_before: frozenset[int] = frozenset()
    notes: Sequence[str] = field(default_factory=tuple)
    vrule_before: frozenset[int] = frozenset()
    label_columns: int = 1


def fmt_number(x: float | None, decimals: int) -> str:
    return _NONE if x is None else f"{x:.{decimals}f}"


def emphasis_marks(values: Sequence[float | None], decimals: int, higher_is_better: bool) -> list[str]:
    """"best"/"second"/"" per value, comparing values rounded to ``decimals``.

    Every value printed like the best shares "best".  "second" goes to the next
    distinct value only when it ranks second (competition ranking: a single
    value holds first place) and is not also the worst: when ties fill first
    place, or only two distinct values are shown, nothing is underlined (the
    garden case of four methods at 1.000 and one at 0.000 underlines nothing).
    """
    shown = [None if v is None else round(v, decimals) for v in values]
    if sum(v is not None for v in shown) < 2:
        return [""] * len(values)
    distinct = sorted({v for v in shown if v is not None}, reverse=higher_is_better)
    marks = {distinct[0]: "best"}
    if len(distinct) > 2 and shown.count(distinct[0]) == 1:
        marks[distinct[1]] = "second"
    return [marks.get(v, "") if v is not None else "" for v in shown]


def number_cells(values: Sequence[float | None], decimals: int, emphasise: bool = False,
                  higher_is_better: bool = True) -> list[Cell]:
    marks = emphasis_marks(values, decimals, higher_is_better) if emphasise else [""] * len(values)
    return [Cell(fmt_number(v, decimals), emphasis=e) for v, e in zip(values, marks)]


def _column(rows: list[list[Cell]], j: int, values: Sequence[float | None], decimals: int,
            emphasise: bool = True, higher_is_better: bool = True) -> None:
    for row, cell in zip(rows, number_cells(values, decimals, emphasise, higher_is_better)):
        row[j] = cell


def _pooling_label(result: dict) -> str:
    return "view-weighted" if result.get("overall_pooling") == "view-weighted" else "scene-macro"


def rqs_table(result: dict) -> Table:
    """Per-scene RQS (scenes x methods) with the Overall row (tab:supp_rqs layout)."""
    methods, scenes = list(result["methods"]), list(result["scenes"])
    rows = [[Cell(s)] + number_cells([result["rqs"][s][m] for m in methods], 3, emphasise=True)
            for s in scenes]
    overall = [result["overall"][m]["rqs"] for m in methods]
    rows.append([Cell(f"Overall ({_pooling_label(result)})")] + number_cells(overall, 3, emphasise=True))
    return Table(
        key="rqs_per_scene",
        title="Per-scene Removal Quality Score (RQS = geometric mean of s_sem, s_geo, s_str).",
        header=[Cell("Scene")] + [Cell(m) for m in methods],
        rows=rows,
        rule_before=frozenset({len(scenes)}),
        notes=(f"Overall is the RQS of the {_pooling_label(result)} pooled axes, "
               "not the mean of the per-scene values.",
               "Best and second best per row are emphasised."),
    )


def overall_table(result: dict) -> Table:
    """Overall axes, RQS and AvgRank per method (tab:main_results layout, left part)."""
    methods = list(result["methods"])
    overall = result["overall"]
    has_drop = all("iou_drop" in overall[m] for m in methods)
    header = [Cell("Method")]
    columns: list[tuple[list, int, bool]] = []
    if has_drop:
        header.append(Cell("IoU_drop (diagnostic)", r"IoU$_{\mathrm{drop}}$ (diagnostic)"))
        columns.append(([overall[m]["iou_drop"] for m in methods], 3, True))
    for axis in AXES:
        header.append(Cell(*_AXIS_HEADERS[axis]))
        columns.append(([overall[m][axis] for m in methods], 3, True))
    header.append(Cell("RQS"))
    columns.append(([overall[m]["rqs"] for m in methods], 3, True))
    header.append(Cell("AvgRank (lower is better)", r"AvgRank$\downarrow$"))
    columns.append(([result["ranks"][m]["avg_rank"] for m in methods], 2, False))
    rows = [[Cell(m)] + [Cell("")] * len(columns) for m in methods]
    for j, (values, decimals, higher) in enumerate(columns, start=1):
        _column(rows, j, values, decimals, higher_is_better=higher)
    return Table(
        key="overall",
        title=f"Overall evaluation (axes pooled over scenes, {_pooling_label(result)}).",
        header=header,
        rows=rows,
        notes=(_AXES_NOTE,
               "RQS is computed from the pooled axes; AvgRank is the mean of the per-axis ranks.",
               *(("IoU_drop is a diagnostic and enters neither RQS nor AvgRank.",) if has_drop else ()),
               "Best and second best per column are emphasised (lowest AvgRank is best)."),
    )


def scene_macro_table(result: dict) -> Table:
    """Scene-macro means (every scene weighted equally) of the axes and of per-scene RQS."""
    methods = list(result["methods"])
    macro = result["scene_macro"]
    has_drop = all("iou_drop" in macro[m] for m in methods)
    keys = [*AXES] + (["iou_drop"] if has_drop else []) + ["mean_rqs"]
    header = [Cell("Method")] + [Cell(*_AXIS_HEADERS[k]) for k in AXES]
    if has_drop:
        header.append(Cell("IoU_drop", r"IoU$_{\mathrm{drop}}$"))
    header.append(Cell("mean RQS"))
    rows = [[Cell(m)] + [Cell("")] * len(keys) for m in methods]
    for j, k in enumerate(keys, start=1):
        _column(rows, j, [macro[m][k] for m in methods], 3)
    return Table(
        key="scene_macro",
        title="Scene-macro means (each scene weighted equally).",
        header=header,
        rows=rows,
        notes=("mean RQS is the mean of the per-scene RQS, not the RQS of the mean axes.",),
    )


def rank_table(result: dict) -> Table:
    """Per-axis ranks with AvgRank, MedRank and worst-axis rank (tab:supp_rank_agg layout)."""
    methods = list(result["methods"])
    ranks = result["ranks"]
    header = [Cell("Method"), Cell("s_sem", r"$s_{\mathrm{sem}}$"), Cell("s_geo", r"$s_{\mathrm{geo}}$"),
              Cell("s_str", r"$s_{\mathrm{str}}$"), Cell("AvgRank", r"AvgRank$\downarrow$"),
              Cell("MedRank", r"MedRank$\downarrow$"), Cell("worst axis", r"worst axis$\downarrow$")]
    rows = []
    for m in methods:
        r = ranks[m]
        rows.append([Cell(m)] + number_cells([r["sem"], r["geo"], r["str"]], 1)
                    + [Cell(fmt_number(r["avg_rank"], 2)), Cell(fmt_number(r["med_rank"], 1)), Cell(fmt_number(r["worst_rank"], 1))])
    for j, key, decimals in ((4, "avg_rank", 2), (5, "med_rank", 1), (6, "worst_rank", 1)):
        marks = emphasis_marks([ranks[m][key] for m in methods], decimals, higher_is_better=False)
        for row, mark in zip(rows, marks):
            if mark == "best":
                row[j] = Cell(row[j].text, emphasis="best")
    return Table(
        key="rank_agg",
        title="Rank aggregation over the three overall axes (rank 1 is best; ties get the average rank).",
        header=header,
        rows=rows,
        notes=("The best (lowest) AvgRank, MedRank and worst-axis rank are emphasised.",),
    )


def reliability_table(result: dict) -> Table:
    """Scene-macro mean RQS, sd, range, 95% CI and P(beats best) (tab:supp_reliability layout)."""
    methods = list(result["methods"])
    rel = result["reliability"]
    best = result.get("reliability_best", "best")
    settings = result.get("settings", {})
    ci = f"{CI_LEVEL:.0%} CI"
    header = [Cell("Method"), Cell("mean RQS"), Cell("sd"), Cell("range"), Cell(ci, ci.replace("%", r"\%")),
              Cell(f"P(beats {best})", f"$P$(beats {_latex_escape(best)})")]
    rows = []
    means = number_cells([rel[m]["mean"] for m in methods], 3, emphasise=True)
    for m, mean_cell in zip(methods, means):
        r = rel[m]
        rows.append([
            Cell(m),
            Cell(mean_cell.text, emphasis="best" if mean_cell.emphasis == "best" else ""),
            Cell(fmt_number(r["sd"], 3)),
            Cell(f"{fmt_number(r['min'], 3)}-{fmt_number(r['max'], 3)}", f"{fmt_number(r['min'], 3)}--{fmt_number(r['max'], 3)}"),
            Cell(f"[{fmt_number(r['ci_low'], 3)}, {fmt_number(r['ci_high'], 3)}]"),
            Cell(fmt_number(r["p_beats_best"], 3)),
        ])
    n_boot = settings.get("n_boot")
    return Table(
        key="reliability",
        title="Reliability of the ranking across scenes (scene-macro mean RQS).",
        header=header,
        rows=rows,
        notes=(f"sd over scenes with ddof=1; {ci}: percentile interval of the paired scene-level bootstrap "
               "(the paper prints mean +- 1.96 sd / sqrt(scenes)).",
               f"P(beats {best}): the same bootstrap" + (f" ({n_boot} resamples)." if n_boot else ".")),
    )


def association_table(result: dict) -> Table:
    """Spearman rho raw / scene-centred (permutation p) and within-scene Kendall tau (tab:supp_axis_corr)."""
    assoc = result["axis_association"]
    n_perm = result.get("settings", {}).get("n_perm")
    header = [Cell("Axis pair"), Cell("rho (raw)", r"$\rho$ (raw)"),
              Cell("rho (scene-centred)", r"$\rho$ (scene-centred)"),
              Cell("mean tau (within scene)", r"mean $\tau$ (within scene)")]
    rows = []
    for pair, a in assoc.items():
        md_name, tex_name = _PAIR_HEADERS.get(pair, (pair, None))
        p = fmt_number(a["p_centred"], 3)
        tau, sd = fmt_number(a["tau_mean"], 2), fmt_number(a["tau_sd"], 2)
        rows.append([
            Cell(md_name, tex_name),
            Cell(fmt_number(a["rho"], 3), f"${fmt_number(a['rho'], 3)}$"),
            Cell(f"{fmt_number(a['rho_centred'], 3)} (p={p})", f"${fmt_number(a['rho_centred'], 3)}$~($p{{=}}{p}$)"),
            Cell(f"{tau} +/- {sd}", f"${tau} \\pm {sd}$"),
        ])
    return Table(
        key="axis_association",
        title="Association between the three axes over the (scene, method) cells.",
        header=header,
        rows=rows,
        notes=("Centred: each axis minus its scene mean; p: two-sided permutation test"
               + (f" ({n_perm} permutations" if n_perm else " (permutations")
               + " of method labels within scenes); tau: Kendall tau-b per scene, mean +- sd (ddof=0).",),
    )


def build_tables(result: dict) -> tuple[list[Table], list[str]]:
    """All tables available in ``result`` and the notes on those left out.

    Args:
        result: the dict from :func:`r360gpu.aggregate.aggregate_tables`.

    Returns:
        (tables in display order, notes such as "too few scenes to rank with confidence (...)").
    """
    builders: list[tuple[str | None, Callable[[dict], Table]]] = [
        (None, rqs_table), (None, overall_table), (None, scene_macro_table), (None, rank_table),
        ("reliability", reliability_table), ("axis_association", association_table),
    ]
    tables = [build(result) for needs, build in builders if needs is None or needs in result]
    notes = list(result.get("notes", {}).values())
    return tables, notes


_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
    "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
    "<": r"\textless{}", ">": r"\textgreater{}",
}


def _latex_escape(text: str) -> str:
    # "--" and "---" are dash ligatures in LaTeX (an option such as --lpips-model would print with an en
    # dash), and "<" / ">" print as inverted marks in the default OT1 font encoding.
    out = []
    for i, ch in enumerate(text):
        out.append(_LATEX_SPECIAL.get(ch, ch))
        if ch == "-" and text[i + 1:i + 2] == "-":
            out.append("{}")
    return "".join(out)


def _latex_cell(cell: Cell) -> str:
    body = cell.latex if cell.latex is not None else _latex_escape(cell.text)
    if cell.emphasis == "best":
        return rf"\textbf{{{body}}}"
    if cell.emphasis == "second":
        return rf"\underline{{{body}}}"
    return body


def _md_cell(cell: Cell) -> str:
    body = cell.text.replace("|", r"\|")
    if not body:
        return body
    if cell.emphasis == "best":
        return f"**{body}**"
    if cell.emphasis == "second":
        return f"_{body}_"
    return body


def render_markdown(table: Table) -> str:
    """The table as GitHub-flavoured Markdown: bold title, pipe table, notes.

    Markdown tables have no inner rules, so a rule before a row (e.g. before
    the Overall row) is rendered as an empty row.
    """
    lines = [f"**{table.title}**", ""]
    lines.append("| " + " | ".join(_md_cell(c) for c in table.header) + " |")
    n_label = min(table.label_columns, len(table.header))
    lines.append("|" + "|".join([":---"] * n_label + ["---:"] * (len(table.header) - n_label)) + "|")
    for i, row in enumerate(table.rows):
        if i in table.rule_before:
            lines.append("| " + " | ".join([""] * len(table.header)) + " |")
        lines.append("| " + " | ".join(_md_cell(c) for c in row) + " |")
    if table.notes:
        lines.append("")
        lines.extend(table.notes)
    return "\n".join(lines) + "\n"


def _latex_colspec(table: Table) -> str:
    """``l`` per label column, ``c`` per number column, ``|`` before the columns in ``vrule_before``."""
    n_label = min(table.label_columns, len(table.header))
    spec = ""
    for j in range(len(table.header)):
        if j in table.vrule_before and j > 0:
            spec += "|"
        spec += "l" if j < n_label else "c"
    return spec


def render_latex(table: Table) -> str:
    """The table as a LaTeX ``table`` float (needs ``\\usepackage{booktabs}``)."""
    caption = " ".join([_latex_escape(table.title)] + [_latex_escape(n) for n in table.notes])
    lines = [
        r"\begin{table}[t]",
        r"\centering",
        rf"\caption{{{caption}}}",
        rf"\label{{tab:r360_{table.key}}}",
        r"\begin{tabular}{" + _latex_colspec(table) + "}",
        r"\toprule",
        " & ".join(_latex_cell(c) for c in table.header) + r" \\",
        r"\midrule",
    ]
    for i, row in enumerate(table.rows):
        if i in table.rule_before:
            lines.append(r"\midrule")
        lines.append(" & ".join(_latex_cell(c) for c in row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def render_tables(result: dict, fmt: str = "md") -> str:
    """Every aggregate table of ``result`` in ``fmt`` ("md" or "latex"), blank-line separated.

    Notes on omitted tables (e.g. reliability with a single scene) are
    included as text (Markdown) or ``%`` comments (LaTeX).
    """
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, got {fmt!r}")
    tables, notes = build_tables(result)
    render = render_markdown if fmt == "md" else render_latex
    parts = [render(t) for t in tables]
    if notes:
        prefix = "Note: " if fmt == "md" else "% Note: "
        parts.append("".join(f"{prefix}{n}\n" for n in notes))
    return "\n".join(parts)
