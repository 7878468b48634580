"""r360gpu.io.frames: similarity frames, nerfstudio's dataparser transform, gsplat's normalisation
(against tests/gsplat_oracle.py), COLMAP points3D; and the frame check's verdicts."""
from __future__ import annotations

import json

import numpy as np
import pytest

from gsplat_oracle import normalize_world
from r360gpu.errors import InputError
from r360gpu.io import Camera, load_cameras, save_colmap, save_transforms_json
from r360gpu.io.colmap_points import read_points3d, save_points3d
from r360gpu.io.frames import Frame, gsplat_frame, gsplat_normalization, nerfstudio_frame, resolve_frame
from r360gpu.io.rotation import quat_to_rotmat
from r360gpu.metrics.frame_check import (CONES_MIN, REMOVED_MIN, STEP_NOTE, FrameVerdict, ViewCoverage, backprojected,
                                         check_views, cone_agreement, frame_verdict, mismatch_message, note_message,
                                         outline_step, removal, view_coverage)


def look_at(centre, target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), name="v", w=40, h=30) -> Camera:
    centre, target, up = (np.asarray(a, float) for a in (centre, target, up))
    z = target - centre
    z /= np.linalg.norm(z)
    x = np.cross(z, -up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c2w = np.eye(4)
    c2w[:3, :3] = np.stack([x, y, z], axis=1)
    c2w[:3, 3] = centre
    return Camera.from_camera_to_world(c2w, 30.0, 31.0, w / 2, h / 2, w, h, name)


def ring(n=12, seed=0, up=(0.0, 0.0, 1.0)) -> list[Camera]:
    rng = np.random.default_rng(seed)
    cams = []
    for i in range(n):
        a = 2 * np.pi * i / n + rng.normal(0, 0.1)
        c = np.array([4 * np.cos(a), 4 * np.sin(a), 1.5 + rng.normal(0, 0.3)]) + rng.normal(0, 0.2, 3)
        cams.append(look_at(c, rng.normal(0, 0.3, 3), up=up, name=f"img_{i:03d}.png"))
    return cams


def random_similarity(seed=1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    r = quat_to_rotmat(rng.normal(size=4))
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = 0.37 * r, rng.normal(size=3)
    return m


def test_a_moved_camera_sees_the_moved_world_with_depth_times_the_scale():
    m = random_similarity()
    frame = Frame.from_matrix(m, "test")
    assert frame.scale == pytest.approx(0.37)
    pts = np.random.default_rng(2).normal(0, 0.5, (50, 3))
    for cam in ring(5):
        uv, z = cam.project(pts)
        uv2, z2 = frame.camera(cam).project(frame.points(pts))
        np.testing.assert_allclose(uv2, uv, atol=1e-9)
        np.testing.assert_allclose(z2, 0.37 * z, rtol=1e-12)
        assert (frame.camera(cam).fx, frame.camera(cam).cy) == (cam.fx, cam.cy)


@pytest.mark.parametrize("bad, why", [
    (np.diag([1.0, 1.0, -1.0, 1.0]), "reflects"),
    (np.diag([1.0, 2.0, 1.0, 1.0]), "uniform scale"),
    (np.full((4, 4), np.nan), "finite"),
    (np.eye(3), "3x4 or 4x4"),
])
def test_a_frame_is_a_similarity(bad, why):
    with pytest.raises(InputError, match=why):
        Frame.from_matrix(bad, "test", "x.json")


def _c2w(cams):
    return np.stack([c.camera_to_world for c in sorted(cams, key=lambda c: c.name)])


@pytest.mark.parametrize("flip", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gsplat_normalisation_equals_gsplats_own_functions(seed, flip):
    rng = np.random.default_rng(seed)
    # a ground plane with clutter above it (points' median height below the mean: no turn) or a
    # ceiling-heavy cloud (median above the mean: gsplat turns the world)
    pts = np.concatenate([rng.normal(0, [2, 2, 0.05], (400, 3)), rng.normal([0, 0, 1], 0.6, (100 + 300 * seed, 3))])
    pts = pts.astype(np.float32)
    cams = ring(10, seed, up=(0.0, 0.0, 1.0) if seed != 2 else (0.3, -0.2, 1.0))
    c2w, moved, want = normalize_world(_c2w(cams), pts, flip=flip)
    frame = gsplat_normalization(cams, pts, flip=flip)
    np.testing.assert_allclose(frame.m, want, atol=1e-9)
    np.testing.assert_allclose(frame.points(pts), moved, atol=1e-6)
    got = np.stack([frame.camera(c).camera_to_world for c in sorted(cams, key=lambda c: c.name)])
    np.testing.assert_allclose(got, c2w, atol=1e-9)


def test_gsplat_frame_reads_the_colmap_model_and_its_points(tmp_path):
    rng = np.random.default_rng(5)
    cams = ring(9, 5)
    pts = rng.normal(0, [1.5, 1.0, 0.4], (300, 3))
    save_colmap(tmp_path / "sparse" / "0", cams)
    save_points3d(tmp_path / "sparse" / "0", pts)
    frame = gsplat_frame(tmp_path)
    _, _, want = normalize_world(_c2w(cams), pts.astype(np.float32))
    np.testing.assert_allclose(frame.m, want, atol=1e-9)
    assert "9 cameras, 300 points" in frame.origin
    assert resolve_frame("gsplat", scene=tmp_path / "x.ply", cameras=tmp_path).matrix == frame.matrix
    save_points3d(tmp_path / "sparse" / "0", pts[:0])  # save_colmap's empty file: nothing to align to
    (tmp_path / "sparse" / "0" / "points3D.bin").write_bytes((0).to_bytes(8, "little"))
    with pytest.raises(InputError, match="needs the COLMAP sparse points"):
        gsplat_frame(tmp_path)
    (tmp_path / "sparse" / "0" / "points3D.bin").unlink()
    with pytest.raises(InputError, match="no points3D.bin"):
        gsplat_frame(tmp_path)
    save_transforms_json(tmp_path / "transforms.json", cams)
    with pytest.raises(InputError, match="COLMAP model gsplat trained on"):
        gsplat_frame(tmp_path / "transforms.json")


@pytest.mark.parametrize("binary", [True, False])
def test_points3d_round_trip_and_errors(tmp_path, binary):
    pts = np.random.default_rng(0).normal(size=(7, 3))
    f = save_points3d(tmp_path, pts, binary=binary)
    np.testing.assert_array_equal(read_points3d(f), pts)
    data = f.read_bytes()
    f.write_bytes(data[:-5] if binary else data + b"8 1 2\n")
    with pytest.raises(InputError, match="truncated|line 9: expected"):
        read_points3d(f)


def test_points3d_are_ordered_by_id(tmp_path):
    f = tmp_path / "points3D.txt"
    f.write_text("# c\n5 5 5 5 1 2 3 0.1 1 2\n2 2 2 2 1 2 3 0.1\n")
    np.testing.assert_array_equal(read_points3d(f), [[2, 2, 2], [5, 5, 5]])


# --- nerfstudio ------------------------------------------------------------------------------------

# ns-process-data's applied_transform (colmap_utils.colmap_to_json): COLMAP world -> transforms.json world
APPLIED = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0]])


