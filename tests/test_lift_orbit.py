"""Orbit scoring (--orbit N): cameras around the lifted target, dropped poses, results under
scenes.S.orbit, and the synthetic ``backside`` method that only an orbit catches."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io.camera import Camera
from r360gpu.lift.orbit import capture_up, keep_pose, orbit_cameras
from r360gpu.synthetic import make_scene


def _capture(n=5):
    """A capture arc of 120 degrees at elevations 15..35 degrees, z up, around (1, 2, 0.5)."""
    centre = np.array([1.0, 2.0, 0.5])
    cams = []
    for i in range(n):
        az = np.deg2rad(-60 + 120 * i / (n - 1))
        el = np.deg2rad(15 + 20 * i / (n - 1))
        d = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        eye = centre + (3.0 + 0.2 * i) * d
        fwd = -d
        right = np.cross(fwd, [0, 0, 1.0])
        right /= np.linalg.norm(right)
        c2w = np.eye(4)
        c2w[:3, :3] = np.stack([right, np.cross(fwd, right), fwd], 1)
        c2w[:3, 3] = eye
        cams.append(Camera.from_camera_to_world(c2w, 100.0 + i, 100.0 + i, 40, 30, 80, 60, f"c{i}"))
    return centre, cams


def test_orbit_cameras_ring_the_target_in_the_capture_band():
    centre, cams = _capture()
    assert np.allclose(capture_up(cams), [0, 0, 1], atol=1e-9)
    orbit = orbit_cameras(centre, cams, 16)
    assert [c.name for c in orbit[:2]] == ["orbit_000", "orbit_001"] and len(orbit) == 16
    dist = np.median([np.linalg.norm(c.center - centre) for c in cams])
    for c in orbit:
        off = c.center - centre
        assert np.linalg.norm(off) == pytest.approx(dist)
        el = np.degrees(np.arcsin(off[2] / np.linalg.norm(off)))
        assert 15 - 1e-6 <= el <= 35 + 1e-6
        uv, z = c.project(centre[None])  # looks at the centre
        assert np.allclose(uv[0], (c.cx, c.cy)) and z[0] > 0
        assert (c.fx, c.width, c.height) == (cams[2].fx, 80, 60)  # the median-focal camera's intrinsics
    az = np.sort(np.degrees(np.arctan2(*[np.array([c.center[k] - centre[k] for c in orbit]) for k in (1, 0)])))
    assert np.diff(np.r_[az, az[0] + 360]).max() < 60  # all the way round, no gap as wide as the capture's
    with pytest.raises(InputError, match="from 1 to"):
        orbit_cameras(centre, cams, 0)
    with pytest.raises(InputError, match="evaluation cameras"):
        orbit_cameras(centre, [], 4)


def test_keep_pose_reasons():
    alpha = np.ones((4, 4))
    depth = np.full((4, 4), 5.0)
    sil = np.zeros((4, 4), bool)
    sil[1:3, 1:3] = True
    assert keep_pose(alpha, depth, sil, sil, 5.0) is None
    assert keep_pose(alpha, np.full((4, 4), 0.5), sil, sil, 5.0) == "inside geometry"
    half = sil.copy()
    half[1, 1:3] = False
    assert keep_pose(alpha, depth, half, sil, 5.0) is None  # half the silhouette is still "seen"
    half[2, 1] = False
    assert keep_pose(alpha, depth, half, sil, 5.0) == "target occluded"
    assert keep_pose(alpha, depth, sil, np.zeros((4, 4), bool), 5.0) == "target occluded"


def test_backside_film_is_ground_from_the_capture_and_target_from_behind():
    from r360gpu.io.sh import sh_to_color
    from r360gpu.synthetic.methods import backside_sh

    front = np.array([0.0, -1.0, 0.0])
    ground, own = np.array([[0.2, 0.5, 0.3]]), np.array([[0.9, 0.1, 0.1]])
    sh = backside_sh(ground, own, front)
    # view direction d: camera -> Gaussian; the capture stands at +front, so it looks along -front.
    from_capture = sh_to_color(sh, -front[None])
    from_behind = sh_to_color(sh, front[None])
    assert np.allclose(from_capture, ground, atol=1e-6) and np.allclose(from_behind, own, atol=1e-6)
    slanted = -np.array([[np.sin(np.radians(65)), -np.cos(np.radians(65)), 0.0]])  # 65 degrees off the front
    assert np.abs(sh_to_color(sh, slanted) - ground).max() < 0.03 * np.abs(own - ground).max()


def _score_with_orbit(tmp_path_factory, ctx, scene: str) -> dict:
    """The synthetic ``scene`` (8 views, 240x180, detail 0.25), clean and backside, scored with --orbit 12."""
    from r360gpu.bundle import load_bundle
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.synthetic import generate_benchmark

    root = tmp_path_factory.mktemp(f"orbit_{scene}")
    b = generate_benchmark(root, seed=0, n_views=8, width=240, height=180, scenes=(scene,), detail=0.25,
                           methods=("clean", "backside"), ctx=ctx)[0]
    opts = EvaluateOptions(n_boot=200, n_perm=100, orbit=12, pictures=False, boundary=False)
    return evaluate(load_bundle(b), options=opts, device=ctx, progress=False)


@pytest.fixture(scope="module")
def scored(tmp_path_factory, ctx):
    return _score_with_orbit(tmp_path_factory, ctx, "garden")


def test_orbit_results_sit_beside_the_capture_axes(scored):
    s = scored["scenes"]["garden"]
    orbit = s["orbit"]
    assert orbit["requested"] == 12 and orbit["kept"] + sum(orbit["dropped"].values()) == 12 and orbit["kept"] >= 4
    assert set(orbit["dropped"]) <= {"inside geometry", "target occluded"}
    assert all(v.startswith("orbit_") for v in orbit["views"]) and orbit["no_orbit"] == {}
    # the frame check runs on the capture's cameras only: the orbit's poses are derived from them
    assert s["frame_check"]["pre"]["level"] == "ok" and "frame_check" not in orbit
    for m in ("clean", "backside"):
        a = orbit["methods"][m]["axes"]
        assert a["rqs"] is not None and 0 <= a["rqs"] <= 1
        # The capture-view axes are the scene's own: no orbit view among them.
        assert not any(r["view"].startswith("orbit_") for r in s["methods"][m]["views"])
    print({w: {m: round(e["methods"][m]["axes"]["rqs"], 3) for m in ("clean", "backside")}
           for w, e in (("capture", s), ("orbit", orbit))}, orbit["dropped"])
    assert [w["scene"] for w in scored["warnings"] if "orbit" in w["message"]] in ([], ["garden"])


def test_report_shows_capture_vs_orbit(scored):
    from r360gpu.report.orbit_table import orbit_table
    from r360gpu.report.tables import render_markdown

    t = orbit_table(scored)
    text = render_markdown(t)
    assert "capture RQS" in text and "orbit RQS" in text and "worst orbit views" in text
    assert len(t.rows) == 2
    assert orbit_table({"scenes": {"a": {"methods": {}}}}) is None
    # and on the console: the poses, then each method's capture -> orbit axes
    from r360gpu.report.outputs import summary_lines

    orbit = scored["scenes"]["garden"]["orbit"]
    text = "\n".join(summary_lines(scored))
    assert f"  garden: {orbit['kept']} of 12 poses scored" in text
    for m in ("clean", "backside"):
        assert f"  garden / {m}: s_sem " in text
        assert f"RQS {scored['scenes']['garden']['methods'][m]['axes']['rqs']:.3f} -> " \
               f"{orbit['methods'][m]['axes']['rqs']:.3f}" in text


def test_renderings_only_methods_have_no_orbit(tmp_path, ctx):
    from r360gpu.bundle.model import SourceSpec
    from r360gpu.pipeline.orbit import RENDERINGS_ONLY, orbit_bundle
    from r360gpu.bundle.objects import scene_from_objects

    scene = make_scene("garden", n_views=4, width=64, height=48, detail=0.1)
    idx = np.arange(scene.background.n, scene.pre.n)
    b = scene_from_objects("g", "bench", {}, scene.pre, {"clean": scene.background,
                                                        "given": SourceSpec("renders", tmp_path)},
                           cameras={c.name: c for c in scene.cameras}, target={"indices": idx})
    orbit, info = orbit_bundle(b, 4, ctx=ctx)
    assert info["no_orbit"] == {"given": RENDERINGS_ONLY}
    assert orbit is None or set(orbit.methods) == {"clean"}


@pytest.fixture(scope="module")
def open_space(tmp_path_factory, ctx):
    """The bench in open space (garden_open: no wall behind it), clean and backside, with an orbit."""
    return _score_with_orbit(tmp_path_factory, ctx, "garden_open")


def _per_view(entry: dict, method: str, xis=(0.3,)) -> dict:
    """{view: single-view axes} of one method of a scene entry."""
    from r360gpu.aggregate.results import method_axes
    from r360gpu.metrics.record import ViewRecord

    return {d["view"]: method_axes([ViewRecord.from_dict(d)], xis=xis) for d in entry["methods"][method]["views"]}


def test_the_capture_misses_the_backside_and_the_orbit_catches_it(open_space):
    from r360gpu.protocol import AXES

    s = open_space["scenes"]["garden_open"]
    orbit = s["orbit"]
    cap = {m: s["methods"][m]["axes"] for m in ("clean", "backside")}
    orb = {m: orbit["methods"][m]["axes"] for m in ("clean", "backside")}
    for where, axes in (("capture", cap), ("orbit", orb)):
        print(f"garden_open {where}: " + "; ".join(
            f"{m} " + " ".join(f"{a} {axes[m][a]:.3f}" for a in (*AXES, "rqs")) for m in ("clean", "backside")))
    print(f"orbit poses kept {orbit['kept']} of {orbit['requested']}, dropped {orbit['dropped']}")
    drops = {}
    for where, entry in (("capture", s), ("orbit", orbit)):
        c, b = _per_view(entry, "clean"), _per_view(entry, "backside")
        drops[where] = {v: round(c[v]["s_str"] - b[v]["s_str"], 3) for v in c
                        if c[v]["s_str"] is not None and b[v]["s_str"] is not None}
        print(f"per-view s_str drop (clean - backside), {where}: {drops[where]}")
    # the axes: at the capture views backside scores as the clean removal, around the target it does not
    d_cap = {a: cap["clean"][a] - cap["backside"][a] for a in ("s_str", "rqs")}
    d_orb = {a: orb["clean"][a] - orb["backside"][a] for a in ("s_str", "rqs")}
    assert orbit["kept"] >= 8  # in open space almost every pose sees the bench
    assert abs(d_cap["rqs"]) <= 0.03 and abs(d_cap["s_str"]) <= 0.06
    assert d_orb["s_str"] >= 0.12 and d_orb["s_str"] >= 3 * abs(d_cap["s_str"])
    assert d_orb["rqs"] >= 0.035 and d_orb["rqs"] >= 2 * abs(d_cap["rqs"])


def test_the_backside_film_is_invisible_from_the_capture_and_plain_from_the_orbit(ctx):
    """The pixels themselves: inside the target's silhouette, backside's renders differ from clean's
    about as much as two clean removals do (their re-optimisation noise) at the capture views, and
    several times more at orbit views behind the bench."""
    from r360gpu.render import Renderer
    from r360gpu.synthetic import make_method

    scene = make_scene("garden_open", n_views=8, width=240, height=180, detail=0.25)
    centre = np.asarray(scene.target.means, np.float64).mean(0)
    rings = {"capture": list(scene.cameras), "orbit": orbit_cameras(centre, list(scene.cameras), 12)}
    clean, other, back, alone = (Renderer(g, ctx=ctx) for g in (
        make_method(scene, "clean"), make_method(scene, "clean", seed=1), make_method(scene, "backside"),
        scene.target))
    diff, floor = {}, {}
    try:
        for where, cams in rings.items():
            diff[where], floor[where] = [], []
            for cam in cams:
                sil = alone.render(cam).alpha > 0.5
                if sil.sum() >= 50:  # the view frames the target
                    c = clean.render(cam).rgb
                    for out, g in ((diff, back), (floor, other)):
                        out[where].append(float(np.abs(c - g.render(cam).rgb).max(axis=-1)[sil].mean()))
    finally:
        for r in (clean, other, back, alone):
            r.release()
    for name, d in (("backside - clean", diff), ("clean seed 1 - clean", floor)):
        print(f"mean |RGB {name}| in the silhouette, per view: "
              + "; ".join(f"{w}: " + " ".join(f"{x:.3f}" for x in v) for w, v in d.items()))
    noise = max(floor["capture"] + floor["orbit"])
    # measured: capture at most 1.4x the noise (the film's faint tint and 1 cm lift), orbit up to 4.3x
    assert max(diff["capture"]) <= 1.6 * noise
    assert max(diff["orbit"]) >= 3.5 * noise and sum(x >= 2.5 * noise for x in diff["orbit"]) >= 3
