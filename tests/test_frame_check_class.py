"""The frame check on the whole class of frame mismatches, generated (r360gpu.metrics.frame_check).

The splats of both demo scenes (the synthetic room and garden, small) are seen through cameras
moved by similarity transforms, not declared: gsplat's normalize_world_space recomputed from the
cameras (with and without its up-side-down turn), nerfstudio's dataparser transform, and random
similarities (rotations uniform over all rotations, scales 0.1-10 about the origin, the object or
the cameras, shifts up to 1.5 orbit radii).  A case is *wrong* when the moved object's silhouette
overlaps its target masks by an IoU under 0.5 at the checked views (median): the masks then do
not mark the object, and the run must not go on as if they did.  The same moved splats with the
cameras moved into their frame (what ``frame = ...`` / ``--frame`` does), and the scenes as they
are, are correctly framed and must be "ok".  With the reference (the scene without its target) in
the same frame, every wrong frame must be refused.  bench/frame_check_scenes.py draws 100 per scene
and adds the PlayCanvas scans (docs/your-scene.md, "The check")."""
from __future__ import annotations

import numpy as np
import pytest

from frame_class import gsplat_transform, moved_gaussians, nerfstudio_transform, random_similarity
from r360gpu.io.frames import Frame
from r360gpu.metrics import frame_check
from r360gpu.render.sources import SceneSource
from r360gpu.synthetic import make_scene
from r360gpu.synthetic.masks import target_masks

N_RANDOM = 8
IOU_MISMATCH = 0.5


@pytest.fixture(scope="module", params=["room", "garden"])
def demo_scene(request, ctx):
    scene = make_scene(request.param, seed=0, n_views=8, width=128, height=96, detail=0.1)
    masks = target_masks(scene, ctx=ctx)
    cams = {c.name: c for c in scene.cameras}
    pick = frame_check.checked_views([v for v in cams if masks[v].any()])
    return scene, masks, cams, pick


def _verdict(gaussians, frame, scene_masks_cams_pick, ctx, reference=None):
    """The check on ``gaussians`` as pre, the cameras moved by ``frame``; with ``reference``
    (Gaussians in the same frame) the reference's removal is read too."""
    _, masks, cams, pick = scene_masks_cams_pick
    src = SceneSource(gaussians, ctx=ctx, frame=frame)
    ref = None if reference is None else SceneSource(reference, ctx=ctx, frame=frame)
    try:
        views = []
        for v in pick:
            img = src.images(v, cams[v])
            views.append((v, cams[v], img.alpha, img.depth, masks[v], img.rgb))
        return frame_check.check_views(views, None if ref is None else (lambda v: ref.images(v, cams[v])))
    finally:
        src.release()
        if ref is not None:
            ref.release()


def _object_iou(target, demo, ctx) -> float:
    """Median IoU, over the checked views, of the (moved) object's silhouette and its target mask."""
    _, masks, cams, pick = demo
    src = SceneSource(target, ctx=ctx)
    try:
        ious = []
        for v in pick:
            sil = src.images(v, cams[v]).alpha > 0.5
            ious.append((sil & masks[v]).sum() / max(1, (sil | masks[v]).sum()))
        return float(np.median(ious))
    finally:
        src.release()


def _cases(scene):
    """(label, 4x4 similarity cameras' world -> the splats' world) of the class."""
    pts = scene.pre.means[np.random.default_rng(0).choice(scene.pre.n, 3000, replace=False)]  # "sparse points"
    cases = [("gsplat", gsplat_transform(scene.cameras, pts)),
             ("gsplat-noflip", gsplat_transform(scene.cameras, pts, flip=False)),
             ("nerfstudio", nerfstudio_transform(scene.cameras))]
    centres = [np.zeros(3), scene.target.means.mean(axis=0), np.mean([c.center for c in scene.cameras], axis=0)]
    radius = float(np.median([np.linalg.norm(c.center - centres[1]) for c in scene.cameras]))
    rng = np.random.default_rng(2026)
    cases += [(f"random {k}", random_similarity(rng, centres=centres, radius=radius, scales=(0.1, 10.0),
                                                any_rotation=True)) for k in range(N_RANDOM)]
    return cases


def test_wrong_frames_are_refused_and_correct_ones_are_not(demo_scene, ctx):
    scene = demo_scene[0]
    assert _verdict(scene.pre, None, demo_scene, ctx).level == "ok"
    verdicts, still_fits, correct = [], [], []
    for label, m in _cases(scene):
        frame = Frame.from_matrix(m, label)
        moved = moved_gaussians(scene.pre, frame)
        wrong = _verdict(moved, None, demo_scene, ctx)  # the splats moved, the cameras as they are
        iou = _object_iou(moved_gaussians(scene.target, frame), demo_scene, ctx)
        (verdicts if iou < IOU_MISMATCH else still_fits).append((label, wrong.level, wrong.cones, wrong.step))
        correct.append((label, _verdict(moved, frame, demo_scene, ctx).level))  # the frame declared
    print(f"\n{scene.name}: wrong frames {verdicts}; object still under its masks (not asserted) {still_fits}")
    assert all(level == "ok" for _, level in correct), f"correctly framed scenes flagged: {correct}"
    assert not [v for v in verdicts if v[1] == "ok"], f"wrong frames passed as ok: {verdicts}"
    # a wrong frame escapes refusal only into the note, where the outline is flat (module docstring)
    assert all(step < frame_check.STEP_NOTE for _, level, _, step in verdicts if level == "note"), verdicts
    assert sum(level == "refuse" for _, level, _, _ in verdicts) >= 0.9 * len(verdicts)
    assert len(verdicts) >= N_RANDOM // 2  # the class is mostly wrong: the test sees it


