"""Orbit scoring (``--orbit N``): the scene scored from all around the target, not only where the capture looked.

For a scene whose pre is a splat scene with cameras: the target is lifted
(:mod:`r360gpu.lift`), N cameras are placed around it
(:func:`r360gpu.lift.orbit.orbit_cameras`), poses inside geometry or with the
target unseen in pre are dropped (counted by reason: "inside geometry", "never seen" by the
capture, "target occluded"), and pre, the
reference and every splat method are rendered there and scored with the
same probes, the masks being the lifted target's.  The result is a scene
entry of its own (axes, RQS, views) that goes under ``scenes.S.orbit``,
never into the capture-view axes.  A method (or reference) given as renderings
is scored there from its renderings at the orbit poses when its source names
them (``orbit = "FOLDER"``: ``rgb/``, ``depth/`` and the ``cameras.json`` they
were made at, which must hold this run's kept poses); otherwise it is listed
under ``no_orbit`` ("renderings only").
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..bundle.model import Bundle
from ..errors import InputError
from ..io import Gaussians, load_gaussians
from ..io.frames import depth_in_cameras, in_frame, points_in_cameras
from ..lift.device import MaskLifter
from ..lift.masks import TargetMaskRenderer
from ..lift.orbit import captured, keep_pose, OCCLUDED, orbit_cameras, seen_share
from ..lift.resolve import scene_target
from ..render import Renderer
from ..render.conventions import RenderOptions
from ..render.sources import frame_of
from ..schema import OrbitEntry
from .reusable import write_orbit, write_target

RENDERINGS_ONLY = "no orbit (renderings only)"


def _is_scene(spec) -> bool:
    return isinstance(spec, Gaussians) or spec.kind == "scene"


def _at_orbit(spec):
    """The source ``spec`` is scored from at the orbit: itself for a splat scene, its orbit renders
    (`r360gpu.bundle.SourceSpec.orbit`) for renderings, None when it has none."""
    return spec if _is_scene(spec) else getattr(spec, "orbit", None)


def orbit_renders_problem(orbit) -> str | None:
    """Why the orbit renderings of ``orbit``'s renders sources cannot be scored at its poses (they
    were made at other poses, or lack some), in one message naming each folder; None when they can."""
    from ..bundle.model import ORBIT_CAMERAS
    from ..bundle.sources import orbit_pose_problems

    poses = [orbit.cameras[v] for v in orbit.views]
    named = {"the reference": orbit.reference, **{f"method {m!r}": s for m, s in orbit.methods.items()}}
    lines = []
    for name, spec in named.items():
        if spec is not None and not _is_scene(spec):
            why = orbit_pose_problems(spec, poses)
            if why:
                lines.append(f"{name}, {spec.path / ORBIT_CAMERAS}: {'; '.join(why)}")
    if not lines:
        return None
    return ("orbit renderings made at other poses than this run's orbit: " + " | ".join(lines)
            + ". Render every pose of the cameras.json this run's orbit writes (orbit/SCENE/cameras.json: "
            "score once without the 'orbit' key, or with the --orbit options the renderings were made for)")


def _gaussians(spec):
    """(Gaussians, RenderOptions or None, world frame or None) of a splat source ``spec``."""
    if isinstance(spec, Gaussians):
        return spec, None, None
    settings = getattr(spec, "render", None)
    return (load_gaussians(spec.path), RenderOptions(**(settings.given() if settings is not None else {})),
            frame_of(spec))


def orbit_bundle(bundle, n: int, *, ctx=None, warn=None, orbit_shape=None):
    """(orbit bundle or None, info) for ``bundle`` (its masks already resolved).

    orbit_shape: {"radius", "elevation", "azimuth"} for
    `r360gpu.lift.orbit.orbit_cameras` (None: its defaults).

    info: {"requested", "kept", "dropped": {reason: count}, "no_orbit": {method: why}} plus
    "note" when no orbit is possible.
    """
    return _orbit(bundle, n, ctx=ctx, warn=warn, orbit_shape=orbit_shape)[:2]


def _orbit(bundle, n: int, *, ctx=None, warn=None, orbit_shape=None):
    """(orbit bundle or None, info, (pre's Gaussians, LiftedTarget) or None): `orbit_bundle` and
    the target it lifted."""
    info: dict = {"requested": int(n), "kept": 0, "dropped": {}, "no_orbit": {}}
    if orbit_shape:
        info["shape"] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in orbit_shape.items()}
    if not _is_scene(bundle.pre) or not bundle.cameras:
        info["note"] = "no orbit: pre is renderings only (or has no cameras)"
        return None, info, None
    for m, spec in bundle.methods.items():
        if not _is_scene(spec) and getattr(spec, "orbit", None) is None:
            info["no_orbit"][m] = RENDERINGS_ONLY
    methods = {m: _at_orbit(s) for m, s in bundle.methods.items() if m not in info["no_orbit"]}
    if not methods:
        info["note"] = "no orbit: every method is renderings only"
        return None, info, None
    g, options, frame = _gaussians(bundle.pre)
    given = [bundle.cameras[v] for v in bundle.views if v in bundle.cameras]
    # what the capture saw ("never seen" vs "target occluded") is summed in the lift's own passes
    lifted = scene_target(bundle, g, ctx=ctx, options=options, frame=frame, warn=warn, capture=given)
    # the poses live in the cameras' world, as the evaluation views do; each source sees them in its frame
    centre, _ = lifted.extent(points_in_cameras(frame, g.means))
    shape = orbit_shape or {}
    cams = orbit_cameras(centre, given, n, **shape)
    pre_r = Renderer(g, ctx=ctx, options=options)
    alone = Renderer(g.subset(lifted.target), ctx=ctx, options=options)
    masks_r = TargetMaskRenderer(g, lifted.target, ctx=ctx, options=options, frame=frame)
    side, by_capture = None, None  # the target's side a pose sees, and what the capture saw: when asked
    kept, masks = [], {}
    try:
        for cam in cams:
            seen = in_frame(frame, cam)
            pre = pre_r.render(seen)
            mask = masks_r.mask(cam)
            args = (pre.alpha, depth_in_cameras(frame, pre.median_depth), mask, alone.render(seen).alpha >= 0.5,
                    float(np.linalg.norm(cam.center - centre)))
            why = keep_pose(*args)
            if why == OCCLUDED:  # or is this side of the target one no given view saw?
                if side is None:
                    by_capture = captured(g, lifted.target, given, ctx=ctx, options=options, frame=frame,
                                          weights=lifted.w_capture)
                    side = MaskLifter(g.subset(lifted.target), ctx=ctx, options=options)
                side.reset()
                side.add_view(seen, np.ones((cam.height, cam.width), np.float32))
                why = keep_pose(*args, seen_share=seen_share(side.weights()[0], by_capture))
            if why is None:
                kept.append(cam)
                masks[cam.name] = mask
            else:
                info["dropped"][why] = info["dropped"].get(why, 0) + 1
    finally:
        for r in (pre_r, alone, masks_r, side):
            if r is not None:
                r.release()
    info["kept"] = len(kept)
    if info["dropped"] and warn is not None:
        warn(f"orbit: {sum(info['dropped'].values())} of {n} poses dropped ("
             + ", ".join(f"{k}: {v}" for k, v in sorted(info["dropped"].items())) + ")")
    if not kept:
        info["note"] = "no orbit: every pose was dropped"
        return None, info, (g, lifted)
    reference = None if bundle.reference is None else _at_orbit(bundle.reference)
    if bundle.reference is not None and reference is None:
        info["note"] = "reference is renderings only: the orbit is scored reference-free"
    views = [c.name for c in kept]
    orbit = Bundle(root=bundle.root, name=bundle.name, prompt=bundle.prompt, views=views,
                   cameras={c.name: c for c in kept}, masks=masks, pre=bundle.pre, reference=reference,
                   methods=methods, options=bundle.options, layout="objects",
                   method_pres={m: s for m, s in bundle.method_pres.items() if m in methods and _is_scene(s)})
    return orbit, info, (g, lifted)


def score_orbit(bundle, opts, open_run, evaluate_scene, *, ctx=None, warn=None, out=None) -> OrbitEntry:
    """The ``scenes.S.orbit`` entry: the orbit bundle scored like a scene, with its poses' ``info``.

    open_run(bundle, opts) opens a SceneRun; evaluate_scene(run) scores it (the pipeline's own).
    out: the output folder (None: nothing written), where the kept poses' cameras.json and target
    masks, and the lifted target, go (`r360gpu.pipeline.reusable`; paths under "files").
    """
    try:
        orbit, info, lifted = _orbit(bundle, opts.orbit, ctx=ctx, warn=warn, orbit_shape=opts.orbit_shape())
    except InputError as e:
        if warn is not None:
            warn(f"orbit: {e.problem}")
        return OrbitEntry({"requested": int(opts.orbit), "kept": 0, "note": f"no orbit: {e.problem}"})
    problem = None if orbit is None else orbit_renders_problem(orbit)
    if problem is not None:  # an error, not a warning: the user's renderings would be scored at other poses
        raise InputError(problem)
    if out is not None and lifted is not None:
        files = info["files"] = {}
        if bundle.target is None:  # a [target]'s lift is written with the scene's
            files["target"] = write_target(out, bundle.name, lifted[0], lifted[1].target, {}, source=getattr(bundle.pre, "path", None))
        if orbit is not None:
            files.update(write_orbit(out, bundle.name, [orbit.cameras[v] for v in orbit.views], orbit.masks))
    if orbit is None:
        return OrbitEntry(info)
    # views=None: the orbit's views are its own cameras, and its cache key names no capture selection
    run = open_run(orbit, replace(opts, views=None, orbit=0))
    try:
        res = evaluate_scene(run)
    finally:
        run.release()
    return OrbitEntry(info, res)
