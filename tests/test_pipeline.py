"""The scoring pipeline's overlapped schedule: same cells as one view at a time, errors from
any thread stop the run, pictures and cache cells come from one writer thread."""
from __future__ import annotations

import importlib
import threading

import pytest

from bundle_factory import make_bundle, make_remove360
from r360gpu.bundle import load_bundle
from r360gpu.errors import InputError
from r360gpu.metrics.record import ViewRecord
from r360gpu.pipeline import EvaluateOptions, default_probes, evaluate
from r360gpu.pipeline.cache import RunCache
from r360gpu.pipeline.picture_sink import PictureSink
from r360gpu.pipeline.run import SceneRun, Timer
from r360gpu.pipeline.stages import score_view
from r360gpu.pipeline.writer import BackgroundWriter
from r360gpu.probes.base import StructuralProbe

OPTS = dict(n_boot=50, n_perm=20)


@pytest.mark.parametrize("layout", ["remove360", "mixed"])
def test_overlapped_views_give_the_cells_of_one_view_at_a_time(tmp_path, ctx, layout):
    """remove360: every source read on host threads; mixed: splat scenes on the GPU thread too."""
    root = make_remove360(tmp_path / "b") if layout == "remove360" else make_bundle(tmp_path / "b")
    bundle = load_bundle(root)
    res = evaluate(bundle, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    sem, stru = default_probes()
    run = SceneRun(bundle, EvaluateOptions(**OPTS), ctx, sem, stru, cache=RunCache(None), timer=Timer())
    one_by_one = {v: score_view(run, v, PictureSink(None, False)) for v in run.views}
    run.release()
    for m, entry in res["scenes"][bundle.name]["methods"].items():
        assert all(isinstance(one_by_one[v].cells[m].record, ViewRecord) for v in run.views)
        assert entry["views"] == [one_by_one[v].cells[m].record.to_dict() for v in run.views]


def test_view_records_are_dicts_only_where_written(tmp_path, ctx):
    """A cache cell is written with its record as a dict and read back as a ViewRecord; a run served
    from the cache writes the same results."""
    import json

    from r360gpu.pipeline.cache import ViewCache

    bundle = load_bundle(make_remove360(tmp_path / "b"))
    out = tmp_path / "o"
    opts = EvaluateOptions(pictures=False, **OPTS)
    first = evaluate(bundle, out=out, options=opts, device=ctx, progress=False)
    cell_file = sorted((out / ".r360cache" / "views").glob(f"*/{bundle.name}/after/*.json"))[0]
    on_disk = json.loads(cell_file.read_text())
    assert on_disk["record"]["view"] == cell_file.stem and on_disk["record"]["method"] == "after"
    cell = ViewCache(cell_file.parent.parent, out).load_cell("after", cell_file.stem)
    assert isinstance(cell.record, ViewRecord) and cell.record.to_dict() == on_disk["record"]
    entry = first["scenes"][bundle.name]["methods"]["after"]["views"]
    assert on_disk["record"] in entry
    again = evaluate(bundle, out=out, options=opts, device=ctx, progress=False)
    assert "render" not in again["timing"]["stages_s"] and "measure" not in again["timing"]["stages_s"]
    drop = lambda d: {k: v for k, v in d.items() if k not in ("created", "timing")}  # noqa: E731
    assert json.dumps(drop(again)) == json.dumps(drop(first))


class _FailsOn(StructuralProbe):
    """The built-in structural probe, failing on one view (as a probe reading a broken file would)."""

    cacheable = False

    def __init__(self, view):
        self.inner, self.view = default_probes()[1][0], view

    @property
    def name(self):
        return "fails-on"

    def params(self):
        return {"view": self.view}

    def predict(self, views):
        for v in views:
            if v.name == self.view:
                raise InputError(f"view {v.name}: broken probe file")
        return self.inner.predict(views)


def test_an_error_on_a_host_thread_stops_the_run_and_leaves_no_cell_behind(tmp_path, ctx):
    root = make_remove360(tmp_path / "b")
    before = threading.active_count()
    with pytest.raises(InputError, match="view_01: broken probe file"):
        evaluate(root, out=tmp_path / "out", structural_probes=[_FailsOn("view_01")],
                 options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert threading.active_count() == before  # no thread left running
    cells = sorted(p.stem for p in (tmp_path / "out" / ".r360cache" / "views").rglob("*.json"))
    assert "view_01" not in cells and "view_02" not in cells
    # every method cell written has its picture (the controls' cells, under "pre"/"reference", have none)
    for p in (tmp_path / "out" / ".r360cache" / "views").rglob("*.json"):
        import json

        if p.parent.name in ("pre", "reference"):
            assert json.loads(p.read_text())["picture"] is None
            continue
        assert (tmp_path / "out" / json.loads(p.read_text())["picture"]).is_file()


def test_background_writer_runs_in_order_bounded_and_raises_the_first_error():
    w = BackgroundWriter(bound=2)
    done, gate = [], threading.Event()
    w.submit(gate.wait)
    w.submit(done.append, 1)
    # a third job must wait for a free slot: release the gate from another thread
    threading.Timer(0.2, gate.set).start()
    w.submit(done.append, 2)
    assert gate.is_set()  # the submit waited for a slot
    with pytest.raises(ZeroDivisionError):
        w.submit(lambda: 1 / 0)
        w.submit(done.append, 3)  # may already raise the error
        w.close()
    w.close(wait_errors=False)
    assert done[:2] == [1, 2]


def test_warning_log_records_each_warning_once_from_any_thread():
    """The run's warning log (util.warning_log) is shared by the stage threads: each warning once,
    printed once, and attributed to the view whose stage raised it (for the view cache)."""
    import contextvars
    import io

    from r360gpu.util import warning_log

    stream = io.StringIO()
    with warning_log.collecting(stream):
        def stage(view):
            with warning_log.where(scene="s", view=view):
                warning_log.warn("depth unit differs", file="d.png", method="m")
                warning_log.count("missing_probe_files", "p:dir")

        threads = [threading.Thread(target=contextvars.copy_context().run, args=(stage, "v" if i % 2 else "w"))
                   for i in range(8)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        recs = warning_log.records()
        per_view = warning_log.for_view("s", "v")
    assert sorted(r["view"] for r in recs) == ["v", "w"]
    assert all(r["message"] == "depth unit differs" and r["file"] == "d.png" for r in recs)
    assert stream.getvalue().count("r360gpu: warning:") == 2
    assert [r["view"] for r in per_view["records"]] == ["v"]
    assert per_view["counts"] == {"missing_probe_files": {"p:dir": 4}}


def test_a_fully_cached_rerun_renders_nothing_and_a_stale_fit_record_is_caught(tmp_path, ctx, monkeypatch):
    """The appearance probe's fit record completes the view cache key, so nothing is rendered;
    when a view must be scored the probe is fitted first and the record checked."""
    import json

    from r360gpu.render.sources import SceneSource

    root = make_bundle(tmp_path / "b")
    opts = EvaluateOptions(**OPTS)
    first = evaluate(root, out=tmp_path / "out", options=opts, device=ctx, progress=False)
    images = SceneSource.images
    calls = []
    monkeypatch.setattr(SceneSource, "images", lambda self, v, c: calls.append(v) or images(self, v, c))
    again = evaluate(root, out=tmp_path / "out", options=opts, device=ctx, progress=False)
    assert calls == [] and "fit probes" not in again["timing"]["stages_s"]
    assert again["scenes"] == first["scenes"] and again["probes"] == first["probes"]
    # a fit record that no longer holds: the views are looked up again under the fitted key
    (rec,) = (tmp_path / "out" / ".r360cache" / "fits").glob("*.json")
    doc = json.loads(rec.read_text())
    doc["semantic"][0]["params"]["model_sha256"] = "0" * 64
    rec.write_text(json.dumps(doc))
    next(iter((tmp_path / "out" / ".r360cache" / "views").rglob("view_01.json"))).unlink()
    third = evaluate(root, out=tmp_path / "out", options=opts, device=ctx, progress=False)
    assert third["scenes"] == first["scenes"] and third["probes"] == first["probes"]


def test_chunks_scored_from_pickled_inputs_give_the_runs_cells(tmp_path, ctx):
    """What an executor in another process would get: pickled inputs in, the same cells out."""
    import pickle

    from r360gpu.pipeline.chunks import score_chunk

    root = make_bundle(tmp_path / "b")
    opts = EvaluateOptions(**OPTS)
    res = evaluate(root, options=opts, device=ctx, progress=False)
    sem, stru = default_probes()
    cells = {}
    for chunk in (["view_00", "view_02"], ["view_01"]):
        args = pickle.loads(pickle.dumps((root, opts, sem, stru, chunk)))
        cells.update(score_chunk(*args, ctx=ctx))
    for m, entry in res["scenes"]["room"]["methods"].items():
        assert entry["views"] == [cells[v][m]["record"] for v in res["scenes"]["room"]["views"]]
    with pytest.raises(InputError, match="view_09"):
        score_chunk(root, opts, sem, stru, ["view_09"], ctx=ctx)


def test_views_in_flight_shrink_for_large_images():
    from r360gpu.pipeline.schedule import LOOKAHEAD, MEMORY_BUDGET, _in_flight

    assert _in_flight(20 << 20) == (LOOKAHEAD, LOOKAHEAD + 1)  # 480x360, 7 sources
    assert _in_flight(MEMORY_BUDGET // 2) == (1, 1)
    assert _in_flight(MEMORY_BUDGET * 3) == (0, 1)  # 8K: one view measured, one written, none ahead


@pytest.mark.parametrize("size", [(300, 400), (120, 160), (61, 97)])
def test_picture_sink_writes_the_sheet_of_the_full_size_inputs(tmp_path, size):
    """The sink brings images and masks to the panel size first (once per view); the sheet
    must be byte for byte the one the report draws from the full-size inputs."""
    import numpy as np

    from dataclasses import replace

    from r360gpu.metrics.compat import depth_delta
    from r360gpu.pipeline.picture_sink import PictureJob
    from r360gpu.probes.base import MaskSet, SemanticPrediction
    from r360gpu.report.contact_sheets import panel_width_for, view_contact_sheet

    h, w = size
    rng = np.random.default_rng(h)
    yy, xx = np.mgrid[:h, :w]
    blob = lambda cy, cx, r: (yy - cy) ** 2 + (xx - cx) ** 2 < r * r  # noqa: E731
    pre, post, ref = (rng.uniform(size=(h, w, 3)).astype(np.float32) for _ in range(3))
    d_pre = rng.uniform(1, 5, (h, w)).astype(np.float32)
    d_post = d_pre.copy()
    d_post[blob(h / 2, w / 2, h / 5)] += 1
    target = blob(h / 2, w / 2, h / 4)

    class Geo:
        changed = blob(h / 2, w / 2, h / 5)
        threshold = 0.5

    sem = (SemanticPrediction(target[None], np.ones(1, np.float32), ["x"], "s"),
           SemanticPrediction(np.zeros((0, h, w), bool), np.zeros(0, np.float32), [], "s"))
    masks = MaskSet(np.stack([blob(h / 3, w / 3, h / 6), target, blob(h / 4, w / 2, h / 8)]), None, "t")
    sink = PictureSink(tmp_path / "out", True)
    job = PictureJob(scene="s", method="m", view="v", pre_rgb=pre, post_rgb=post, ref_rgb=ref, pre_depth=d_pre,
                     post_depth=d_post, mask=target, geo=Geo, compat=False, semantic=sem,
                     structural=[("a on I_pre", pre, masks), ("a on I_post", post, masks)])
    sink.view([job, replace(job, method="m2")])
    # the second method's sheet reuses the panels of the first where their arrays are the same
    for method in ("m", "m2"):
        direct = view_contact_sheet(
            tmp_path / f"direct_{method}.png", title=f"s / {method} / v", pre=pre, post=post, target=target, ref=ref,
            delta=depth_delta(d_pre, d_post), threshold=0.5, changed=Geo.changed, semantic_pre=sem[0].union(),
            semantic_post=sem[1].union(),
            structural=[("a on I_pre", pre, masks.masks), ("a on I_post", post, masks.masks)], width=panel_width_for(w))
        assert (tmp_path / "out" / "pictures" / "s" / method / "v.png").read_bytes() == direct.read_bytes()


def test_panel_width_follows_small_views():
    """Views narrower than PANEL_WIDTH keep their own width (no enlarged pixels), down to MIN_PANEL_WIDTH,
    which keeps the lines of numbers on a 4-column sheet whole."""
    import cv2
    import numpy as np

    from r360gpu.report.contact_sheets import (MIN_PANEL_WIDTH, PANEL_WIDTH, panel_width_for, sheet_image, view_numbers,
                                         _FONT, _TITLE_SCALE)

    assert [panel_width_for(w) for w in (4000, PANEL_WIDTH, 290, MIN_PANEL_WIDTH, 97, 1)] == [
        PANEL_WIDTH, PANEL_WIDTH, 290, MIN_PANEL_WIDTH, MIN_PANEL_WIDTH, MIN_PANEL_WIDTH]
    record = {"semantic": {"grounded-sam2": {"iou_pre": 0.87654, "iou_post": 0.12345}},
              "geometric": {"acc_depth": 0.91234, "threshold": 0.12345},
              "structural": {"sam-vit-h": {"sim_sam": 0.85432}},
              "fidelity": {"psnr": 31.234, "ssim": 0.91234, "lpips": 0.12345}}
    sheet_w = sheet_image([("p", np.zeros((8, 8, 3), np.uint8))] * 4, panel_width=MIN_PANEL_WIDTH).shape[1]
    for line in view_numbers(record):
        assert cv2.getTextSize(line, _FONT, _TITLE_SCALE, 1)[0][0] <= sheet_w - 8, line


def _small_benchmark(root, ctx, scenes=("room",)):
    from r360gpu.synthetic import generate_benchmark

    return generate_benchmark(root, n_views=4, width=64, height=48, scenes=scenes, detail=0.08, ctx=ctx)


def test_splat_views_are_rendered_ahead_while_the_first_is_probed(tmp_path, ctx, monkeypatch):
    """With every source rendered on the GPU thread, a view's size is known once it is rendered:
    the next views are rendered while the host threads probe the first."""
    import r360gpu.pipeline.schedule as ev
    import r360gpu.pipeline.stages as st

    folder = _small_benchmark(tmp_path / "b", ctx)[0]
    rendered, waited = [], []
    second = threading.Event()
    real_render, real_gather = st.render_on_device, ev._gather

    def render(run, v):
        rendered.append(v)
        if len(rendered) >= 2:
            second.set()
        return real_render(run, v)

    def gather(run, data):
        if data.view == rendered[0]:
            waited.append(second.wait(timeout=20))
        return real_gather(run, data)

    monkeypatch.setattr(ev, "render_on_device", render)  # the scheduler's own name for the stage
    monkeypatch.setattr(ev, "_gather", gather)
    evaluate(folder, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert waited == [True] and len(rendered) == 4


def test_the_next_scene_is_opened_while_the_last_views_are_probed(tmp_path, ctx, monkeypatch):
    import r360gpu.pipeline.stages as st

    ev = importlib.import_module("r360gpu.pipeline.evaluate")  # (the package exports a function of that name)

    folders = _small_benchmark(tmp_path / "b", ctx, scenes=("room", "garden"))
    alone = {f.name: evaluate(f, options=EvaluateOptions(**OPTS), device=ctx, progress=False)["scenes"][f.name]
             for f in folders}
    events = []

    class Recorded(SceneRun):
        def __init__(self, bundle, *a, **k):
            events.append(("open", bundle.name))
            super().__init__(bundle, *a, **k)

    real_measure = st.measure

    def measure(run, data, sink):
        events.append(("measure", run.bundle.name, data.view))
        return real_measure(run, data, sink)

    monkeypatch.setattr(ev, "SceneRun", Recorded)
    monkeypatch.setattr(importlib.import_module("r360gpu.pipeline.schedule"), "measure", measure)
    both = evaluate(folders, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    room_views = both["scenes"]["room"]["views"]
    assert events.index(("open", "garden")) < events.index(("measure", "room", room_views[-1]))
    assert [e for e in events if e[0] == "open"] == [("open", "room"), ("open", "garden")]
    for name, entry in alone.items():  # opened ahead or not, a scene's numbers are its own
        assert both["scenes"][name] == entry


def test_warnings_are_recorded_in_scene_and_view_order():
    from r360gpu.pipeline.evaluate import in_run_order

    def rec(scene, view, message):
        return {"scene": scene, "method": None, "view": view, "file": None, "message": message}

    raised = [rec("b", "v2", "late"), rec("a", "v1", "x"), rec(None, None, "run-wide"), rec("b", None, "scene b"),
              rec("a", "v0", "first"), rec("a", "v1", "y"), rec("b", "v0", "b0")]
    views_of = {"a": {"v0": 0, "v1": 1}, "b": {"v0": 0, "v2": 1}}
    got = in_run_order(raised, ["a", "b"], views_of)
    assert [r["message"] for r in got] == ["run-wide", "first", "x", "y", "scene b", "b0", "late"]
    assert in_run_order(list(reversed(got)), ["a", "b"], views_of) != got  # within a view: as raised
    assert sorted(map(str, got)) == sorted(map(str, raised))


def test_a_scene_that_cannot_be_opened_ahead_fails_at_its_turn(tmp_path, ctx, monkeypatch):
    """The error of a scene opened ahead comes once the scene before is scored and cached."""
    import r360gpu.pipeline.stages as st

    import cv2
    import numpy as np

    room, garden = _small_benchmark(tmp_path / "b", ctx, scenes=("room", "garden"))
    masks = sorted((garden / "masks").glob("*.png"))
    good = {p: p.read_bytes() for p in masks}
    for p in masks:  # no target in any view: found once the scene is opened
        assert cv2.imwrite(str(p), np.zeros((48, 64), np.uint8))
    with pytest.raises(InputError) as err:
        evaluate([room, garden], out=tmp_path / "out", options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert "garden" in str(err.value) and "empty" in str(err.value)
    for p, data in good.items():
        p.write_bytes(data)
    rendered = []
    real_render = st.render_on_device
    monkeypatch.setattr(importlib.import_module("r360gpu.pipeline.schedule"), "render_on_device",
                        lambda run, v: rendered.append(run.bundle.name) or real_render(run, v))
    evaluate([room, garden], out=tmp_path / "out", options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert rendered.count("room") == 0 and rendered.count("garden") == 4  # every room view was cached


def test_host_threads_scale_with_cores_and_the_variable_is_checked(monkeypatch):
    import os

    import pytest

    from r360gpu.errors import InputError
    import r360gpu.pipeline.schedule as ev

    monkeypatch.delenv("R360GPU_HOST_THREADS", raising=False)
    for cores, want in ((None, 2), (1, 2), (2, 2), (4, 2), (6, 4), (16, ev.MAX_HOST_THREADS), (128, ev.MAX_HOST_THREADS)):
        monkeypatch.setattr(os, "cpu_count", lambda c=cores: c)
        assert ev.host_threads() == want, cores
    monkeypatch.setenv("R360GPU_HOST_THREADS", "3")
    assert ev.host_threads() == 3
    for bad in ("0", "-2", "two", "1.5"):
        monkeypatch.setenv("R360GPU_HOST_THREADS", bad)
        with pytest.raises(InputError, match="R360GPU_HOST_THREADS"):
            ev.host_threads()
    # one view ahead per host thread, still within the memory budget
    assert ev._in_flight(20 << 20, 8) == (8, ev.writer_threads(8) + 1) == (8, 5)  # a view waiting per writer
    assert ev._in_flight(ev.MEMORY_BUDGET // 2, 8) == (1, 1)


def test_results_do_not_depend_on_the_number_of_host_threads(tmp_path, ctx, monkeypatch):
    """1 host thread and 1 writer against 4 host threads and 2 writers: the same results and pictures."""
    import cv2
    import numpy as np

    root = make_bundle(tmp_path / "b")
    runs, sheets = {}, {}
    for n in ("1", "4"):
        monkeypatch.setenv("R360GPU_HOST_THREADS", n)
        out = tmp_path / f"out{n}"
        res = evaluate(load_bundle(root), out=out, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
        runs[n] = {k: v for k, v in res.items() if k not in ("created", "timing")}
        sheets[n] = {p.relative_to(out).as_posix(): cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
                     for p in sorted((out / "pictures").rglob("*.png"))}
    assert runs["1"] == runs["4"]
    assert sheets["1"] and sheets["1"].keys() == sheets["4"].keys()
    for k, a in sheets["1"].items():
        assert np.array_equal(a, sheets["4"][k]), k


def test_pictures_read_each_depth_back_once(tmp_path, ctx, monkeypatch):
    """The methods of a view share pre's depth: the picture jobs read each image's depth back once,
    not once per method."""
    import r360gpu.render.sources as sources
    from r360gpu.pipeline.stages import gather, measure, picture_jobs, render_on_device

    bundle = load_bundle(_small_benchmark(tmp_path / "b", ctx)[0])
    sem, stru = default_probes()
    run = SceneRun(bundle, EvaluateOptions(**OPTS), ctx, sem, stru, cache=RunCache(None), timer=Timer())
    sink = PictureSink(tmp_path / "o", True)
    data = gather(run, render_on_device(run, run.views[0]))
    cells, geos = measure(run, data, sink)
    calls = []
    real = sources.host_depth
    monkeypatch.setattr(sources, "host_depth", lambda depth, c: calls.append(id(depth)) or real(depth, c))
    jobs = picture_jobs(run, data, geos, cells)
    run.release()
    assert len(jobs) == len(bundle.methods) >= 3
    assert sorted(calls) == sorted(set(calls)) and len(calls) == len(bundle.methods) + 1  # pre + each method