def test_with_a_reference_every_wrong_frame_is_refused(demo_scene, ctx):
    """The same class with the reference (the scene without its target, in the same frame as pre):
    every wrong frame refused, the correct ones and the declared frames not."""
    scene = demo_scene[0]
    assert _verdict(scene.pre, None, demo_scene, ctx, scene.background).level == "ok"
    wrong, correct = [], []
    for label, m in _cases(scene):
        frame = Frame.from_matrix(m, label)
        moved, moved_ref = moved_gaussians(scene.pre, frame), moved_gaussians(scene.background, frame)
        if _object_iou(moved_gaussians(scene.target, frame), demo_scene, ctx) < IOU_MISMATCH:
            v = _verdict(moved, None, demo_scene, ctx, moved_ref)
            wrong.append((label, v.level, v.cones, v.removed))
        correct.append((label, _verdict(moved, frame, demo_scene, ctx, moved_ref).level))
    assert all(level == "ok" for _, level in correct), f"correctly framed scenes flagged: {correct}"
    assert all(level == "refuse" for _, level, _, _ in wrong), f"wrong frames not refused: {wrong}"
    assert len(wrong) >= N_RANDOM // 2


def test_the_refusal_names_what_it_saw_and_the_fix(demo_scene, ctx):
    """gsplat's normalised world scored with the unmoved cameras: refused, naming the cause and
    the remedy, the numbers kept in the verdict."""
    scene = demo_scene[0]
    pts = scene.pre.means[np.random.default_rng(0).choice(scene.pre.n, 3000, replace=False)]
    frame = Frame.from_matrix(gsplat_transform(scene.cameras, pts), "gsplat")
    v = _verdict(moved_gaussians(scene.pre, frame), None, demo_scene, ctx)
    assert v.level == "refuse"
    back = frame_check.FrameVerdict.from_dict(v.to_dict())
    assert back == v
    msg = frame_check.mismatch_message(v, source="ply", frame=None, cameras="colmap")
    assert "different world frames" in msg and "--frame gsplat" in msg and "dataparser_transforms.json" in msg


def test_a_flat_outline_is_a_quiet_note_in_results_json(tmp_path, ctx):
    """The room framed right with its masks drawn 3 pixels wide of the sofa: the outline has little
    depth step, the cones agree.  Scored as usual; results.json keeps the note under frame_check,
    with no warning and no frame advice."""
    import cv2

    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.synthetic import write_bundle

    scene = make_scene("room", seed=0, n_views=5, width=96, height=72, detail=0.1)
    folder = write_bundle(scene, tmp_path / "room", methods=["clean"], ctx=ctx)
    for png in sorted((folder / "masks").glob("*.png")):
        m = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(png), cv2.dilate(m, np.ones((7, 7), np.uint8)))
    res = evaluate(folder, options=EvaluateOptions(n_boot=50, n_perm=20, boundary=False, pictures=False,
                                                   controls=False), device=ctx, progress=False)
    check = res["scenes"]["room"]["frame_check"]["pre"]
    assert check["level"] == "note" and check["step"] < frame_check.STEP_NOTE
    assert check["cones"] >= frame_check.CONES_MIN and "little depth step" in check["note"]
    assert not [w for w in res["warnings"] if "frame" in w["message"]]
    assert res["scenes"]["room"]["methods"]["clean"]["axes"]["rqs"] is not None


def test_a_reference_that_still_holds_the_object_is_refused_before_scoring(tmp_path, ctx):
    """The room framed right, but its reference is pre itself: pre and the reference render the
    same thing under the masks, so the run stops before scoring, naming the reading."""
    import shutil

    from r360gpu.errors import InputError
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.synthetic import write_bundle

    scene = make_scene("room", seed=0, n_views=5, width=96, height=72, detail=0.1)
    folder = write_bundle(scene, tmp_path / "room", methods=["clean"], ctx=ctx)
    opts = EvaluateOptions(n_boot=50, n_perm=20, boundary=False, pictures=False, controls=False)
    assert evaluate(folder, options=opts, device=ctx, progress=False)["scenes"]["room"]["frame_check"]["pre"][
        "removed"] >= frame_check.REMOVED_MIN
    shutil.copy(folder / "pre.ply", folder / "reference.ply")
    with pytest.raises(InputError, match="the reference render the same thing under the target masks"):
        evaluate(folder, options=opts, device=ctx, progress=False)
