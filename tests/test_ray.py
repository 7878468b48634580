"""Scoring on Ray (r360gpu.pipeline.distributed) gives the serial run's --out, through worker and driver failures.

One local Ray instance (2 CPUs) serves the module; the two-node test starts
its own head and worker node with ``ray start`` on this machine.
"""
from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from r360gpu.cli import main
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.pipeline.distributed import FAIL_ONCE_ENV, RayExecutor, RayOptions, chunk_views

from run_compare import OPTS, scenes, serial  # noqa: F401 (module fixtures)
from run_compare import comparable as _comparable, tree as _tree, tree_differences as _tree_differences

ROOT = Path(__file__).resolve().parents[1]
CLI_STATS = ["--n-boot", "200", "--n-perm", "100"]


def test_tree_differences_name_files_and_pixels():
    import cv2
    import numpy as np

    img = np.zeros((6, 8, 3), np.uint8)
    other = img.copy()
    other[2, 5] = (0, 9, 0)
    png = lambda x: cv2.imencode(".png", x)[1].tobytes()  # noqa: E731
    a = {"p/a.png": png(img), "p/b.png": png(img), "p/c.png": b"x"}
    b = {"p/a.png": png(img), "p/b.png": png(other), "p/d.png": b"y"}
    assert _tree_differences(a, a) == []
    recompressed = {**a, "p/a.png": cv2.imencode(".png", img, [cv2.IMWRITE_PNG_COMPRESSION, 0])[1].tobytes()}
    assert _tree_differences(a, recompressed) == [  # another length: still reported, pixels equal
        f"p/a.png: {len(a['p/a.png'])} vs {len(recompressed['p/a.png'])} bytes; 0 pixels differ (at most by 0), "
        "no pixel of 8x6"]
    assert _tree_differences(a, b) == [
        "only in the first: p/c.png", "only in the second: p/d.png",
        f"p/b.png: {len(a['p/b.png'])} vs {len(b['p/b.png'])} bytes; 1 pixels differ (at most by 9), "
        "rows 2-2, columns 5-5 of 8x6"]


def test_chunks_cover_the_views_in_order():
    views = [f"v{i}" for i in range(7)]
    assert chunk_views(views, 3) == [["v0", "v1", "v2"], ["v3", "v4", "v5"], ["v6"]]
    assert chunk_views(views, 10) == [views]
    assert sum(chunk_views(views, 1), []) == views


def test_without_ray_the_flag_says_how_to_install(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray now raises ImportError
    rc = main(["score", str(tmp_path), "--out", str(tmp_path / "o"), "--ray", "local"])
    err = capsys.readouterr().err
    assert rc == 2 and "pip install 'r360gpu[ray]'" in err and "Traceback" not in err


def test_ray_flags_need_ray(tmp_path, capsys):
    assert main(["score", str(tmp_path), "--out", str(tmp_path / "o"), "--ray-chunk", "4"]) == 2
    assert "--ray-chunk need(s) --ray" in capsys.readouterr().err


@pytest.fixture(scope="module")
def marker_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fail-once")


@pytest.fixture(scope="module")
def ray_instance(marker_dir):
    """One local Ray instance for the module; its workers see the fail-once test hook's variable."""
    ray = pytest.importorskip("ray")
    if ray.is_initialized():
        ray.shutdown()
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=200 * 2**20,
             runtime_env={"env_vars": {FAIL_ONCE_ENV: str(marker_dir / "fail-once")}})
    yield ray
    ray.shutdown()


def test_two_scenes_on_ray_equal_the_serial_run(scenes, serial, ray_instance, tmp_path, capsys):
    """--ray local: results, tables, pictures and view cache are the serial run's."""
    s_out, s_res = serial
    out = tmp_path / "ray"
    rc = main(["score", *map(str, scenes), "--out", str(out), "--ray", "local", *CLI_STATS,
               "--quiet"])
    assert rc == 0, capsys.readouterr().err
    doc = json.loads((out / "results.json").read_text())
    serial_doc = json.loads((s_out / "results.json").read_text())
    assert _comparable(doc) == _comparable(serial_doc)
    # default chunk: ceil(2 views / (2 x 2 workers)) = 1 view per task
    assert doc["timing"]["executor"]["tasks"] == 4 and doc["timing"]["executor"]["views_sent"] == 4
    assert "render" in doc["timing"]["stages_s"]  # the workers' stage timings are merged
    assert (out / "tables.md").read_bytes() == (s_out / "tables.md").read_bytes()
    pictures = _tree(out, "pictures")
    assert pictures and not _tree_differences(pictures, _tree(s_out, "pictures")), \
        _tree_differences(pictures, _tree(s_out, "pictures"))
    assert _tree(out, ".r360cache/views") == _tree(s_out, ".r360cache/views")
    assert s_res["scenes"].keys() == {"room", "garden"}


