"""``inpaint`` with methods given as splat scenes, rendered at the benchmark's test cameras: on a generated
360-USID-shaped scene (photographs = the clean reference rendered at the test cameras of a COLMAP model),
every value equals rendering with r360gpu and scoring the renders (as a folder in compat mode, in memory
in default mode) to 1e-6; a scene in another world frame scores through its frame; cameras that cannot
be matched to the photographs exit 2 naming the file."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from PIL import Image

from r360gpu.cli import main
from r360gpu.io import load_gaussians
from r360gpu.io.inpaint_folders import natsorted_glob, read_image, read_mask_binary
from r360gpu.io.photo_cameras import photo_cameras
from r360gpu.metrics.inpainting import METRICS, score_views
from r360gpu.metrics.json_values import dec_tree
from r360gpu.pipeline.inpaint import quantised
from r360gpu.render.sources import SceneSource
from r360gpu.synthetic.frames import moved_gaussians, random_similarity
from r360gpu.synthetic.inpaint_splats import write_usid_splat_example

TOL = 1e-6


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    return write_usid_splat_example(tmp_path_factory.mktemp("splats") / "ex", n_test=3, n_train=2)


@pytest.fixture
def folder(example, tmp_path):
    dst = tmp_path / "ex"
    shutil.copytree(example, dst)
    return dst


def _args(root, out, *extra, methods=("hole", "reference")):
    return ["inpaint", "360usid", str(root / "data"), *(f"{m}={root}/output/{{scene}}/{m}.ply" for m in methods),
            "--masks", f"{root}/output/{{scene}}/object_mask", "--out", str(out), "--quiet", *extra]


def _doc(out):
    return dec_tree(json.loads((out / "results.json").read_text()))


def _renders(root, method):
    """The method rendered by r360gpu at the test cameras of the scene's COLMAP model."""
    scene = root / "data" / "room"
    photos = natsorted_glob(scene / "test_images", "jpg")
    src = SceneSource(str(root / "output" / "room" / f"{method}.ply"))
    try:
        return photos, [src.images(p.name, c).rgb for p, c in zip(photos, photo_cameras(photos, scene))]
    finally:
        src.release()


def test_default_mode_equals_rendering_then_scoring(example, tmp_path):
    out = tmp_path / "out"
    assert main(_args(example, out)) == 0
    doc = _doc(out)
    src = doc["sources"]["room"]["hole"]
    assert src["kind"] == "scene" and src["path"].endswith("hole.ply") and src["cameras"].endswith("room")
    for method in ("hole", "reference"):
        photos, renders = _renders(example, method)
        masks = natsorted_glob(example / "output" / "room" / "object_mask", ".png")
        views = doc["scenes"]["room"][method]["views"]
        for p, r, m, v in zip(photos, renders, masks, views):
            photo = read_image(p)
            want = score_views(p.name, photo, [r], [read_mask_binary(m, photo.shape[:2])])[0]
            assert v["view"] == p.name
            for name, _ in METRICS:
                got, ref = v[name], getattr(want, name)
                assert (got is None and ref is None) or abs(got - ref) <= TOL, (method, p.name, name)
    means = {m: doc["scenes"]["room"][m]["means"]["masked_psnr"]["mean"] for m in ("hole", "reference")}
    assert means["reference"] > means["hole"] + 10  # the clean reference is the photographs up to JPEG


def test_compat_equals_the_renders_saved_as_a_folder(example, tmp_path):
    """compat: the splat's renders are 8-bit as the benchmark's saved renders; scoring them as a folder agrees."""
    folder = tmp_path / "hole_renders"
    _, renders = _renders(example, "hole")
    (folder / "room" / "renders").mkdir(parents=True)
    for k, r in enumerate(renders):
        q = np.round(quantised(r) * 255).astype(np.uint8)
        Image.fromarray(q).save(folder / "room" / "renders" / f"{k:05d}.png")
    assert main(_args(example, tmp_path / "a", "--compat", methods=("hole",))) == 0
    args = ["inpaint", "360usid", str(example / "data"), f"hole={folder}", "--masks",
            f"{example}/output/{{scene}}/object_mask", "--out", str(tmp_path / "b"), "--quiet", "--compat"]
    assert main(args) == 0
    a, b = _doc(tmp_path / "a")["scenes"]["room"]["hole"], _doc(tmp_path / "b")["scenes"]["room"]["hole"]
    for va, vb in zip(a["views"], b["views"]):
        for name, _ in METRICS:
            assert va[name] == pytest.approx(vb[name], abs=TOL, nan_ok=True), name