def _dataparser(tmp_path, orient: np.ndarray, scale: float, applied=APPLIED):
    """dataparser_transforms.json as nerfstudio writes it: transform = orient @ applied (original -> ns)."""
    a = np.eye(4)
    a[:3] = applied
    doc = {"transform": (orient @ a)[:3].tolist(), "scale": scale}
    path = tmp_path / "dataparser_transforms.json"
    path.write_text(json.dumps(doc))
    return path


def test_nerfstudio_frame_is_the_same_for_colmap_and_transforms_json_cameras(tmp_path):
    cams = ring(6, 3)
    save_colmap(tmp_path / "colmap", cams)
    # transforms.json as ns-process-data writes it: the COLMAP world moved by applied_transform
    moved = Frame.from_matrix(APPLIED, "applied")
    save_transforms_json(tmp_path / "data" / "transforms.json", [moved.camera(c) for c in cams])
    doc = json.loads((tmp_path / "data" / "transforms.json").read_text())
    doc["applied_transform"] = APPLIED.tolist()
    (tmp_path / "data" / "transforms.json").write_text(json.dumps(doc))
    orient = random_similarity(7)
    orient[:3, :3] /= 0.37  # auto_orient_and_center_poses: rigid
    dp = _dataparser(tmp_path, orient, 0.25)
    from_colmap = nerfstudio_frame(dp, tmp_path / "colmap")
    from_transforms = nerfstudio_frame(dp, tmp_path / "data" / "transforms.json")
    assert from_colmap.scale == pytest.approx(0.25) and from_transforms.scale == pytest.approx(0.25)
    by_name = {c.name: c for c in load_cameras(tmp_path / "data" / "transforms.json")}
    for c in cams:
        a, b = from_colmap.camera(c), from_transforms.camera(by_name[c.name])
        np.testing.assert_allclose(a.camera_to_world, b.camera_to_world, atol=1e-9)
        # and both equal nerfstudio's own: poses = orient @ c2w, translation times scale
        ns = orient @ (moved.camera(c).camera_to_world)
        np.testing.assert_allclose(b.center, 0.25 * ns[:3, 3], atol=1e-9)