def test_a_killed_worker_is_retried_with_the_same_results(scenes, serial, ray_instance, marker_dir, tmp_path):
    _, s_res = serial
    marker = marker_dir / "fail-once"
    marker.touch()  # the first task to find it ends its worker process
    ex = RayExecutor(RayOptions(chunk=1, max_retries=2), log=lambda *a: None)
    res = evaluate(scenes[:1], out=tmp_path / "o", options=EvaluateOptions(**OPTS), progress=False, executor=ex)
    assert not marker.exists()  # the hook fired: one worker died mid-run
    assert ex.tasks == 2 and len(ex.sent_views) == 2
    assert res["scenes"]["room"] == s_res["scenes"]["room"]  # a scene's entry depends on that scene alone


def test_a_killed_worker_without_retries_is_an_error(scenes, ray_instance, marker_dir, tmp_path):
    marker = marker_dir / "fail-once"
    marker.touch()
    ex = RayExecutor(RayOptions(chunk=3, max_retries=0), log=lambda *a: None)
    with pytest.raises(Exception, match="(?i)worker|died|crash|exit"):
        evaluate(scenes[:1], out=tmp_path / "o", options=EvaluateOptions(**OPTS), progress=False, executor=ex)
    assert not marker.exists()


class _DriverKilled(Exception):
    pass


def test_a_stopped_driver_resumes_without_recomputing(scenes, serial, ray_instance, tmp_path):
    _, s_res = serial
    out = tmp_path / "o"

    def stop_after_first(n):
        raise _DriverKilled(n)

    first = RayExecutor(RayOptions(chunk=1), log=lambda *a: None, on_task=stop_after_first)
    with pytest.raises(_DriverKilled):
        evaluate(scenes, out=out, options=EvaluateOptions(**OPTS), progress=False, executor=first)
    from r360gpu.bundle import load_bundle

    cached = {p.stem for p in (out / ".r360cache" / "views").glob("*/room/clean/*.json")}
    views = load_bundle(scenes[0]).views
    assert first.tasks == 1 and len(cached) == 1 and cached <= set(views)  # one task, then the driver stopped
    again = RayExecutor(RayOptions(chunk=1), log=lambda *a: None)
    res = evaluate(scenes, out=out, options=EvaluateOptions(**OPTS), progress=False, executor=again)
    sent = set(again.sent_views)
    assert not sent & {("room", v) for v in cached}  # finished views were not sent again
    assert len(sent) == 3
    assert _comparable(res) == _comparable(s_res)
    # a third run finds everything in the cache and starts no task
    third = RayExecutor(RayOptions(), log=lambda *a: None)
    evaluate(scenes, out=out, options=EvaluateOptions(**OPTS), progress=False, executor=third)
    assert third.sent_views == [] and third.tasks == 0


def test_scenes_holding_device_renders_are_refused(scenes, ray_instance, ctx):
    import r360gpu
    from r360gpu.bundle import load_bundle
    from r360gpu.errors import InputError
    from r360gpu.io import load_gaussians, load_mask
    from r360gpu.render import Renderer
    from r360gpu.render.sources import DeviceViewsSource

    b = load_bundle(scenes[0])
    v = b.views[0]
    dev = DeviceViewsSource({v: Renderer(load_gaussians(b.pre.path), ctx=ctx).render_device(b.cameras[v])}, ctx=ctx)
    scene = r360gpu.scene_from_objects("room", "sofa", {v: load_mask(b.masks[v])}, dev, {"m": dev})
    with pytest.raises(InputError, match="DeviceViewsSource"):
        evaluate(scene, device=ctx, options=EvaluateOptions(**OPTS), progress=False, executor="ray")


def test_resource_requests_are_checked(ray_instance):
    from r360gpu.errors import InputError

    ex = RayExecutor(RayOptions(gpus_per_task=1), log=lambda *a: None)
    ex.start()  # joins the module's instance (2 CPUs, no GPU)
    with pytest.raises(InputError, match="asks for 1 GPU"):
        ex._resources()
    ex.options = RayOptions(cpus_per_task=3)
    with pytest.raises(InputError, match="asks for 3 CPU"):
        ex._resources()
    ex.options = RayOptions()  # defaults: no GPU on this cluster, one CPU a task, two at once
    assert ex._resources() == (0.0, 1.0, 2)
    ex.close()
    assert ray_instance.is_initialized()  # an executor leaves alone the instance it did not start
    for bad in (dict(chunk=0), dict(cpus=0), dict(gpus_per_task=-1), dict(gpus_per_task=0, cpus_per_task=0)):
        with pytest.raises(InputError):
            RayOptions(**bad)


