"""A method given as renderings is scored at the orbit from its renderings at the orbit poses (``orbit =
"FOLDER"``: rgb/, depth/ and the cameras.json they were made at), as a splat method is; renderings
made at other poses, missing or of another size are a clear error naming the folder."""
from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from r360gpu import cli
from r360gpu.bundle import check_bundle, load_bundle
from r360gpu.errors import InputError
from r360gpu.io.cameras_json import load_cameras_json, save_cameras_json
from r360gpu.synthetic import generate_benchmark

ARGS = dict(seed=0, n_views=4, width=64, height=48, detail=0.25)
ORBIT = 4


def render_to(folder, scene_file, cameras, frame=None):
    """``scene_file`` rendered at ``cameras`` into ``folder``/rgb (16-bit PNG) and depth (.npy): the
    stand-in for a method's own renderer."""
    from r360gpu.render.sources import SceneSource

    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    src = SceneSource(str(scene_file), frame=frame)
    try:
        for cam in cameras:
            img = src.images(cam.name, cam)
            rgb16 = np.round(img.rgb * 65535).astype(np.uint16)
            cv2.imwrite(str(folder / "rgb" / f"{cam.name}.png"), cv2.cvtColor(rgb16, cv2.COLOR_RGB2BGR))
            np.save(folder / "depth" / f"{cam.name}.npy", img.depth)
    finally:
        src.release()


def score(bundle, out, ctx):
    from r360gpu.pipeline import EvaluateOptions, evaluate

    opts = EvaluateOptions(n_boot=20, n_perm=10, orbit=ORBIT, pictures=False, boundary=False, controls=False)
    return evaluate(load_bundle(bundle), out=out, device=ctx, progress=False, options=opts)["scenes"]["room"]


@pytest.fixture(scope="module")
def scored(tmp_path_factory, ctx):
    """The room with ``clean`` as a splat file and ``given``: clean rendered at the capture views and
    (from the first run's orbit cameras.json) at the orbit poses, declared with ``orbit``."""
    root = tmp_path_factory.mktemp("orbit_renders")
    folder = generate_benchmark(root / "gen", scenes=("room",), methods=("clean",), ctx=ctx, **ARGS)[0]
    first = score(folder, root / "first", ctx)
    assert first["orbit"]["kept"] >= 2
    bundle = load_bundle(folder)
    clean = bundle.methods["clean"].path
    render_to(folder / "given", clean, [bundle.cameras[v] for v in bundle.views])
    poses = root / "first" / first["orbit"]["files"]["cameras"]
    render_to(folder / "given_orbit", clean, load_cameras_json(poses))
    shutil.copy(poses, folder / "given_orbit" / "cameras.json")
    with open(folder / "scene.toml", "a") as f:
        f.write('\n[methods.given]\nrenders = "given"\norbit = "given_orbit"\n')
    return root, folder, first, score(folder, root / "second", ctx)


def test_renderings_at_the_orbit_poses_are_scored_as_the_splat_file_is(scored):
    _, _, first, second = scored
    orbit = second["orbit"]
    assert "given" not in orbit.get("no_orbit", {}) and set(orbit["methods"]) == {"clean", "given"}
    views = [v["view"] for v in orbit["methods"]["given"]["views"]]
    assert views == [v["view"] for v in orbit["methods"]["clean"]["views"]] == first["orbit"]["views"]
    a, b = orbit["methods"]["given"]["axes"], orbit["methods"]["clean"]["axes"]
    # the same scene through a 16-bit PNG and a float32 depth file: equal to the PNG's rounding
    assert a["s_geo"] == pytest.approx(b["s_geo"], abs=1e-4)
    assert a["s_sem"] == pytest.approx(b["s_sem"], abs=1e-3) and a["s_str"] == pytest.approx(b["s_str"], abs=0.02)
    print(f"orbit of {len(views)} poses, given vs clean: " + ", ".join(f"{k} {a[k]:.4f} / {b[k]:.4f}"
                                                                  for k in ("s_sem", "s_geo", "s_str", "rqs")))