def test_legacy_transforms_json_without_applied_transform_beside_colmap(tmp_path):
    legacy = np.array([[0.0, 1, 0, 0], [1.0, 0, 0, 0], [0, 0, -1.0, 0]])
    dp = _dataparser(tmp_path, np.eye(4), 1.0, applied=legacy)
    save_transforms_json(tmp_path / "transforms.json", ring(3))
    plain = nerfstudio_frame(dp, tmp_path / "transforms.json")
    np.testing.assert_allclose(plain.m[:3], legacy, atol=1e-12)  # no applied_transform: the file as it is
    (tmp_path / "colmap" / "sparse" / "0").mkdir(parents=True)
    np.testing.assert_allclose(nerfstudio_frame(dp, tmp_path / "transforms.json").m, np.eye(4), atol=1e-12)


@pytest.mark.parametrize("doc, why", [
    ({"scale": 1.0}, "expected an object"),
    ({"transform": [[1, 0, 0]], "scale": 1.0}, "3x4 or 4x4"),
    ({"transform": np.eye(4)[:3].tolist(), "scale": -2}, "positive"),
    ({"transform": np.diag([1.0, 1, -1, 1])[:3].tolist(), "scale": 1}, "reflects"),
])
def test_bad_dataparser_transforms_name_the_file(tmp_path, doc, why):
    f = tmp_path / "dataparser_transforms.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=why) as e:
        nerfstudio_frame(f, None)
    assert str(f) in str(e.value)


def test_resolve_frame_keywords_and_auto(tmp_path):
    (tmp_path / "splat.ply").write_bytes(b"")
    assert resolve_frame(None, scene=tmp_path / "splat.ply", cameras=None) is None
    dp = _dataparser(tmp_path, np.eye(4), 0.5, applied=np.eye(4)[:3])
    auto = resolve_frame("auto", scene=tmp_path / "splat.ply", cameras=None)
    assert auto.scale == pytest.approx(0.5) and str(dp) in auto.origin
    assert resolve_frame("cameras", scene=tmp_path / "splat.ply", cameras=None) is None
    named = resolve_frame("dataparser_transforms.json", scene="x", cameras=None, root=tmp_path)
    assert named.scale == pytest.approx(0.5)
    with pytest.raises(InputError, match="neither one of auto, cameras, gsplat"):
        resolve_frame("gsplatt", scene="x", cameras=None, root=tmp_path)
    with pytest.raises(InputError, match="set cameras"):
        resolve_frame("gsplat", scene="x", cameras=None)


# --- the frame check -------------------------------------------------------------------------------

def _cov(alpha_fill, target_fill, n=4):
    mask = np.zeros((40, 40), bool)
    mask[2:6, 2:6] = True
    out = []
    for i in range(n):
        a = np.zeros((40, 40), np.float32)
        a.flat[-int(alpha_fill * 1600):] = 1.0 if alpha_fill else 0.0
        if target_fill:
            a[2:6, 2:6] = 0.0
            a[2:6, 2:2 + int(4 * target_fill)] = 1.0
        out.append(view_coverage(f"v{i}", a, mask))
    return out


