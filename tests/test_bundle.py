"""Scene bundles: scene.toml parsing, every check (all problems listed at once), the
Remove360 layout, fingerprints."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from bundle_factory import (H, SCENE_TOML, VIEWS, W, camera, make_bundle, make_remove360, write_depth_png16,
                            write_mask, write_renders, write_rgb)
from r360gpu.bundle import (Bundle, BundleError, Problem, SourceSpec, check_bundle, inspect_bundle, load_bundle,
                            view_name)
from r360gpu.errors import InputError
from r360gpu.io import random_gaussians, save_cameras_json, save_colmap, save_ply, save_transforms_json


def toml_with(**replace: str) -> str:
    text = SCENE_TOML
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    return text


def problem_text(problems: list[Problem]) -> str:
    return "\n".join(str(p) for p in problems)


def assert_problems(problems: list[Problem], *fragments: str) -> None:
    text = problem_text(problems)
    for fragment in fragments:
        assert fragment in text, f"{fragment!r} not in:\n{text}"


# --- a valid bundle ----------------------------------------------------------------------------

def test_valid_bundle_loads(tmp_path):
    root = make_bundle(tmp_path / "b")
    assert check_bundle(root) == []
    b = load_bundle(root)
    assert isinstance(b, Bundle)
    assert b.root == root and b.name == "room" and b.prompt == "sofa" and b.layout == "scene.toml"
    assert b.views == list(VIEWS)
    assert set(b.cameras) == set(VIEWS)
    assert b.cameras["view_01"].name == "view_01.jpg" and b.cameras["view_01"].width == W
    assert b.masks == {v: root / "masks" / f"{v}.png" for v in VIEWS}
    assert b.pre == SourceSpec("scene", root / "pre.ply")
    assert b.reference == SourceSpec("scene", root / "ref.splat")
    assert list(b.methods) == ["clean", "objectclear"]  # file order
    oc = b.methods["objectclear"]
    assert oc.kind == "renders" and oc.depth_scale == 0.001
    assert oc.rgb_dir == root / "methods/objectclear/rgb" and oc.depth_dir == root / "methods/objectclear/depth"
    assert b.options.background == (1.0, 1.0, 1.0) and b.options.depth == "median"
    assert b.options.reference_free is False
    assert b.config == root / "scene.toml" and b.cameras_path == root / "cameras"
    assert list(b.sources()) == ["pre", "reference", "clean", "objectclear"]


def test_scene_toml_path_and_defaults(tmp_path):
    root = make_bundle(tmp_path / "lounge", toml_with(**{'name = "room"\n': ""}).split("[options]")[0])
    b = load_bundle(root / "scene.toml")  # the file itself is accepted too
    assert b.name == "lounge"  # default: the folder name
    assert b.options.background == (0.0, 0.0, 0.0) and b.options.depth == "expected"


def test_views_selection_and_override(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'masks = "masks"\n': 'masks = "masks"\nviews = ["view_0[12]"]\n'}))
    assert load_bundle(root).views == ["view_01", "view_02"]
    b = load_bundle(root, views=["view_00"])
    assert b.views == ["view_00"] and list(b.cameras) == ["view_00"] and list(b.masks) == ["view_00"]


def test_default_views_are_the_masked_ones(tmp_path):
    root = make_bundle(tmp_path / "b")
    save_colmap(root / "cameras", [camera(f"{v}.jpg") for v in (*VIEWS, "train_only")])
    assert load_bundle(root).views == list(VIEWS)  # a camera without a mask is not evaluated
    problems = check_bundle(root, views=["*"])  # ... unless selected explicitly
    assert_problems(problems, "missing masks for 1 selected view(s): 'train_only'")


def test_prompt_override(tmp_path):
    root = make_bundle(tmp_path / "b")
    assert load_bundle(root, prompt=" chair ").prompt == "chair"
    assert_problems(check_bundle(root, prompt="  "), "the prompt given is empty")


@pytest.mark.parametrize("writer", ["cameras_json", "transforms_json"])
def test_other_camera_formats(tmp_path, writer):
    root = make_bundle(tmp_path / "b")
    shutil.rmtree(root / "cameras")
    cams = [camera(f"images/{v}.png") for v in VIEWS]
    if writer == "cameras_json":
        save_cameras_json(root / "cams.json", cams)
    else:
        save_transforms_json(root / "cams.json", cams)
    (root / "scene.toml").write_text(toml_with(**{'cameras = "cameras"': 'cameras = "cams.json"'}))
    b = load_bundle(root)
    assert b.views == list(VIEWS) and b.cameras["view_02"].name == "images/view_02.png"


def test_renders_with_explicit_rgb_and_depth_folders(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(
        **{'renders = "methods/objectclear"': 'rgb = "methods/objectclear/rgb"\ndepth = "methods/objectclear/depth"'}))
    oc = load_bundle(root).methods["objectclear"]
    assert oc.rgb_dir == root / "methods/objectclear/rgb" and oc.depth_dir == root / "methods/objectclear/depth"
    assert oc.depth_scale == 0.001


def test_inria_output_folder_is_resolved(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'scene = "pre.ply"': 'scene = "pre_run"'}))
    for it in (7000, 30000):
        d = root / "pre_run" / "point_cloud" / f"iteration_{it}"
        d.mkdir(parents=True)
        save_ply(d / "point_cloud.ply", random_gaussians(10, sh_degree=0, seed=it))
    assert load_bundle(root).pre.path == root / "pre_run/point_cloud/iteration_30000/point_cloud.ply"


def test_reference_renders_without_depth_is_fine(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'scene = "ref.splat"': 'renders = "refr"'}))
    write_renders(root / "refr", depth=False)
    ref = load_bundle(root).reference
    assert ref.kind == "renders" and ref.depth_dir is None


def test_renders_only_bundle_without_cameras(tmp_path):
    root = tmp_path / "b"
    for v in VIEWS:
        write_mask(root / "masks" / f"{v}.png")
    write_renders(root / "pre")
    write_renders(root / "m1")
    (root / "scene.toml").write_text('prompt = "sofa"\nmasks = "masks"\n[pre]\nrenders = "pre"\n'
                                     '[methods.m1]\nrenders = "m1"\n')
    b = load_bundle(root)
    assert b.cameras is None and b.cameras_path is None and b.views == list(VIEWS)


# --- problems, all at once -------------------------------------------------------------------------

BROKEN_TOML = """\
name = "room"
promt = "sofa"
cameras = "cameras"
masks = "masks"