def test_a_worker_on_another_version_fails_clearly(scenes, ray_instance, monkeypatch):
    from r360gpu.errors import InputError
    from r360gpu.pipeline import distributed

    common = {"version": "0.0.0-other"}
    with pytest.raises(InputError, match="same version on every node"):
        distributed.score_task(common, ["view_000"])


def test_model_probes_reopen_their_files_when_sent_to_a_worker(tmp_path):
    """ONNX sessions cannot be pickled: a probe sent to a Ray worker reopens its model files by path."""
    import pickle

    import numpy as np

    pytest.importorskip("onnx")
    from onnx_graphs import sam_decoder, sam_encoder_nchw
    from r360gpu.probes.base import ProbeView
    from r360gpu.probes.sam_amg import AmgParams, SamAmgProbe

    enc = sam_encoder_nchw(tmp_path / "sam.encoder.onnx")
    dec = sam_decoder(tmp_path / "sam.decoder.onnx", iou=[0.99, 0.95, 0.92, 0.93], radius=[80, 160, 168, 240],
                      slope=[1.0, 1.0, 1.0, 1e-5])
    probe = SamAmgProbe(enc, dec, params=AmgParams(points_per_side=2))
    sent = pickle.loads(pickle.dumps(probe))
    assert sent.models.encoder.session is not probe.models.encoder.session
    assert sent.describe() == probe.describe()
    view = [ProbeView("v0", np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8), "post")]
    a, b = probe.predict(view)[0], sent.predict(view)[0]
    assert a.count == b.count > 0
    np.testing.assert_array_equal(a.masks, b.masks)
    np.testing.assert_array_equal(a.scores, b.scores)


# -- two nodes on this machine -------------------------------------------------------------------------------------

def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(path: Path, text: str, proc, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            return False
        if path.is_file() and text in path.read_text(errors="replace"):
            return True
        time.sleep(0.5)
    return False


def test_two_nodes_started_with_ray_start(scenes, serial, tmp_path):
    """A head and a worker node (``ray start``, one CPU each, loopback), the CLI as a driver joining them."""
    pytest.importorskip("ray")
    ray_cli = shutil.which("ray", path=str(Path(sys.executable).parent)) or shutil.which("ray")
    if ray_cli is None:
        pytest.skip("the ray command is not installed")
    port = _free_port()
    temp = Path(tempfile.mkdtemp(prefix="r360ray-"))  # short: Ray's socket paths must stay under 108 bytes
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    common = ["--num-cpus=1", "--node-ip-address=127.0.0.1", "--object-store-memory=100000000", "--block"]
    procs = []
    try:
        logs = {n: tmp_path / f"{n}.log" for n in ("head", "worker")}
        head = subprocess.Popen([ray_cli, "start", "--head", f"--port={port}", "--include-dashboard=false",
                                 f"--temp-dir={temp}", *common],
                                stdout=logs["head"].open("w"), stderr=subprocess.STDOUT, env=env)
        procs.append(head)
        if not _wait_for(logs["head"], "Ray runtime started", head, 120):
            pytest.skip(f"ray start --head did not start: {logs['head'].read_text()[-800:]}")
        worker = subprocess.Popen([ray_cli, "start", f"--address=127.0.0.1:{port}", *common],
                                  stdout=logs["worker"].open("w"), stderr=subprocess.STDOUT, env=env)
        procs.append(worker)
        if not _wait_for(logs["worker"], "Ray runtime started", worker, 120):
            pytest.skip(f"ray start (worker node) did not start: {logs['worker'].read_text()[-800:]}")
        out = tmp_path / "o"
        run = subprocess.run([sys.executable, "-m", "r360gpu", "score", *map(str, scenes), "--out", str(out),
                              "--ray", f"127.0.0.1:{port}", "--ray-chunk", "1", *CLI_STATS],
                             env=env, capture_output=True, text=True, timeout=400)
        assert run.returncode == 0, run.stderr[-3000:]
        assert "room on Ray: task 2/2 done" in run.stdout  # plain progress lines when not on a terminal
        doc = json.loads((out / "results.json").read_text())
        assert doc["timing"]["executor"]["nodes"] == 2  # both nodes ran tasks
        assert _comparable(doc) == _comparable(json.loads((serial[0] / "results.json").read_text()))
    finally:
        for p in reversed(procs):  # SIGTERM: ray start --block stops the processes it started
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(temp, ignore_errors=True)