def test_frame_verdicts():
    """The cameras miss the splats (refuse) only by the target's coverage or the cones; an empty
    image around a covered target is an object scan framed right; a low outline step is a note."""
    assert frame_verdict(_cov(1.0, 1.0)).level == "ok"
    assert frame_verdict(_cov(0.0, 0.0)).level == "refuse"
    assert frame_verdict(_cov(0.05, 1.0)).level == "ok"            # an object on an empty background
    assert frame_verdict(_cov(0.9, 0.25)).level == "refuse"        # the target falls where pre renders little
    assert frame_verdict(_cov(0.0, 0.0)[:2] + _cov(1.0, 1.0)[:2]).level == "refuse"  # half the views
    assert frame_verdict(_cov(0.0, 0.0)[:1] + _cov(1.0, 1.0)[:3]).level == "ok"
    assert frame_verdict([]).level == "ok"
    faint = [view_coverage(f"v{i}", np.full((8, 8), 0.3, np.float32), np.ones((8, 8), bool)) for i in range(3)]
    assert faint[0].coverage == 0.0 and faint[0].touched == 1.0
    assert frame_verdict(faint).level == "refuse"  # drawn, but nowhere solid under the target
    assert "covers less than" in mismatch_message(frame_verdict(faint), source="p", frame=None, cameras=None)
    covered = _cov(1.0, 1.0)
    assert frame_verdict(covered, cones=CONES_MIN - 0.01).level == "refuse"
    assert frame_verdict(covered, cones=CONES_MIN).level == "ok"
    stepped = [ViewCoverage(c.view, c.coverage, c.target, c.touched, s) for c, s in zip(covered, (0.0, 0.1, 0.9, 0.9))]
    assert frame_verdict(stepped, cones=1.0).level == "ok" and frame_verdict(stepped).step == 0.5
    flat = [ViewCoverage(c.view, c.coverage, c.target, c.touched, STEP_NOTE / 2) for c in covered]
    assert frame_verdict(flat, cones=1.0).level == "note"
    assert frame_verdict(flat, cones=0.5).level == "refuse"  # missing the splats outranks the note
    note = note_message(frame_verdict(flat, cones=1.0))
    assert "little depth step" in note and "frame" not in note.replace("frame check", "")
    v = frame_verdict(_cov(0.0, 0.0))
    assert FrameVerdict.from_dict(json.loads(json.dumps(v.to_dict()))) == v
    msg = mismatch_message(v, source="pre.ply", frame=None, cameras="cameras")
    assert "renders nothing" in msg and "dataparser_transforms" in msg and "gsplat" in msg
    nan = view_coverage("x", np.full((3, 3), np.nan, np.float32), np.zeros((3, 3), bool))
    assert nan.coverage == 0.0 and nan.target is None
    # the reference decides too where the geometry does not refuse, whatever the outline's step
    assert frame_verdict(covered, cones=1.0, removed=REMOVED_MIN).level == "ok"
    assert frame_verdict(flat, cones=1.0, removed=REMOVED_MIN).level == "note"
    for views in (covered, flat):
        same = frame_verdict(views, cones=1.0, removed=REMOVED_MIN - 0.01)
        assert same.level == "refuse" and "the reference render the same thing" in mismatch_message(
            same, source="p", frame=None, cameras=None)
    assert "differs from pre at 90%" in note_message(frame_verdict(flat, cones=1.0, removed=0.9))
    assert "no reference" in note_message(frame_verdict(flat, cones=1.0))
    v = frame_verdict(flat, cones=1.0, removed=0.25)
    assert FrameVerdict.from_dict(json.loads(json.dumps(v.to_dict()))) == v


def _images(rgb, depth):
    from r360gpu.render.sources import ViewImages

    return ViewImages(np.asarray(rgb, np.float32), np.asarray(depth, np.float32), np.ones(np.shape(depth), np.float32))