def test_a_scene_in_its_own_world_frame(example, tmp_path):
    """A splat exported in a nerfstudio frame (dataparser_transforms.json beside it) renders at the same views."""
    frame = random_similarity(np.random.default_rng(3), scale=(0.5, 2.0), shift=1.0)
    moved = tmp_path / "moved"
    moved.mkdir()
    from r360gpu.io import save_ply

    g = load_gaussians(example / "output" / "room" / "hole.ply")
    assert g.sh_degree == 0
    save_ply(moved / "hole.ply", moved_gaussians(g, frame))
    (moved / "dataparser_transforms.json").write_text(json.dumps(
        {"transform": (frame.m[:3] / frame.scale).tolist(), "scale": frame.scale}))
    assert main(_args(example, tmp_path / "a", methods=("hole",))) == 0
    args = ["inpaint", "360usid", str(example / "data"), f"hole={moved}/hole.ply", "--masks",
            f"{example}/output/{{scene}}/object_mask", "--out", str(tmp_path / "b"), "--quiet"]
    assert main(args) == 0
    b = _doc(tmp_path / "b")
    assert "nerfstudio" in b["sources"]["room"]["hole"]["frame"]["origin"]
    a = _doc(tmp_path / "a")["scenes"]["room"]["hole"]["means"]
    assert abs(a["psnr"]["mean"] - b["scenes"]["room"]["hole"]["means"]["psnr"]["mean"]) < 0.05
    assert main([*args[:-1], "--frame", "cameras", "--quiet"]) == 0  # ignoring the frame renders elsewhere
    c = _doc(tmp_path / "b")["scenes"]["room"]["hole"]["means"]
    assert c["psnr"]["mean"] < a["psnr"]["mean"] - 1


def _fails(capsys, args, *needles):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    for n in needles:
        assert str(n) in err, err


def test_photograph_without_a_camera(folder, tmp_path, capsys):
    photo = folder / "data" / "room" / "test_images" / "IMG_2.jpg"
    photo.rename(photo.with_name("IMG_99.jpg"))
    out = tmp_path / "out"
    _fails(capsys, _args(folder, out), "IMG_99.jpg", "no camera")
    assert not out.exists()


def test_no_colmap_model_and_wrong_aspect(folder, tmp_path, capsys):
    out = tmp_path / "out"
    photo = folder / "data" / "room" / "test_images" / "IMG_0.jpg"
    Image.open(photo).crop((0, 0, 40, 40)).save(photo)
    _fails(capsys, _args(folder, out), photo, "aspect ratio")
    shutil.rmtree(folder / "data" / "room" / "sparse")
    _fails(capsys, _args(folder, out), folder / "data" / "room", "--cameras")
    _fails(capsys, _args(folder, out, "--cameras", str(tmp_path / "nope")), tmp_path / "nope")
    assert not out.exists()


def test_unreadable_splat_file(folder, tmp_path, capsys):
    bad = folder / "output" / "room" / "hole.ply"
    bad.write_bytes(b"ply\nformat nonsense\n")
    _fails(capsys, _args(folder, tmp_path / "out"), bad)
    assert not (tmp_path / "out").exists()


def test_spinnerf_scene_renders_at_its_colmap_cameras(example, tmp_path):
    """SPIn-NeRF: the first --n-test photographs of images/ matched to the scene's sparse/0 by name."""
    scene = tmp_path / "spin" / "room"
    shutil.copytree(example / "data" / "room" / "test_images", scene / "images")
    shutil.copytree(example / "data" / "room" / "sparse", scene / "sparse")
    (scene / "images" / "label").mkdir()
    for k, p in enumerate(natsorted_glob(scene / "images", "jpg")):
        shutil.copy(example / "output" / "room" / "object_mask" / f"{k:05d}.png",
                    scene / "images" / "label" / f"{p.stem}.png")
    assert main(["inpaint", "spinnerf", str(scene), f"hole={example}/output/room/hole.ply", "--n-test", "3",
                 "--out", str(tmp_path / "s"), "--quiet"]) == 0
    assert main(_args(example, tmp_path / "u", methods=("hole",))) == 0
    s, u = _doc(tmp_path / "s")["scenes"]["room"]["hole"], _doc(tmp_path / "u")["scenes"]["room"]["hole"]
    assert [v["view"] for v in s["views"]] == [v["view"] for v in u["views"]]
    for a, b in zip(s["views"], u["views"]):
        for name, _ in METRICS:
            assert a[name] == pytest.approx(b[name], abs=TOL, nan_ok=True), name


