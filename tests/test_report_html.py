"""report.html: self-contained, every picture a valid embedded PNG, escaped text,
and a real browser renders it (headless Chromium)."""
from __future__ import annotations

import base64
import json
import re
import shutil
import subprocess
import warnings
from html import unescape as html_unescape
from html.parser import HTMLParser
from pathlib import Path

import cv2
import numpy as np
import pytest

from r360gpu.errors import R360Warning
from r360gpu.report.html import pick_views, write_html
from r360gpu.report.html_blocks import table_html
from r360gpu.report.html_sections import best_per_axis, low_axis_warnings
from r360gpu.report.results_tables import write_tables
from r360gpu.report.results_tables import main_table

from report_fake import METHODS, SCENES, VIEWS, fake_results


class _Page(HTMLParser):
    """Collects tags, <img> sources and visible text; checks nesting of the container tags."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.imgs: list[str] = []
        self.tags: list[str] = []
        self.text: list[str] = []
        self.stack: list[str] = []
        self.attrs_with_urls: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        for k in ("href", "src"):
            if k in a and tag != "img":
                self.attrs_with_urls.append(a[k])
        if tag in ("section", "details", "table", "div", "figure", "ul"):
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if tag in ("section", "details", "table", "div", "figure", "ul"):
            assert self.stack and self.stack[-1] == tag, f"</{tag}> closes <{self.stack[-1] if self.stack else None}>"
            self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    results = fake_results(out)
    with warnings.catch_warnings():
        warnings.simplefilter("error", R360Warning)  # every picture must embed
        path = write_html(results, out)
    return results, out, path


def _decode(uri: str) -> np.ndarray:
    # plots are PNG, contact sheets JPEG (see html.JPEG_QUALITY)
    assert uri.startswith(("data:image/png;base64,", "data:image/jpeg;base64,")), uri[:40]
    data = base64.b64decode(uri.split(",", 1)[1], validate=True)
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None, "not a decodable image"
    return img


def _leaking(results: dict) -> dict:
    """The methods with a 'leaks most' thumbnail (those with a view that leaks)."""
    from r360gpu.report.findings import worst_views

    return worst_views(results)


def test_page_is_self_contained_and_every_image_decodes(report):
    results, out, path = report
    assert path == out / "report.html"
    text = path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    page.close()
    assert page.stack == []
    # overview chart + one worst-view thumbnail per method that leaks + one plot per (scene, method)
    # + one sheet per view
    n_methods = len(SCENES) * len(METHODS)
    n_leaking = len(_leaking(results))
    assert len(page.imgs) == 1 + n_leaking + n_methods + n_methods * len(VIEWS)
    for uri in page.imgs:
        img = _decode(uri)
        assert img.std() > 5  # not blank
    # no external resources; one inline script (table sorting, opening linked sections)
    assert page.tags.count("script") == 1 and "<script>" in text and "<script src" not in text
    assert "link" not in page.tags and "iframe" not in page.tags
    # links: in-page anchors, or the full-size PNG of an embedded sheet (a file beside the page)
    files = [u for u in page.attrs_with_urls if not u.startswith("#")]
    assert files and all((out / u).is_file() and u.startswith("pictures/") and u.endswith(".png") for u in files)
    assert "http://" not in text and "https://" not in text
    # embedded sheets are the files written by the picture functions (re-encoded as JPEG)
    from r360gpu.report.html_blocks import jpeg_uri as _jpeg_uri

    rel = results["scenes"]["room"]["methods"]["ghost"]["pictures"]["01"]
    assert _jpeg_uri((out / rel).read_bytes()) in text
    assert text == write_html(results, out).read_text(encoding="utf-8")  # deterministic


def test_summary_content(report):
    results, out, path = report
    text = path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    visible = " ".join(page.text)
    assert "ghost: s_geo = 0.238 < 0.5 -- geometry barely changed inside the target region." in visible
    assert "blurry: s_sem = 0.417 < 0.5" in visible
    assert "clean: s" not in visible  # clean has no low axis
    assert "weight-free built-in probes: builtin-appearance (semantic), builtin-graphseg (structural)" in visible
    assert "Excluded views (empty target mask, not in the means): 02." in visible
    best = {label: (ms, v) for label, ms, v, _ in best_per_axis(results)}
    assert best["s_sem (acc_seg)"][0] == ["clean", "ghost"]
    assert best["s_geo (acc_depth)"][0] == ["clean"] and best["AvgRank"][0] == ["clean"]
    # the main table is the first table on the page, best values bold
    first = text[text.index("<table"):text.index("</table>")]
    assert '<td class="num"><strong>0.884</strong></td>' in first
    assert '<td class="num"><u>0.556</u></td>' in first
    assert first.count('class="num vr"') == 4  # the bar before PSNR: header + 3 rows
    assert low_axis_warnings(results) == [
        "blurry: s_sem = 0.417 < 0.5 -- the semantic probe still finds the object in many views.",
        "ghost: s_geo = 0.238 < 0.5 -- geometry barely changed inside the target region."]
    for key in ("llvmpipe", "builtin-appearance", "expected"):
        assert key in visible


def test_text_is_escaped(tmp_path):
    evil = "gh<b>o</b>st & \"co\""
    results = fake_results(tmp_path, methods=("clean", evil))
    results["scenes"]["room"]["prompt"] = "<script>alert(1)</script>"
    path = write_html(results, tmp_path)
    text = path.read_text(encoding="utf-8")
    assert text.count("<script>") == 1 and "<script>alert" not in text and "<b>o</b>" not in text
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "gh&lt;b&gt;o&lt;/b&gt;st &amp; &quot;co&quot;" in text
    assert '<td class="lab">gh&lt;b&gt;o&lt;/b&gt;st &amp; &quot;co&quot;</td>' in table_html(main_table(results))


def test_missing_or_foreign_pictures_are_reported_not_embedded(tmp_path):
    results = fake_results(tmp_path)
    (tmp_path / "outside.png").write_bytes((tmp_path / results["scenes"]["room"]["methods"]["clean"]["plot"])
                                           .read_bytes())
    sub = tmp_path / "out"
    sub.mkdir()
    shutil.copytree(tmp_path / "pictures", sub / "pictures")
    shutil.copytree(tmp_path / "plots", sub / "plots")
    entry = results["scenes"]["room"]["methods"]["clean"]
    entry["plot"] = "../outside.png"
    entry["pictures"]["00"] = "pictures/none.png"
    (sub / "fake.png").write_text("not a png")
    entry["pictures"]["01"] = "fake.png"
    with pytest.warns(R360Warning, match="3 picture"):
        text = write_html(results, sub).read_text(encoding="utf-8")
    assert "picture path &#x27;../outside.png&#x27; leaves the output folder; not embedded" in text
    assert "picture &#x27;pictures/none.png&#x27; not found" in text
    assert "picture &#x27;fake.png&#x27; is not a PNG; not embedded" in text


def test_pick_views_and_limit(report, tmp_path):
    names = [f"{i:03d}" for i in range(10)]
    assert pick_views(names, None) == names and pick_views(names, 12) == names
    assert pick_views(names, 4) == ["000", "003", "006", "009"]
    assert pick_views(names, 1) == ["000"] and pick_views(names, 0) == []
    results, out, _ = report
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    text = write_html(results, copy, max_views=2).read_text(encoding="utf-8")
    assert text.count("<img") == 1 + len(_leaking(results)) + 6 + 6 * 2
    assert "Per-view contact sheets (2 of 3 views)" in text
    assert "every view's picture is in the pictures/room/clean folder" in text


def test_minimal_results_render(tmp_path):
    """No aggregate, no sensitivity, no pictures, no probes: tables and page still render."""
    results = fake_results(None)
    for key in ("aggregate", "sensitivity", "probes", "adapter", "options"):
        del results[key]
    md, tex = write_tables(results, tmp_path)
    assert "aggregate tables omitted" in md.read_text()
    assert "| clean | -- | -- |" in md.read_text()
    text = write_html(results, tmp_path).read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    assert page.stack == [] and page.imgs == []
    assert "No probe descriptions in the results." in text


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


_CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                   "--disable-background-networking", "--disable-component-update", "--disable-sync",
                   "--hide-scrollbars"]

# Test instrumentation only (the report itself has no JavaScript): after load,
# record every image's decode state and its box on the page.
_PROBE = """<script>
window.addEventListener('load', function () {
  var r = Array.prototype.map.call(document.images, function (i) {
    var b = i.getBoundingClientRect();
    return {ok: i.complete && i.naturalWidth > 0, w: i.naturalWidth, x: b.left + window.scrollX,
            y: b.top + window.scrollY, bw: b.width, bh: b.height};
  });
  var p = document.createElement('pre'); p.id = 'r360-probe'; p.textContent = JSON.stringify(r);
  document.body.appendChild(p);
});
</script>"""


def _run_chromium(exe: str, args: list[str], tmp: Path) -> subprocess.CompletedProcess:
    cmd = [exe, *_CHROMIUM_FLAGS, f"--user-data-dir={tmp / 'profile'}", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def test_renders_in_headless_chromium(report, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("Chromium is not installed (Debian package 'chromium'); the browser check needs it")
    results, out, path = report
    shot = tmp_path / "shot.png"
    res = _run_chromium(exe, [f"--screenshot={shot}", "--window-size=1280,2000", path.as_uri()], tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    img = cv2.imread(str(shot), cv2.IMREAD_COLOR)
    assert img is not None and img.shape == (2000, 1280, 3)
    assert img.std() > 10  # not blank

    probe_page = tmp_path / "probe.html"
    probe_page.write_text(path.read_text(encoding="utf-8").replace("</body>", _PROBE + "</body>"), encoding="utf-8")
    res = _run_chromium(exe, ["--dump-dom", "--virtual-time-budget=5000", "--window-size=1280,2000",
                              probe_page.as_uri()], tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    dom = res.stdout
    start = dom.index('<pre id="r360-probe">') + len('<pre id="r360-probe">')
    boxes = json.loads(dom[start:dom.index("</pre>", start)].replace("&quot;", '"').replace("&amp;", "&"))
    assert len(boxes) == 1 + len(_leaking(results)) + len(SCENES) * len(METHODS) * (1 + len(VIEWS))
    broken = [b for b in boxes if not b["ok"]]
    assert broken == []
    # every image laid out inside the screenshot shows content, not a blank box
    visible = [b for b in boxes if b["bw"] > 20 and b["bh"] > 20 and b["y"] + b["bh"] <= 2000]
    assert visible, "no image in the first 2000 px of the page"
    for b in visible:
        x0, y0 = int(b["x"]) + 2, int(b["y"]) + 2
        crop = img[y0 : int(b["y"] + b["bh"]) - 2, x0 : int(b["x"] + b["bw"]) - 2]
        assert crop.size and crop.std() > 10, b


# -- the report: first screen, per-view table, probe checks, known failures ------------

from report_fake import add_expected, add_probe_checks, add_ranked_reliability  # noqa: E402

from r360gpu.report import findings  # noqa: E402
from r360gpu.report.tables import render_latex  # noqa: E402


def _visible(text: str) -> str:
    page = _Page()
    page.feed(text)
    return " ".join(" ".join(page.text).split())


@pytest.fixture(scope="module")
def checked_report(tmp_path_factory):
    """The fake results with probe verdicts, controls, known failures and a long probe parameter
    list (like the built-in appearance probe's, which made the page 3,637 px wide)."""
    out = tmp_path_factory.mktemp("checked")
    results = add_expected(add_probe_checks(fake_results(out)))
    params = {f"parameter_{i}": [0.25 * k for k in range(12)] for i in range(12)}
    params["model_sha256"] = "0123456789abcdef" * 8
    results["probes"]["semantic"][0]["params"] = params
    with warnings.catch_warnings():
        warnings.simplefilter("error", R360Warning)
        path = write_html(results, out)
    return results, out, path


def test_first_screen_main_table_verdicts_and_worst_views(checked_report):
    results, out, path = checked_report
    text = path.read_text(encoding="utf-8")
    leaks = text[text.index('<section id="leaks">'):text.index('<section id="summary">')]
    assert leaks.index("<table") < leaks.index("Probe checks") < leaks.index("Where each method leaks most") \
        < leaks.index("Controls behind the probe checks")
    assert '<td class="lab">garden</td><td class="lab">identity</td><td class="num">0.900</td>' in leaks
    # verdict cells and one sentence per verdict that is not ok, citing the controls
    assert '<td class="lab v-weak">weak</td>' in leaks and '<td class="lab v-blind">blind</td>' in leaks
    vis = _visible(leaks)
    assert "room: s_geo is weak here" in vis and "0.300 on the identity control" in vis
    assert "garden: s_sem is blind here" in vis and "0.900 on the identity control (nothing removed)" in vis
    assert vis.count(" is weak here") == 1 and vis.count(" is blind here") == 1
    # Overall cells of a doubtful axis are marked (acc_seg: blind in garden, acc_depth: weak in room)
    main = leaks[:leaks.index("</table>")]
    assert main.count('class="num doubt"') == 2 * len(METHODS)
    assert "acc_seg (s_sem): the probe check is not ok in scene(s) garden (blind)" in vis
    # worst view per method: ghost's is a room view with the lowest acc_depth (0.2 at view 00)
    worst = findings.worst_views(results)
    assert worst["ghost"]["scene"] == "room" and worst["ghost"]["view"] == "00"
    rows = findings.view_rows(results)
    leaking = {r["method"] for r in rows if findings.leaks(r)}
    assert leaks.count("<figure>") == len(leaking)
    for m in METHODS:  # a method with no leaking view gets no thumbnail, and is named as not leaking
        assert (m in worst) == (m in leaking)
        if m not in leaking:
            assert f"<b>{m}</b>" in leaks[leaks.index("No view leaks"):]
    assert findings.leaks({"s_sem": 1.0, "acc_depth": 0.49}) and not findings.leaks({"s_sem": 1.0, "s_str": 0.5})
    anchor = f'href="#pic-0-{METHODS.index("ghost")}-0"'
    assert anchor in leaks and f'id="pic-0-{METHODS.index("ghost")}-0"' in text


def test_report_without_checks_has_no_verdicts(report):
    _, _, path = report
    text = path.read_text(encoding="utf-8")
    assert "Probe checks" not in text and "doubt" not in text.split("<style>")[1].split("</style>")[1]
    assert "Known failure modes" not in text


def test_known_failures_caught_or_missed(checked_report):
    results, _, path = checked_report
    checks = {(c.scene, c.method): c for c in findings.expectation_checks(results)}
    assert checks["room", "clean"].outcome == "passes"
    assert checks["room", "blurry"].outcome == "caught"  # s_sem 1/3
    assert checks["garden", "blurry"].outcome == "missed"  # s_sem 0.5 is not below 0.5
    assert checks["room", "ghost"].outcome == "partly"  # s_geo 0.25 caught, s_str 0.6 missed
    vis = _visible(path.read_text(encoding="utf-8")).replace(" :", ":")
    assert "Known failure modes: caught?" in vis
    assert "caught: s_sem 0.333 caught" in vis and "missed: s_sem 0.500 missed" in vis
    assert "partly: s_geo 0.250 caught, s_str 0.600 missed" in vis
    assert "3 of 6 as expected" in vis  # room clean + blurry, garden clean


def test_per_view_table_every_view_linked(checked_report):
    results, _, path = checked_report
    text = path.read_text(encoding="utf-8")
    assert text.count('<table class="sortable perview">') == len(SCENES)
    ids = set(re.findall(r'<figure id="(pic-[^"]+)"', text))
    links = re.findall(r'<a href="#(pic-[^"]+)" title="contact sheet">', text)
    assert len(links) == len(SCENES) * len(METHODS) * len(VIEWS) and set(links) == ids
    # every view's contact sheet shown, with its numbers beside it
    assert "Per-view contact sheets (3 views)" in text
    # the axis record is a table, not a JSON dump
    assert "Axis record (as stored)" not in text and "<pre>" not in text
    rec = text[text.index("<summary>Axis record</summary>"):]
    assert rec.index('<table class="kv">') < 60 and "0.3: 1.000, 0.5: 1.000" in rec[:6000]


def test_per_view_table_counts_see_through_holes_where_a_scene_has_them(checked_report):
    """The count of target pixels with no depth after removal is a column of the per-view table of
    a scene with a hole (the fake's ghost in the room), explained in the caption; a scene without
    any hole keeps its table as it was."""
    from report_fake import no_depth

    _, _, path = checked_report
    text = path.read_text(encoding="utf-8")
    tables = re.findall(r'<table class="sortable perview">.*?</table>', text, re.S)
    room, garden = tables
    assert '<th class="num">no depth</th>' in room and "a see-through hole that acc_depth counts" in room
    assert "no depth" not in garden
    heads = re.findall(r"<th[^>]*>(.*?)</th>", room)
    col = heads.index("no depth") - 2  # after Method and View
    for v in VIEWS:
        row = re.search(rf'<tr id="row-[^"]*"><td class="lab">ghost</td><td class="lab">(?:<a [^>]*>)?{v}<(.*?)</tr>',
                        room, re.S)
        cells = re.findall(r'<td class="num" data-v="([^"]*)">', row.group(1))
        assert float(cells[col]) == no_depth("room", "ghost", v)


def test_note_box_one_item_per_probe(checked_report):
    _, _, path = checked_report
    text = path.read_text(encoding="utf-8")
    note = text[text.index('<div class="info">'):]
    note = note[:note.index("</div>")]
    assert "<li><strong>builtin-appearance</strong> (semantic): colour statistics only</li>" in note
    assert "<li><strong>builtin-graphseg</strong> (structural): graph segmentation</li>" in note


def test_no_lpips_column_without_a_model(tmp_path):
    results = fake_results(None)
    for sd in results["scenes"].values():
        for entry in sd["methods"].values():
            entry["axes"]["lpips"] = None
            for rec in entry["views"]:
                rec["fidelity"].update(lpips=None, lpips_reason="no LPIPS model given", lpips_model=None)
    text = write_html(results, tmp_path).read_text(encoding="utf-8")
    assert "LPIPS (lower is better)" not in text and "LPIPS not computed: no LPIPS model given." in text
    md, tex = write_tables(results, tmp_path)
    tex_text = tex.read_text()
    assert "% Note: LPIPS omitted: no LPIPS model ran" in tex_text
    assert "LPIPS" not in "".join(ln for ln in tex_text.splitlines() if not ln.startswith("%"))
    assert "LPIPS omitted: no LPIPS model ran" in md.read_text()
    assert "LPIPS" not in render_latex(main_table(results))


# Test instrumentation: page width against the window, then sorting the first per-view table by
# its acc_depth column (twice: ascending, descending).
_LAYOUT_PROBE = """<script>
window.addEventListener('load', function () {
  var d = document.documentElement, out = {sw: d.scrollWidth, iw: window.innerWidth, wide: []};
  document.querySelectorAll('body *').forEach(function (e) {
    var b = e.getBoundingClientRect();
    if (b.right > window.innerWidth + 1 && !e.closest('.scroll')) out.wide.push(e.tagName + '.' + e.className);
  });
  var t = document.querySelector('table.sortable'), hs = t.tHead.rows[0].cells, j = -1;
  for (var i = 0; i < hs.length; i++) if (hs[i].textContent.indexOf('acc_depth') === 0) j = i;
  function col() { return Array.prototype.map.call(t.tBodies[0].rows, function (r) { return r.cells[j].textContent; }); }
  out.before = col(); hs[j].click(); out.asc = col(); hs[j].click(); out.desc = col();
  var p = document.createElement('pre'); p.id = 'r360-probe'; p.textContent = JSON.stringify(out);
  document.body.appendChild(p);
});
</script>"""


@pytest.mark.parametrize("width", [1400, 800])
def test_no_sideways_scroll_and_sorting_in_chromium(checked_report, tmp_path, width):
    exe = _chromium()
    if exe is None:
        pytest.skip("Chromium is not installed (Debian package 'chromium'); the browser check needs it")
    _, _, path = checked_report
    page = tmp_path / "probe.html"
    page.write_text(path.read_text(encoding="utf-8").replace("</body>", _LAYOUT_PROBE + "</body>"), encoding="utf-8")
    res = _run_chromium(exe, ["--dump-dom", "--virtual-time-budget=5000", f"--window-size={width},900",
                              page.as_uri()], tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    dom = res.stdout
    start = dom.index('<pre id="r360-probe">') + len('<pre id="r360-probe">')
    got = json.loads(html_unescape(dom[start:dom.index("</pre>", start)]))
    assert got["sw"] <= got["iw"], f"page {got['sw']} px wide in a {got['iw']} px window: {got['wide'][:10]}"
    assert got["wide"] == []
    nums = [float(x) for x in got["asc"] if x != "--"]
    assert nums == sorted(nums) and len(nums) >= 6
    if "--" in got["asc"]:  # missing values last either way
        assert got["asc"][-1] == "--" and got["desc"][-1] == "--"
    assert [float(x) for x in got["desc"] if x != "--"] == sorted(nums, reverse=True)
    assert sorted(got["before"]) == sorted(got["asc"])


def test_first_screen_says_too_few_scenes_to_rank(checked_report):
    """The fake's two scenes: the sentence saying so where the intervals would be, and no intervals."""
    results, _, path = checked_report
    text = path.read_text(encoding="utf-8")
    leaks = text[text.index('<section id="leaks">'):text.index('<section id="summary">')]
    assert "reliability" not in results["aggregate"]
    said = "too few scenes to rank with confidence (2 scenes; at least 5 needed)"
    assert results["aggregate"]["notes"]["reliability"] == said
    assert "How sure is the ranking" in leaks and said in leaks
    assert "95% CI" not in text and "P(beats " not in text
    assert text.count(said) == 1  # not repeated among the table notes


def test_first_screen_says_how_sure_the_ranking_is(tmp_path):
    results = add_ranked_reliability(add_probe_checks(fake_results(tmp_path, pictures=False)))
    text = write_html(results, tmp_path).read_text(encoding="utf-8")
    leaks = text[text.index('<section id="leaks">'):text.index('<section id="summary">')]
    rel = results["aggregate"]["reliability"]
    assert "How sure is the ranking" in leaks and "95% CI" in leaks and "P(beats " in leaks
    assert leaks.index("How sure is the ranking") < leaks.index("Probe checks")  # right under the main table
    for m, r in rel.items():
        assert 0.0 <= r["ci_low"] <= r["ci_high"] <= 1.0
        assert f"[{r['ci_low']:.3f}, {r['ci_high']:.3f}]" in leaks
    assert "too few scenes" not in text
    tables = text[text.index('<section id="tables">'):]
    assert "95% CI" not in tables[:tables.index("</section>")]  # shown once


def test_contact_sheets_link_to_the_full_size_png(checked_report):
    results, out, path = checked_report
    text = path.read_text(encoding="utf-8")
    for s in SCENES:
        for m in METHODS:
            pics = results["scenes"][s]["methods"][m]["pictures"]
            for rel in pics.values():
                href = f'<a href="{rel}" title="full-size picture">'
                assert href in text and (out / rel).is_file()