def test_removal_is_where_the_reference_differs_from_pre_under_the_mask():
    """A red box at depth 1 before a grey wall at depth 2; the reference is the wall alone."""
    rgb, depth = np.full((60, 80, 3), 0.5), np.full((60, 80), 2.0)
    box = np.zeros((60, 80), bool)
    box[20:40, 30:50] = True
    pre = _images(np.where(box[..., None], [1.0, 0.0, 0.0], rgb), np.where(box, 1.0, depth))
    wall = _images(rgb, depth)
    assert removal(pre, wall, box) == 1.0
    assert removal(pre, wall, np.roll(box, 30, axis=1)) == 0.0  # the masks away from the box: the wall both
    wide = np.zeros_like(box)
    wide[18:42, 28:52] = True
    assert removal(pre, wall, wide) == 1.0  # masks two pixels wide of the box count the box only
    grey_box = _images(rgb, np.where(box, 1.0, depth))
    assert removal(grey_box, wall, box) == 1.0  # the same colour, nearer: told by depth
    faint = _images(rgb + 0.05, depth)
    assert removal(faint, wall, box) == 0.0  # under DIFFERS
    assert removal(pre, wall, np.zeros_like(box)) is None
    assert removal(pre, _images(rgb[:30], depth[:30]), box) is None  # sizes differ
    tiny = np.zeros_like(box)
    tiny[25:28, 35:38] = True
    assert removal(pre, wall, tiny) == 1.0  # eroded to its centre pixel


# --- the frame keys of scene.toml -------------------------------------------------------------------

def test_scene_toml_frame_keys(tmp_path):
    from bundle_factory import SCENE_TOML, make_bundle
    from r360gpu.bundle import check_bundle, load_bundle

    root = make_bundle(tmp_path / "b")
    assert load_bundle(root).pre.frame is None  # no dataparser_transforms.json beside pre.ply
    dp = _dataparser(root, np.eye(4), 2.0, applied=np.eye(4)[:3])
    b = load_bundle(root)  # beside pre.ply, not beside methods/clean.ply
    assert b.pre.frame.scale == pytest.approx(2.0) and b.methods["clean"].frame is None
    dp.unlink()
    toml = SCENE_TOML.replace('masks = "masks"', 'masks = "masks"\nframe = "gsplat"')
    (root / "scene.toml").write_text(toml)
    problems = [str(p) for p in check_bundle(root)]  # save_colmap's points3D.bin is empty
    assert any("needs the COLMAP sparse points" in p and "(frame of [pre])" in p for p in problems), problems
    (root / "scene.toml").write_text(SCENE_TOML.replace('[methods.objectclear]\n',
                                                        '[methods.objectclear]\nframe = "cameras"\n'))
    assert any("'frame' applies to splat scenes only" in str(p) for p in check_bundle(root))
    (root / "scene.toml").write_text(SCENE_TOML.replace('masks = "masks"', 'masks = "masks"\nframes = "gsplat"'))
    assert any("did you mean 'frame'" in str(p) for p in check_bundle(root))
    (root / "scene.toml").write_text(SCENE_TOML.replace('masks = "masks"', 'masks = "masks"\nframe = 3'))
    assert any("'frame' must be 'auto', 'cameras', 'gsplat'" in str(p) for p in check_bundle(root))


def test_the_frame_is_part_of_the_fingerprint(tmp_path):
    from bundle_factory import make_bundle
    from r360gpu.bundle import load_bundle

    root = make_bundle(tmp_path / "b")
    plain = load_bundle(root).fingerprint()
    _dataparser(root, np.eye(4), 2.0, applied=np.eye(4)[:3])
    assert load_bundle(root).fingerprint() != plain


def test_the_outline_step_follows_the_object_not_the_mask():
    """An object standing out of its background is nearer just inside its mask than just outside
    all along the outline; a mask that is elsewhere (cameras in another frame) lies on the wall."""
    yy, xx = np.mgrid[0:60, 0:80]
    depth = 4.0 + 0.01 * xx + 0.02 * np.sin(yy / 3.0)  # a slanted, slightly rippled wall
    obj = (abs(xx - 30) < 10) & (abs(yy - 25) < 12)
    depth = np.where(obj, 2.0, depth).astype(np.float32)
    alpha = np.ones(depth.shape, np.float32)
    assert outline_step(depth, alpha, obj) == 1.0
    elsewhere = np.roll(obj, 35, axis=1)
    assert outline_step(depth, alpha, elsewhere) == 0.0
    assert outline_step(depth, alpha, np.zeros_like(obj)) is None
    floating = np.where(obj, 1.0, 0.0).astype(np.float32)  # nothing rendered around it: in front of empty space
    assert outline_step(depth, floating, obj) == 1.0
    nan = depth.copy()
    nan[:20] = np.nan  # the upper outline not rendered: measured on the rest
    assert outline_step(nan, alpha, obj) == 1.0
    assert outline_step(depth, np.zeros_like(alpha), obj) is None  # nothing solid inside: not measured