def test_lifted_target_masks_when_the_method_has_none(example, tmp_path):
    """--pre/--target: the target's masks rendered at the test cameras score as those masks given as a folder."""
    from r360gpu.io.inpaint_folders import usid_scenes
    from r360gpu.lift.masks import TargetMaskRenderer
    from r360gpu.pipeline.inpaint_target import LIFTED_NOTE

    out = tmp_path / "lifted"
    target = f"{example}/output/{{scene}}/target.npy"
    args = ["inpaint", "360usid", str(example / "data"), f"hole={example}/output/{{scene}}/hole.ply",
            "--pre", f"{example}/output/{{scene}}/pre.ply", "--target", target, "--quiet"]
    assert main([*args, "--out", str(out)]) == 0
    doc = _doc(out)
    rec = doc["lifted_targets"]["room"]
    pre = load_gaussians(example / "output" / "room" / "pre.ply")
    idx = np.load(example / "output" / "room" / "target.npy")
    assert rec["source"] == "indices" and rec["gaussians"] == idx.size and rec["of"] == pre.n
    assert doc["scenes"]["room"]["hole"]["masks"].startswith("lifted target")
    assert "lifted target" in (out / "report.html").read_text()
    # the same masks rendered here, written as a folder and given with --masks
    cams = usid_scenes(example / "data", ["x=" + str(example / "output" / "room" / "hole.ply")])[0].cameras
    sel = np.zeros(pre.n, bool)
    sel[idx] = True
    r = TargetMaskRenderer(pre, sel)
    folder = tmp_path / "masks" / "room"
    folder.mkdir(parents=True)
    try:
        for k, c in enumerate(cams):
            m = r.mask(c)
            Image.fromarray(np.where(m, 255, 0).astype(np.uint8)).save(folder / f"{k:05d}.png")
            given = read_mask_binary(example / "output" / "room" / "object_mask" / f"{k:05d}.png", m.shape)
            if given.any():
                assert (m & (given > 0)).sum() / (m | (given > 0)).sum() > 0.7  # the object, as the scene's own masks
    finally:
        r.release()
    assert main([*args[:4], "--masks", str(folder.parent), "--quiet", "--out", str(tmp_path / "given")]) == 0
    a, b = doc["scenes"]["room"]["hole"], _doc(tmp_path / "given")["scenes"]["room"]["hole"]
    for va, vb in zip(a["views"], b["views"]):
        for name, _ in METRICS:
            assert va[name] == pytest.approx(vb[name], abs=TOL, nan_ok=True), name
    assert LIFTED_NOTE in a["masks"]


def test_lifted_target_hostile(folder, tmp_path, capsys):
    base = ["inpaint", "360usid", str(folder / "data"), f"hole={folder}/output/{{scene}}/hole.ply", "--quiet",
            "--out", str(tmp_path / "out")]
    pre = f"{folder}/output/{{scene}}/pre.ply"
    _fails(capsys, [*base, "--pre", pre], "--pre and --target")
    _fails(capsys, [*base, "--pre", pre, "--target", str(tmp_path / "none.npy")], tmp_path / "none.npy")
    _fails(capsys, [*base, "--pre", pre, "--target", "box:1,2,3"], "6 numbers")
    bad = folder / "output" / "room" / "target.npy"
    np.save(bad, np.array([10 ** 9]))
    _fails(capsys, [*base, "--pre", pre, "--target", str(bad)], bad)
    assert not (tmp_path / "out").exists()