[pre]
scene = "missing.ply"
depht_scale = 2

[reference]
scene = "ref.splat"

[methods.Clean]
scene = "methods/clean.ply"

[methods.clean]
scene = "methods/clean.ply"

[methods.pre]
renders = "methods/objectclear"

[methods.both]
scene = "methods/clean.ply"
renders = "methods/objectclear"

[methods.objectclear]
renders = "methods/objectclear"
depth_scale = -1

[methods.short]
renders = "methods/short"

[methods.nodepth]
renders = "methods/nodepth"

[options]
depth = "mediam"
background = [0, 2, 0]
"""


def make_broken(root: Path) -> Path:
    make_bundle(root, BROKEN_TOML)
    (root / "ref.splat").write_bytes(b"x" * 33)
    write_mask(root / "masks" / "ghost.png")  # no camera
    write_mask(root / "masks" / "view_01.png", W + 4, H)  # wrong size
    write_renders(root / "methods" / "short", views=["view_00"])
    write_rgb(root / "methods" / "short" / "rgb" / "view_02.png", W // 2, H // 2)
    os.remove(root / "methods" / "short" / "depth" / "view_00.png")
    write_depth_png16(root / "methods" / "short" / "depth" / "view_02.png", W, H - 1)
    write_renders(root / "methods" / "nodepth", depth=False)
    return root


BROKEN_EXPECTED = [
    "scene.toml: unknown key 'promt' (did you mean 'prompt'?)",
    "scene.toml: missing required key 'prompt'",
    "scene.toml: unknown key 'depht_scale' in [pre] (did you mean 'depth_scale'?)",
    "missing.ply: no such file (scene of [pre])",
    "scene.toml: duplicate method name: 'Clean' and 'clean' differ only in case",
    "scene.toml: method name 'pre' is reserved",
    "[methods.both] needs exactly one of 'scene' (a splat file) or 'renders'",
    "[methods.objectclear] 'depth_scale' must be a positive number, got -1",
    "[options] 'depth' must be 'expected' or 'median', got 'mediam' (did you mean 'median'?)",
    "[options] 'background' must be three numbers in [0, 1]",
    "masks: masks for 1 view(s) with no camera in",
    "masks/view_01.png: mask is 20x12, the camera of view 'view_01' is 16x12",
    "ref.splat: truncated .splat file: 33 bytes is not a multiple of the 32-byte record (scene of [reference])",
    "methods/short/rgb: missing RGB images of [methods.short] for 1 of 3 views: 'view_01'",
    "methods/short/rgb/view_02.png: RGB image is 8x6, the mask of view 'view_02' is 16x12",
    "methods/short/depth: missing depth images of [methods.short] for 2 of 3 views: 'view_00', 'view_01'",
    "methods/short/depth/view_02.png: depth image is 16x11, the mask of view 'view_02' is 16x12",
    "methods/nodepth/depth: depth folder of [methods.nodepth] does not exist",
]


def test_every_problem_is_listed_at_once(tmp_path):
    root = make_broken(tmp_path / "b")
    problems = check_bundle(root)
    assert_problems(problems, *BROKEN_EXPECTED)
    assert len(problems) == len(BROKEN_EXPECTED)
    assert all(p.path for p in problems)  # each names a file


def test_load_bundle_raises_with_every_problem(tmp_path):
    root = make_broken(tmp_path / "b")
    with pytest.raises(BundleError) as info:
        load_bundle(root)
    err = info.value
    assert isinstance(err, InputError)
    lines = str(err).splitlines()
    assert lines[0] == f"invalid bundle {root} ({len(BROKEN_EXPECTED)} problems):"
    assert len(lines) == 1 + len(BROKEN_EXPECTED) and len(err.problems) == len(BROKEN_EXPECTED)
    for fragment in BROKEN_EXPECTED:
        assert any(fragment in line for line in lines[1:]), fragment


def test_invalid_toml(tmp_path):
    root = make_bundle(tmp_path / "b", 'prompt = "sofa\n')
    (problem,) = check_bundle(root)
    assert problem.path == str(root / "scene.toml") and problem.message.startswith("invalid TOML:")


def test_duplicate_method_table(tmp_path):
    root = make_bundle(tmp_path / "b", SCENE_TOML + '\n[methods.clean]\nscene = "pre.ply"\n')
    (problem,) = check_bundle(root)
    assert "duplicate method: [methods.clean] is declared twice" in problem.message


def test_missing_required_keys(tmp_path):
    root = make_bundle(tmp_path / "b", 'name = "x"\n')
    assert_problems(check_bundle(root), "missing required key 'prompt'", "missing required key 'masks'",
                    "missing required table [pre]", "missing required table [methods.NAME]")


def test_wrong_types(tmp_path):
    root = make_bundle(tmp_path / "b", 'name = 3\nprompt = ""\ncameras = 1\nmasks = ["m"]\nviews = "view_*"\n'
                                       'pre = "pre.ply"\n[methods]\nscene = "x.ply"\n[options]\n'
                                       'reference_free = "yes"\ncolour = 1\n')
    assert_problems(check_bundle(root),
                    "'name' must be a non-empty string", "'prompt' must be a non-empty string",
                    "'cameras' must be a path", "'masks' must be a folder path",
                    "'views' must be a list of view names or glob patterns",
                    "[pre] must be a table", "[methods.scene] must be a table",
                    "[options] 'reference_free' must be true or false", "unknown key 'colour' in [options]")


def test_bad_names(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'name = "room"': 'name = "a/b"',
                                                   "[methods.clean]": '[methods."x/y"]'}))
    assert_problems(check_bundle(root), "scene name 'a/b' contains a path separator",
                    "method name 'x/y' contains a path separator")


def test_source_key_conflicts(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'scene = "pre.ply"': 'scene = "pre.ply"\ndepth_scale = 2.0',
                                                   'depth_scale = 0.001': 'depth = "d"'}))
    assert_problems(check_bundle(root), "[pre] 'depth_scale' applies to renders only",
                    "[methods.objectclear] 'depth' goes with 'rgb'")


def test_not_a_bundle(tmp_path):
    (tmp_path / "empty").mkdir()
    (problem,) = check_bundle(tmp_path / "empty")
    assert "not a bundle: no scene.toml" in problem.message
    (problem,) = check_bundle(tmp_path / "nowhere")
    assert problem.message == "no such bundle folder"
    (tmp_path / "file.txt").write_text("x")
    (problem,) = check_bundle(tmp_path / "file.txt")
    assert "not a bundle" in problem.message


def test_cameras_required_for_splat_scenes(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'cameras = "cameras"\n': ""}))
    assert_problems(check_bundle(root),
                    "missing key 'cameras': needed to render the splat scene of [pre], [reference], [methods.clean]")


def test_unreadable_cameras_are_reported_with_the_rest(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'cameras = "cameras"': 'cameras = "cams.json"'}))
    (root / "cams.json").write_text("{not json")
    os.remove(root / "pre.ply")
    problems = check_bundle(root)
    assert_problems(problems, "cams.json:", "pre.ply: no such file (scene of [pre])")


def test_duplicate_view_names_from_cameras(tmp_path):
    root = make_bundle(tmp_path / "b")
    save_colmap(root / "cameras", [camera(f"{v}.jpg") for v in VIEWS] + [camera("other/view_00.png")])
    assert_problems(check_bundle(root), "cameras 'other/view_00.png' and 'view_00.jpg' have the same view name "
                                        "'view_00'")


def test_view_selection_problems(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'masks = "masks"\n': 'masks = "masks"\n'
                                                                         'views = ["nope*", "view_9"]\n'}))
    assert_problems(check_bundle(root), "pattern 'nope*' (views in scene.toml) matches no view",
                    "view 'view_9' (views in scene.toml) has no camera and no mask",
                    "no evaluation views (no view matches views in scene.toml)")
    assert_problems(check_bundle(root, views=["x*"]), "pattern 'x*' (--views) matches no view")


def test_masks_folder_problems(tmp_path):
    root = make_bundle(tmp_path / "b")
    shutil.rmtree(root / "masks")
    assert_problems(check_bundle(root), "masks: masks folder does not exist")
    (root / "masks").mkdir()
    cv2.imwrite(str(root / "masks" / "view_00.jpg"), np.zeros((H, W), np.uint8))
    assert_problems(check_bundle(root), "masks folder has no <view>.png masks (found 1 other images, "
                                        "e.g. view_00.jpg: masks must be PNG)")


def test_masks_without_cameras_at_all(tmp_path):
    root = make_bundle(tmp_path / "b")
    save_colmap(root / "cameras", [camera("a.jpg"), camera("b.jpg")])
    assert_problems(check_bundle(root), "masks for 3 view(s) with no camera",
                    "no evaluation views (no mask has a matching camera)")


def test_corrupt_mask_found_by_check_not_by_header_only_load(tmp_path):
    root = make_bundle(tmp_path / "b")
    png = (root / "masks" / "view_02.png").read_bytes()
    (root / "masks" / "view_02.png").write_bytes(png[:40])  # header intact, pixel data cut
    assert_problems(check_bundle(root), "view_02.png: cannot decode mask image")
    assert load_bundle(root).views == list(VIEWS)  # load_bundle reads mask headers only
    (root / "masks" / "view_01.png").write_bytes(b"garbage")
    with pytest.raises(BundleError, match="view_01.png"):
        load_bundle(root)


def test_many_size_problems_are_summarised(tmp_path):
    views = [f"v{i:02d}" for i in range(14)]
    root = make_bundle(tmp_path / "b", views=views)
    for v in views:
        write_mask(root / "masks" / f"{v}.png", W * 2, H * 2)
    problems = check_bundle(root)
    assert len(problems) == 11
    assert_problems(problems, "masks: ... and 4 more masks with problems")


@pytest.mark.parametrize("content, message", [
    (b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nend_header\n" + bytes(8),
     "PLY file is not a Gaussian-splat scene"),
    (b"not a ply at all", "unknown Gaussian-splat format"),
])
def test_bad_splat_files(tmp_path, content, message):
    root = make_bundle(tmp_path / "b")
    target = root / "methods" / "clean.ply" if content.startswith(b"ply") else root / "methods" / "clean.spz"
    target.write_bytes(content)
    if target.suffix == ".spz":
        (root / "scene.toml").write_text(toml_with(**{"methods/clean.ply": "methods/clean.spz"}))
    assert_problems(check_bundle(root), message, "(scene of [methods.clean])")


def test_truncated_and_empty_ply(tmp_path):
    root = make_bundle(tmp_path / "b")
    data = (root / "pre.ply").read_bytes()
    (root / "pre.ply").write_bytes(data[:-5])
    props = "".join(f"property float {n}\n" for n in ("x", "y", "z", "opacity", "rot_0"))
    (root / "methods" / "clean.ply").write_bytes(
        f"ply\nformat binary_little_endian 1.0\nelement vertex 0\n{props}end_header\n".encode())
    (root / "ref.splat").write_bytes(b"")
    assert_problems(check_bundle(root), "pre.ply: truncated PLY file", "clean.ply: scene has no Gaussians",
                    "ref.splat: empty .splat file")
    (root / "pre.ply").write_bytes(data + b"xx")
    assert_problems(check_bundle(root), "pre.ply: PLY file has 2 bytes more than the header declares")


def test_renders_problems(tmp_path):
    root = make_bundle(tmp_path / "b", toml_with(**{'renders = "methods/objectclear"': 'renders = "nowhere"'}))
    assert_problems(check_bundle(root), "nowhere/rgb: RGB folder of [methods.objectclear] does not exist",
                    "nowhere/depth: depth folder of [methods.objectclear] does not exist")
    root = make_bundle(tmp_path / "c", toml_with(
        **{'renders = "methods/objectclear"': 'rgb = "methods/objectclear/rgb"'}))
    assert_problems(check_bundle(root), "[methods.objectclear] has no depth: the geometric axis needs depth")
    root = make_bundle(tmp_path / "d")
    write_rgb(root / "methods/objectclear/rgb/view_00.jpg")
    (root / "methods/objectclear/depth/view_01.png").write_bytes(b"\x89PNG\r\n\x1a\nshort")
    assert_problems(check_bundle(root), "several RGB images for view 'view_00': view_00.jpg, view_00.png",
                    "view_01.png: malformed PNG header")


# --- the Remove360 layout ------------------------------------------------------------------------

def test_remove360_layout(tmp_path):
    root = make_remove360(tmp_path / "bedroom_table")
    assert check_bundle(root) == []
    b = load_bundle(root)
    assert b.layout == "remove360" and b.config is None and b.cameras is None
    assert b.name == "bedroom_table" and b.prompt == "table" and b.views == list(VIEWS)
    assert b.pre == SourceSpec("renders", root / "rgb/before", 1.0, root / "rgb/before", root / "depth/before")
    assert list(b.methods) == ["after"]
    assert b.methods["after"].rgb_dir == root / "rgb/after" and b.methods["after"].depth_dir == root / "depth/after"
    assert b.reference is None
    assert b.masks["view_00"] == root / "masks/view_00.png"  # the .json beside it is ignored


def test_remove360_layout_options(tmp_path):
    root = make_remove360(tmp_path / "bedroom_table", prompt=None)
    (problem,) = check_bundle(root)
    assert problem.path == str(root / "prompt.txt")
    assert "no prompt: write the removed object's category (e.g. 'table') into prompt.txt" in problem.message
    b = load_bundle(root, prompt="table", method_name="gaussian_cut", views=["view_0[01]"])
    assert b.prompt == "table" and list(b.methods) == ["gaussian_cut"] and b.views == ["view_00", "view_01"]
    assert_problems(check_bundle(root, prompt="t", method_name="pre"), "method name 'pre' is reserved")
    write_renders(tmp_path / "ref", depth=False)
    shutil.copytree(tmp_path / "ref" / "rgb", root / "rgb" / "reference")
    b = load_bundle(root, prompt="table")
    assert b.reference == SourceSpec("renders", root / "rgb/reference", 1.0, root / "rgb/reference", None)


def test_remove360_fresh_download_lists_what_is_missing(tmp_path):
    root = make_remove360(tmp_path / "s")
    shutil.rmtree(root / "rgb")
    shutil.rmtree(root / "depth")
    problems = check_bundle(root)
    assert_problems(problems, "rgb/before: RGB folder of pre does not exist",
                    "depth/before: depth folder of pre does not exist",
                    "rgb/after: RGB folder of method 'after' does not exist",
                    "depth/after: depth folder of method 'after' does not exist")
    assert len(problems) == 4


def test_remove360_missing_views(tmp_path):
    root = make_remove360(tmp_path / "s")
    os.remove(root / "rgb" / "after" / "view_01.jpg")
    write_mask(root / "masks" / "extra.png")
    assert_problems(check_bundle(root), "rgb/after: missing RGB images of method 'after' for 2 of 4 views: "
                                        "'extra', 'view_01'",
                    "rgb/before: missing RGB images of pre for 1 of 4 views: 'extra'")


# --- fingerprint and helpers -----------------------------------------------------------------------

def test_fingerprint(tmp_path):
    root = make_bundle(tmp_path / "b")
    fp = load_bundle(root).fingerprint()
    assert len(fp) == 64 and fp == load_bundle(root).fingerprint()
    assert load_bundle(root, views=["view_00"]).fingerprint() != fp
    assert load_bundle(root, prompt="chair").fingerprint() != fp

    # Content, not mtime: touching changes nothing; other bytes of the same size with the mtime
    # restored (cp -p, rsync -a) change the fingerprint.
    mask = root / "masks" / "view_01.png"
    st = mask.stat()
    os.utime(mask, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert load_bundle(root).fingerprint() == fp
    data = bytearray(mask.read_bytes())
    data[-20] ^= 0xFF  # inside the PNG's last chunks: same size, other bytes
    mask.write_bytes(bytes(data))
    os.utime(mask, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    fp2 = load_bundle(root).fingerprint()
    assert fp2 != fp
    write_rgb(root / "methods/objectclear/rgb/view_02.png", seed=99)
    fp3 = load_bundle(root).fingerprint()
    assert fp3 != fp2
    (root / "scene.toml").write_text(SCENE_TOML + "# a comment\n")
    assert load_bundle(root).fingerprint() != fp3


def test_fingerprint_is_independent_of_the_bundle_location(tmp_path):
    root = make_bundle(tmp_path / "b")
    fp = load_bundle(root).fingerprint()
    shutil.copytree(root, tmp_path / "c", copy_function=shutil.copy2)
    os.utime(tmp_path / "c" / "cameras", ns=(0, 0))  # folders' times are not hashed
    assert load_bundle(tmp_path / "c").fingerprint() == fp


def test_fingerprint_of_a_vanished_file(tmp_path):
    root = make_remove360(tmp_path / "s")
    b = load_bundle(root)
    fp = b.fingerprint()
    os.remove(root / "depth" / "after" / "view_02.png")
    assert b.fingerprint() != fp  # no exception: hashed as missing


@pytest.mark.parametrize("camera_name, view", [
    ("frame_0001.jpg", "frame_0001"), ("images/frame_0001.JPG", "frame_0001"), ("a\\b\\c.png", "c"),
    ("frame.0001", "frame.0001"), ("frame_0001", "frame_0001"), ("x.tar.png", "x.tar"), (".png", ".png"),
])
def test_view_name(camera_name, view):
    assert view_name(camera_name) == view


def test_inspect_bundle_returns_the_bundle_only_when_valid(tmp_path):
    root = make_bundle(tmp_path / "b")
    bundle, problems = inspect_bundle(root)
    assert problems == [] and bundle.views == list(VIEWS)
    os.remove(root / "pre.ply")
    bundle, problems = inspect_bundle(root)
    assert bundle is None and len(problems) == 1