def _cube_views(shift=(0.0, 0.0, 0.0)):
    """Four cameras around a cube of points at the origin: each camera's mask is the cube's
    footprint; the points are the cube moved by ``shift`` (a mismatched frame when non-zero)."""
    g = np.linspace(-0.4, 0.4, 9)
    cube = np.stack(np.meshgrid(g, g, g), axis=-1).reshape(-1, 3)
    cams = [look_at((4 * np.cos(a), 4 * np.sin(a), 1.0), name=f"v{i}", w=80, h=60)
            for i, a in enumerate(np.radians([0, 70, 140, 250]))]
    views = []
    for cam in cams:
        u, v = cam.project(cube)[0].T
        mask = np.zeros((60, 80), np.uint8)
        mask[np.clip(v.astype(int), 0, 59), np.clip(u.astype(int), 0, 79)] = 1
        import cv2

        mask = cv2.dilate(mask, np.ones((5, 5), np.uint8)) > 0
        views.append((cam, cube + np.asarray(shift), mask))
    return views


def test_cone_agreement_is_high_where_the_masks_cones_meet_and_low_elsewhere():
    assert cone_agreement(_cube_views()) == 1.0
    assert cone_agreement(_cube_views((2.0, -2.0, 0.0))) == 0.0
    assert cone_agreement(_cube_views((0.0, 0.0, 1.5))) == 0.0
    # moved along some cameras' lines of sight, the points stay in those views' masks: the cones
    # alone let part of such a shift pass (why the check also reads the outline step)
    assert 0.3 < cone_agreement(_cube_views((1.5, 0.0, 0.0))) < 0.9
    assert cone_agreement(_cube_views()[:1]) is None  # one view: no pairs
    behind = [(c, np.array([[0.0, 0.0, 100.0]]), m) for c, _, m in _cube_views()]
    assert cone_agreement(behind) is None  # fewer than MIN_PIXELS points in any other image


def test_cone_agreement_ignores_points_hidden_in_the_other_view():
    """A point behind pre's surface in view j (an occluder in front of the target there) says
    nothing about j's mask, which marks only the target's visible pixels."""
    views = _cube_views()
    cam0, pts0, mask0 = views[0]
    cam1, pts1, mask1 = views[1]
    # view 1's mask loses its right three quarters (an occluder), and its depth shows the occluder 1 unit in front
    mid = int(np.percentile(np.nonzero(mask1)[1], 25))
    occluded = mask1.copy()
    occluded[:, mid:] = False
    depth1 = np.full(mask1.shape, 10.0)  # the backdrop, behind the cube (about 4 units away)
    depth1[:, mid:] = 2.0
    plain = [(cam0, pts0, mask0), (cam1, pts1, occluded)]
    assert cone_agreement(plain) < 0.8  # the hidden part counted against the mask
    seen = [(cam0, pts0, mask0, None), (cam1, pts1, occluded, depth1)]
    assert cone_agreement(seen) == 1.0
    # no pair with a point seen: the hidden points count after all (opposite sides of an object)
    everywhere = [(cam0, pts0, mask0, np.full(mask0.shape, 1.0)), (cam1, pts1, occluded, np.full(mask1.shape, 1.0))]
    assert cone_agreement(everywhere) == cone_agreement(plain)
    # a point *in front of* the surface is not hidden: shifted off the masks, it still counts
    off = [(c, p, m, np.full(m.shape, 10.0)) for c, p, m in _cube_views((0.0, 0.0, 1.5))]
    assert cone_agreement(off) == 0.0