def test_lifted_target_from_masks_of_some_cameras(example, tmp_path):
    """--target masks:FOLDER lifts <image stem>.png masks (here the test views', renamed) onto pre's Gaussians."""
    folder = tmp_path / "object_masks"
    folder.mkdir()
    for k, p in enumerate(natsorted_glob(example / "data" / "room" / "test_images", "jpg")):
        shutil.copy(example / "output" / "room" / "object_mask" / f"{k:05d}.png", folder / f"{p.stem}.png")
    out = tmp_path / "out"
    assert main(["inpaint", "360usid", str(example / "data" / "room"), f"hole={example}/output/room/hole.ply",
                 "--pre", f"{example}/output/room/pre.ply", "--target", f"masks:{folder}", "--quiet",
                 "--out", str(out)]) == 0
    doc = _doc(out)
    rec = doc["lifted_targets"]["room"]
    idx = set(np.load(example / "output" / "room" / "target.npy").tolist())
    assert rec["source"] == "masks" and rec["lifted_from"] and 0.5 * len(idx) < rec["gaussians"] < 2 * len(idx)
    assert doc["scenes"]["room"]["hole"]["means"]["masked_psnr"]["n"] >= 1


def _orbit_args(root, out, *extra):
    o = f"{root}/output/{{scene}}"
    return ["inpaint", "360usid", str(root / "data"), f"hole={o}/hole.ply", "--pre", f"{o}/pre.ply",
            "--target", f"{o}/target.npy", "--reference", f"{o}/reference.ply", "--quiet", "--out", str(out), *extra]


def test_orbit_against_the_reference_reconstruction(example, tmp_path):
    """--orbit: at the orbit poses of score --orbit, the method's render scored against the reference's
    render equals rendering both with r360gpu and scoring them (1e-6); its own table, marked."""
    from r360gpu.io.inpaint_folders import usid_scenes
    from r360gpu.pipeline.inpaint_target import scene_bundle
    from r360gpu.pipeline.orbit import orbit_bundle

    out = tmp_path / "out"
    assert main(_orbit_args(example, out, "--orbit", "6")) == 0
    doc = _doc(out)
    o = doc["orbit"]["room"]
    assert o["against"] == "against the reference reconstruction, not photographs" and o["requested"] == 6
    assert o["kept"] >= 2 and o["kept"] + sum(o["dropped"].values()) == 6
    assert "against the reference reconstruction, not photographs" in (out / "tables.md").read_text()
    assert "inpaint_orbit" in (out / "tables.tex").read_text()
    scene = usid_scenes(example / "data", [f"hole={example}/output/{{scene}}/hole.ply"])[0]
    o_ = f"{example}/output/{{scene}}"
    bundle = scene_bundle(scene, f"{o_}/pre.ply", f"{o_}/target.npy", None, reference=f"{o_}/reference.ply",
                          methods={"hole": f"{o_}/hole.ply"})
    orbit, _ = orbit_bundle(bundle, 6)
    cams = [orbit.cameras[v] for v in orbit.views]
    views = o["methods"]["hole"]["views"]
    assert [v["view"] for v in views] == [c.name for c in cams]
    ref, hole = (SceneSource(str(example / "output" / "room" / f"{n}.ply")) for n in ("reference", "hole"))
    try:
        for c, v in zip(cams, views):
            want = score_views(c.name, ref.images(c.name, c).rgb, [hole.images(c.name, c).rgb],
                               [orbit.masks[c.name].astype(np.float64)])[0]
            for name, _ in METRICS:
                got, exp = v[name], getattr(want, name)
                assert (got is None and exp is None) or abs(got - exp) <= TOL, (c.name, name)
    finally:
        ref.release()
        hole.release()
    assert doc["scenes"]["room"]["hole"]["means"]["psnr"]["n"] == 3  # the photographs' table is unchanged


def test_orbit_hostile_and_renders_only(example, tmp_path, capsys):
    no_ref = _orbit_args(example, tmp_path / "a", "--orbit", "4")
    i = no_ref.index("--reference")
    _fails(capsys, no_ref[:i] + no_ref[i + 2:], "--orbit needs --reference")
    bad = _orbit_args(example, tmp_path / "a", "--orbit", "4")
    bad[bad.index("--reference") + 1] = str(tmp_path / "none.ply")
    _fails(capsys, bad, tmp_path / "none.ply")
    assert not (tmp_path / "a").exists()
    renders = tmp_path / "r" / "room" / "renders"
    renders.mkdir(parents=True)
    for p in natsorted_glob(example / "data" / "room" / "test_images", "jpg"):
        shutil.copy(p, renders / (p.stem + ".png"))
    args = _orbit_args(example, tmp_path / "b", "--orbit", "4")
    args.insert(4, f"photos={tmp_path / 'r'}")
    assert main(args) == 0
    assert _doc(tmp_path / "b")["orbit"]["room"]["no_orbit"] == {"photos": "no orbit (renderings only)"}