def test_a_renderings_method_without_orbit_renderings_is_still_listed_as_renderings_only(scored, tmp_path, ctx):
    from r360gpu.pipeline.orbit import RENDERINGS_ONLY

    _, folder, _, _ = scored
    b = tmp_path / "b"
    shutil.copytree(folder, b)
    (b / "scene.toml").write_text((b / "scene.toml").read_text().replace('orbit = "given_orbit"\n', ""))
    assert score(b, tmp_path / "out", ctx)["orbit"]["no_orbit"] == {"given": RENDERINGS_ONLY}


def _variant(folder, dst, edit):
    shutil.copytree(folder, dst)
    edit(dst / "given_orbit")
    return dst


def _drop_pose(orbit_dir):
    cams = load_cameras_json(orbit_dir / "cameras.json")
    save_cameras_json(orbit_dir / "cameras.json", cams[1:])
    return cams[0].name


def _move_pose(orbit_dir):
    doc = json.loads((orbit_dir / "cameras.json").read_text())
    doc[1]["position"][0] += 0.05
    (orbit_dir / "cameras.json").write_text(json.dumps(doc))
    return doc[1]["img_name"]


@pytest.mark.parametrize("edit, words", [(_drop_pose, "have no camera there"), (_move_pose, "is another camera there")])
def test_renderings_made_at_other_poses_are_an_error_naming_the_folder(scored, tmp_path, ctx, capsys, edit, words):
    _, folder, _, _ = scored
    b = tmp_path / "b"
    shutil.copytree(folder, b)
    pose = edit(b / "given_orbit")
    assert check_bundle(b) == []  # the folder is consistent in itself; the run's poses decide
    with pytest.raises(InputError) as e:
        score(b, tmp_path / "out", ctx)
    msg = str(e.value)
    assert words in msg and pose in msg and str(b / "given_orbit" / "cameras.json") in msg
    out = tmp_path / "cli"
    code = cli.main(["score", str(b), "--orbit", str(ORBIT), "--out", str(out), "--n-boot", "20", "--n-perm", "10",
                     "--no-pictures"])
    assert code == 2 and "Traceback" not in capsys.readouterr().err
    assert not (out / "results.json").exists() and not (out / "orbit").exists()


def _wrong_size(orbit_dir):
    first = sorted((orbit_dir / "rgb").glob("*.png"))[0]
    cv2.imwrite(str(first), np.zeros((10, 12, 3), np.uint8))
    return first, "is 12x10, the orbit camera"


def _missing_rgb(orbit_dir):
    first = sorted((orbit_dir / "rgb").glob("*.png"))[0]
    first.unlink()
    return orbit_dir / "rgb", f"missing RGB images of [methods.given] orbit for 1 of"


def _missing_depth(orbit_dir):
    shutil.rmtree(orbit_dir / "depth")
    return orbit_dir / "depth", "depth folder of [methods.given] orbit does not exist"


def _no_cameras(orbit_dir):
    (orbit_dir / "cameras.json").unlink()
    return orbit_dir / "cameras.json", "cameras.json its renderings were made at"


@pytest.mark.parametrize("edit", [_wrong_size, _missing_rgb, _missing_depth, _no_cameras])
def test_orbit_folder_problems_are_found_by_check_and_score(scored, tmp_path, edit, capsys):
    _, folder, _, _ = scored
    b = tmp_path / "b"
    shutil.copytree(folder, b)
    path, words = edit(b / "given_orbit")
    problems = check_bundle(b)
    assert any(p.path == str(path) and words in p.message for p in problems), problems
    code = cli.main(["score", str(b), "--orbit", str(ORBIT), "--out", str(tmp_path / "out"), "--no-pictures"])
    assert code == 2 and words in capsys.readouterr().err


@pytest.mark.parametrize("old, new, words", [
    ('scene = "methods/clean.ply"', 'scene = "methods/clean.ply"\norbit = "given_orbit"', "'orbit' applies to renders only"),
    ('orbit = "given_orbit"', "orbit = 3", "'orbit' must be a folder path"),
    ('[pre]\nscene = "pre.ply"', '[pre]\nrenders = "given"\norbit = "given_orbit"', "'orbit' applies to methods and the"),
])
def test_orbit_key_values_are_checked(scored, tmp_path, old, new, words):
    _, folder, _, _ = scored
    b = tmp_path / "b"
    shutil.copytree(folder, b)
    text = (b / "scene.toml").read_text()
    assert old in text
    (b / "scene.toml").write_text(text.replace(old, new))
    problems = check_bundle(b)
    assert any(words in p.message for p in problems), problems