def test_backprojection_inverts_the_camera():
    cam = look_at((3.0, 1.0, 1.0), w=80, h=60)
    rows, cols = np.mgrid[0:60, 0:80]
    depth = (2.0 + 0.01 * cols).astype(np.float32)
    mask = np.zeros((60, 80), bool)
    mask[20:40, 30:50] = True
    pts = backprojected(cam, np.ones((60, 80), np.float32), depth, mask)
    assert len(pts) == 18 * 18  # eroded by one pixel
    uv, z = cam.project(pts)
    assert np.allclose(uv % 1.0, 0.5) and np.allclose(z, 2.0 + 0.01 * np.floor(uv[:, 0]), rtol=1e-6)
    small = backprojected(cam.resized(40, 30), np.ones((60, 80), np.float32), depth, mask)
    assert np.allclose(small, pts)  # a camera of another size is resized to the image


def test_check_views_flags_a_mask_off_the_object():
    """An object in front of a wall seen by two cameras: its masks fit (ok); the masks of a
    world moved 1.5 units aside do not (refused, with the cone agreement in the message)."""
    cams = [look_at((4.0, 0.0, 0.0), name="a", w=80, h=60), look_at((0.0, 4.0, 0.0), name="b", w=80, h=60)]

    def views(offset):
        out = []
        for cam in cams:
            rows, cols = np.mgrid[0:60, 0:80]
            ray = np.stack([(cols + 0.5 - cam.cx) / cam.fx, (rows + 0.5 - cam.cy) / cam.fy, np.ones((60, 80))], -1)
            d = np.full((60, 80), 6.0)  # a far backdrop
            # a ball of radius 0.6 at the origin: depth of the nearer hit along each pixel's ray
            o = cam.center
            dirs = ray @ cam.R  # world directions (not unit): point = o + z * dirs
            b = dirs @ o
            a = (dirs ** 2).sum(-1)
            disc = b ** 2 - a * (o @ o - 0.36)
            hit = disc > 0
            z = (-b - np.sqrt(np.where(hit, disc, 0))) / a
            d = np.where(hit, z, d).astype(np.float32)
            uv = cam.project(np.asarray(offset, float)[None])[0][0]
            mask = (cols - uv[0]) ** 2 + (rows - uv[1]) ** 2 < (0.6 * cam.fx / 4.0) ** 2
            out.append((cam.name, cam, np.ones((60, 80), np.float32), d, mask))
        return out

    ok = check_views(views((0.0, 0.0, 0.0)))
    assert ok.level == "ok" and ok.cones == 1.0 and ok.step > STEP_NOTE
    off = check_views(views((1.5, -1.5, 0.0)))
    assert off.level == "refuse" and off.cones < CONES_MIN
    msg = mismatch_message(off, source="pre.ply", frame="nerfstudio x", cameras=None)
    assert "away from where their viewing cones meet" in msg and "moved by nerfstudio x" in msg
    assert f"cone agreement {off.cones:.2f}" in msg
    one = check_views(views((0.0, 0.0, 0.0))[:1])
    assert one.cones is None and one.level == "ok"  # one view: coverage only

    def with_rgb(vs):  # the ball white, the backdrop black
        return [(*v, np.repeat((v[3] < 6.0)[..., None], 3, axis=-1).astype(np.float32)) for v in vs]

    backdrop = _images(np.zeros((60, 80, 3)), np.full((60, 80), 6.0))
    removed = check_views(with_rgb(views((0.0, 0.0, 0.0))), lambda name: backdrop)
    assert removed.level == "ok" and removed.removed == 1.0
    pre = {v[0]: _images(v[5], v[3]) for v in with_rgb(views((0.0, 0.0, 0.0)))}
    unremoved = check_views(with_rgb(views((0.0, 0.0, 0.0))), pre.get)
    assert unremoved.level == "refuse" and unremoved.removed == 0.0 and unremoved.cones == 1.0
    asked = []
    check_views(with_rgb(views((1.5, -1.5, 0.0))), lambda name: asked.append(name))
    assert not asked  # the cones refuse already: the reference is not rendered
    # masks over most of the image are no object's: the removal is not judged on them (the coverage
    # and the cones still are), so an unremoved reference under them is no refusal
    whole = [(n, c, a, d, np.ones_like(m), rgb) for n, c, a, d, m, rgb in with_rgb(views((0.0, 0.0, 0.0)))]
    big = check_views(whole, pre.get)
    assert big.removed is None and big.level != "refuse"