def _llff_scene(example, root):
    """A SPIn-NeRF scene with LLFF's poses_bounds.npy (rows: the images in sorted order) and no COLMAP model."""
    from r360gpu.io import load_cameras

    scene = root / "room"
    shutil.copytree(example / "data" / "room" / "test_images", scene / "images")
    cams = {c.name: c for c in load_cameras(example / "data" / "room")}
    rows = []
    for p in sorted((scene / "images").iterdir()):
        c = cams[p.name]
        m = c.camera_to_world
        cols = [m[:3, 1], m[:3, 0], -m[:3, 2], m[:3, 3], [c.height, c.width, c.fx]]  # down, right, back, centre, hwf
        rows.append(np.concatenate([np.stack(cols, 1).reshape(-1), [0.1, 10.0]]))
    np.save(scene / "poses_bounds.npy", np.array(rows))
    return scene


def test_spinnerf_llff_poses_bounds(example, tmp_path, capsys):
    """Without sparse/0, LLFF's poses_bounds.npy places the test cameras: the same values as the COLMAP model."""
    scene = _llff_scene(example, tmp_path / "spin")
    masks = tmp_path / "m"
    masks.mkdir()
    for k, p in enumerate(natsorted_glob(scene / "images", "jpg")):
        shutil.copy(example / "output" / "room" / "object_mask" / f"{k:05d}.png", masks / f"{p.stem}.png")
    args = ["inpaint", "spinnerf", str(scene), f"hole={example}/output/room/hole.ply", "--n-test", "3", "--masks",
            str(masks), "--quiet"]
    assert main([*args, "--out", str(tmp_path / "s")]) == 0
    assert main(_args(example, tmp_path / "u", methods=("hole",))) == 0
    s, u = _doc(tmp_path / "s")["scenes"]["room"]["hole"], _doc(tmp_path / "u")["scenes"]["room"]["hole"]
    assert _doc(tmp_path / "s")["sources"]["room"]["hole"]["cameras"] == str(scene)
    for a, b in zip(s["views"], u["views"]):
        for name, _ in METRICS:
            assert a[name] == pytest.approx(b[name], abs=TOL, nan_ok=True), name
    pb = scene / "poses_bounds.npy"
    np.save(pb, np.load(pb)[:2])
    _fails(capsys, [*args, "--out", str(tmp_path / "x")], pb, "2 poses but 3 images")
    np.save(pb, np.zeros((3, 15)))
    _fails(capsys, [*args, "--out", str(tmp_path / "x")], pb, "(N, 17)")
    assert not (tmp_path / "x").exists()


def test_inria_output_folder_as_a_method(example, tmp_path):
    """METHOD=an INRIA output folder: its highest point_cloud/iteration_* is rendered, as score opens it."""
    run = tmp_path / "inria" / "room"
    for it, src in ((7000, "pre"), (30000, "hole")):
        (run / "point_cloud" / f"iteration_{it}").mkdir(parents=True)
        shutil.copy(example / "output" / "room" / f"{src}.ply",
                    run / "point_cloud" / f"iteration_{it}" / "point_cloud.ply")
    args = ["inpaint", "360usid", str(example / "data"), f"hole={tmp_path}/inria/{{scene}}", "--masks",
            f"{example}/output/{{scene}}/object_mask", "--quiet", "--out", str(tmp_path / "a")]
    assert main(args) == 0
    assert main(_args(example, tmp_path / "b", methods=("hole",))) == 0
    a, b = _doc(tmp_path / "a"), _doc(tmp_path / "b")
    assert a["sources"]["room"]["hole"]["path"].endswith("iteration_30000/point_cloud.ply")
    assert a["scenes"]["room"]["hole"]["views"] == b["scenes"]["room"]["hole"]["views"]
