"""Every 3D output of a bundle, and the comparison of a framed run with the unframed one: shared by
tests/test_frame_invariance.py and bench/frame_invariance_sweep.py.

`outputs` scores a bundle (the synthetic room, clean and floaters) for every 3D output r360gpu
makes: the lifted ``[target]`` of LIFT_VIEWS views' masks and its target masks at the other views,
the target masks of a ``[target]`` of indices, the orbit (poses kept and their poses), residuals
(top ranking, the residual PLY), the pruned what-if, the axes of the capture views, the orbit and
the pruned scenes, and the viewer's live acc_depth at the first evaluation view.  `compare` puts a
framed run beside the unframed one and `failures` names the checks it fails (the tolerances and
why: tests/test_frame_invariance.py's docstring).  `sweep_frame` draws the similarities of the
sweep.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from frame_class import APPLIED  # ns-process-data's applied_transform (COLMAP -> transforms.json world)
from r360gpu.bundle import load_bundle
from r360gpu.io import load_gaussians, load_mask

# what else r360gpu gives is imported where used: bench/frame_invariance.py shares `with_target`
# and may run on another checkout's code

ARGS = dict(seed=0, n_views=5, width=160, height=120, detail=0.25)
ORBIT = 4
LIFT_VIEWS = 3
#: Axes that must agree to 1e-6; every other number of the axes entries to AXES_TOL.
EXACT = ("s_sem", "s_geo")
AXES_TOL = 0.05
#: Orbit camera poses (R, t) and the viewer's live acc_depth: to this.
POSE_TOL = 1e-6
#: Every Gaussian's residual: to this.
RESIDUAL_TOL = 1e-3
AXES_KINDS = ("axes", "orbit_axes", "pruned_axes")
#: scene.toml lines naming a splat file.
_SCENE_KEY = 'scene = "'


def make_room(root: Path, ctx) -> tuple[Path, int, np.ndarray]:
    """The synthetic room at ARGS (clean and floaters) generated under ``root``: (bundle folder, how many
    floaters the floaters method adds, pre's target rows)."""
    from r360gpu.synthetic import generate_benchmark, make_scene

    folder = generate_benchmark(root, scenes=("room",), methods=("clean", "floaters"), ctx=ctx, **ARGS)[0]
    scene = make_scene("room", n_views=ARGS["n_views"], width=ARGS["width"], height=ARGS["height"],
                       detail=ARGS["detail"])
    n_floaters = load_gaussians(load_bundle(folder).methods["floaters"].path).n - scene.background.n
    return folder, n_floaters, np.arange(scene.background.n, scene.pre.n)


def with_target(src: Path, dst: Path, indices=None, views: int = LIFT_VIEWS) -> Path:
    """A copy whose scene.toml has no masks but a [target]: ``views`` views' masks, or ``indices``."""
    shutil.copytree(src, dst)
    text = (dst / "scene.toml").read_text().replace('masks = "masks"\n', "")
    if indices is not None:
        np.save(dst / "target.npy", indices)
        (dst / "scene.toml").write_text(text + '\n[target]\nindices = "target.npy"\n')
        return dst
    shown = [p.stem for p in sorted((dst / "masks").glob("*.png")) if load_mask(p).any()]
    (dst / "given").mkdir()
    for i in np.linspace(0, len(shown) - 1, views).round().astype(int):
        shutil.copy(dst / "masks" / f"{shown[i]}.png", dst / "given" / f"{shown[i]}.png")
    (dst / "scene.toml").write_text(text + '\n[target]\nmasks = "given"\n')
    return dst


def outputs(folder: Path, work: Path, ctx, n_floaters: int, target: np.ndarray) -> dict:
    """Every 3D output of the bundle at ``folder`` (module docstring); ``target``: pre's target rows,
    ``n_floaters``: how many Gaussians the pruned what-if removes."""
    from r360gpu.lift.resolve import lifted_target, resolve_target
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.pipeline.orbit import orbit_bundle
    from r360gpu.render.sources import open_source
    from r360gpu.viewer.layers import build_layers
    from r360gpu.viewer.live import live_axis

    tb = load_bundle(with_target(folder, work / "target"))
    pre = open_source(tb.pre, ctx=ctx)
    try:
        resolved, record = resolve_target(tb, pre, ctx=ctx)
        lifted, _ = lifted_target(tb, pre.gaussians, ctx=ctx, options=pre.render_options, frame=pre.frame)
    finally:
        pre.release()
    assert record["gaussians"] == len(lifted.indices)
    ib = load_bundle(with_target(folder, work / "indices", target))
    pre = open_source(ib.pre, ctx=ctx)
    try:
        by_indices = resolve_target(ib, pre, ctx=ctx)[0].masks
    finally:
        pre.release()
    bundle = load_bundle(folder)
    orbit, info = orbit_bundle(bundle, ORBIT, ctx=ctx)
    opts = EvaluateOptions(n_boot=50, n_perm=20, pictures=False, boundary=False, controls=False, orbit=ORBIT,
                           residuals=True, prune_residuals=n_floaters)
    res = evaluate(bundle, out=work / "out", device=ctx, progress=False, options=opts)["scenes"][bundle.name]
    layers = build_layers(bundle, ctx)
    try:
        view = bundle.views[0]
        cam = bundle.cameras[view]
        live = live_axis(ctx, layers["pre"].image(cam, view), layers["floaters"].image(cam, view),
                         load_mask(bundle.masks[view], shape=(cam.height, cam.width)), "evaluation")
    finally:
        for layer in layers.values():
            layer.release()
    return {"lifted": lifted.indices, "rendered": record["rendered"], "masks": resolved.masks, "by_indices": by_indices,
            "orbit": [(c.name, c.R, c.t) for c in orbit.cameras.values()], "dropped": info["dropped"],
            "axes": {m: e["axes"] for m, e in res["methods"].items()},
            "orbit_axes": {m: e["axes"] for m, e in res["orbit"]["methods"].items()},
            "pruned_axes": {m: e["axes"] for m, e in res["pruned"].items()},
            "residual_top": {m: e["top"] for m, e in res["residuals"].items()},
            "residual_ply": {m: residual_ply(work / "out" / e["file"]) for m, e in res["residuals"].items()},
            "method_files": {m: bundle.methods[m].path for m in res["residuals"]},
            "views": list(bundle.views), "live": live.acc_depth}


def residual_ply(path) -> tuple[np.ndarray, np.ndarray]:
    """((N, 3) float32 vertex positions, (N,) residual) of a residual PLY."""
    from r360gpu.io.ply import read_ply

    v = read_ply(path).arrays["vertex"]
    return np.stack([v["x"], v["y"], v["z"]], 1).astype(np.float32), np.asarray(v["residual"], np.float64)


def _numbers(x, prefix=""):
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _numbers(v, f"{prefix}.{k}")
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            yield from _numbers(v, f"{prefix}[{i}]")
    elif isinstance(x, (int, float)) and not isinstance(x, bool):
        yield prefix, float(x)


def axes_diff(a, b) -> tuple[float, str]:
    """(largest |a - b| over every number of two axes trees, where); (inf, ...) when they differ in shape."""
    na, nb = dict(_numbers(a)), dict(_numbers(b))
    if na.keys() != nb.keys():
        return float("inf"), "different entries: " + ", ".join(sorted(na.keys() ^ nb.keys())[:3])
    return max(((abs(na[k] - nb[k]) if np.isfinite(na[k]) or np.isfinite(nb[k]) else 0.0, k) for k in na),
               default=(0.0, ""))


def compare(out: dict, plain: dict) -> dict:
    """The framed run ``out`` beside the unframed ``plain``: one entry per check (see `failures`)."""
    masks = {v: int(np.count_nonzero(out["masks"][v] != m)) if v in out["masks"] else -1
             for v, m in plain["masks"].items() if v in plain["rendered"]}
    by_indices = {v: int(np.count_nonzero(out["by_indices"][v] != m)) if v in out["by_indices"] else -1
                  for v, m in plain["by_indices"].items()}
    same_orbit = [c[0] for c in out["orbit"]] == [c[0] for c in plain["orbit"]] and out["dropped"] == plain["dropped"]
    pairs = zip(out["orbit"], plain["orbit"])
    pose = max((max(np.abs(a[1] - b[1]).max(), np.abs(a[2] - b[2]).max()) for a, b in pairs),
               default=0.0) if same_orbit else float("inf")
    residual = max(float(np.abs(out["residual_ply"][m][1] - r).max()) if len(out["residual_ply"][m][1]) == len(r)
                   else float("inf") for m, (_, r) in plain["residual_ply"].items())
    # the residual PLY is the method's file, in its own frame
    ply_coords = all(np.array_equal(xyz, load_gaussians(out["method_files"][m]).means)
                     for m, (xyz, _) in out["residual_ply"].items())
    exact = max(abs(out[k][m][axis] - a[axis]) for k in AXES_KINDS for m, a in plain[k].items() for axis in EXACT)
    return {"lifted": np.array_equal(out["lifted"], plain["lifted"]), "n_lifted": len(out["lifted"]),
            "rendered": out["rendered"] == plain["rendered"], "mask_pixels": sum(abs(v) for v in masks.values()),
            "n_masks": len(masks),
            "indices_views": sorted(out["by_indices"]) == sorted(plain["by_indices"]) == sorted(plain["views"]),
            "indices_pixels": sum(abs(v) for v in by_indices.values()), "n_indices": len(by_indices),
            "orbit_kept": same_orbit, "n_orbit": len(out["orbit"]), "pose": pose,
            "top": out["residual_top"] == plain["residual_top"], "residual": residual, "residual_ply": ply_coords,
            "live": abs(out["live"] - plain["live"]), "exact": exact,
            **{k: axes_diff(out[k], plain[k]) for k in AXES_KINDS}}


CHECKS = ("lifted", "rendered", "mask_pixels", "indices_views", "indices_pixels", "orbit_kept", "pose", "top",
          "residual", "residual_ply", "live", "exact", *AXES_KINDS)


def failures(c: dict, checks=CHECKS) -> list[str]:
    """The ``checks`` a `compare` result fails."""
    bounds = {"pose": POSE_TOL, "live": POSE_TOL, "exact": 1e-6, "residual": RESIDUAL_TOL}
    bad = []
    for k in checks:
        if k in bounds:
            ok = c[k] <= bounds[k]
        elif k in AXES_KINDS:
            ok = c[k][0] <= AXES_TOL
        elif k in ("mask_pixels", "indices_pixels"):
            ok = not c[k]
        else:
            ok = bool(c[k])
        if not ok:
            bad.append(k)
    return bad


def file_rounding(folder: Path) -> float:
    """How far storing pre's centres as float32 can have moved one, in the cameras' units: half the
    largest float32 spacing of the file's centre coordinates, divided by its frame's scale."""
    b = load_bundle(folder)
    means = np.abs(np.asarray(load_gaussians(b.pre.path).means, np.float32))
    return float(np.spacing(means).max()) / 2 / (b.pre.frame.scale if b.pre.frame is not None else 1.0)


def undone_bundle(folder: Path, moved: Path, frame, dst: Path) -> Path:
    """A copy of the unframed bundle ``folder`` whose splat files are those of ``moved`` (in ``frame``)
    moved back into the cameras' world in float64 and stored again, no frame declared: the float32
    rounding of the moved files, without any frame handling."""
    return rewritten(folder, dst, lambda rel: undone(load_gaussians(moved / rel), frame))


def rewritten(src: Path, dst: Path, make) -> Path:
    """A copy of bundle ``src`` whose every splat file is ``make(relative path)``."""
    from r360gpu.io.inria_ply import save_ply

    shutil.copytree(src, dst)
    for line in (dst / "scene.toml").read_text().splitlines():
        if line.startswith(_SCENE_KEY):
            rel = Path(line[len(_SCENE_KEY):].rstrip('"'))
            save_ply(dst / rel, make(rel))
    return dst


def undone(g, frame):
    """Gaussians of a file in ``frame`` moved back into the cameras' world, in float64 before storing."""
    from r360gpu.io.gaussians import Gaussians
    from r360gpu.io.rotation import quat_to_rotmat, rotmat_to_quat

    back = frame.rotation.T
    quats = np.array([rotmat_to_quat(back @ m) for m in quat_to_rotmat(g.quats)])
    return Gaussians(frame.points_back(g.means), np.asarray(g.scales, np.float64) / frame.scale, quats,
                     g.opacities, g.sh)


def ulp_moved(g, rng):
    """``g`` with every centre coordinate moved to a random float32 neighbour or kept."""
    from r360gpu.io.gaussians import Gaussians

    m = np.asarray(g.means, np.float32)
    step = rng.integers(-1, 2, size=m.shape)
    moved = np.where(step > 0, np.nextafter(m, np.float32(np.inf)),
                     np.where(step < 0, np.nextafter(m, np.float32(-np.inf)), m))
    return Gaussians(moved, g.scales, g.quats, g.opacities, g.sh)


def nerfstudio_applied(folder: Path, dst: Path) -> Path:
    """A copy of a nerfstudio layout whose transforms.json records ns-process-data's applied_transform
    (APPLIED) and whose dataparser transforms include it, as nerfstudio writes them: the same cameras
    and splats, the frame reached through the applied transform."""
    shutil.copytree(folder, dst)
    tj = dst / "data" / "transforms.json"
    doc = json.loads(tj.read_text())
    doc["applied_transform"] = APPLIED.tolist()
    tj.write_text(json.dumps(doc))
    a = np.eye(4)
    a[:3] = APPLIED
    for dp in dst.glob("exports/*/dataparser_transforms.json"):
        d = json.loads(dp.read_text())
        t = np.eye(4)
        t[:3] = d["transform"]
        d["transform"] = (t @ a)[:3].tolist()
        dp.write_text(json.dumps(d))
    return dst


def scene_radius(means) -> float:
    """The largest distance of a Gaussian centre from their mean."""
    m = np.asarray(means, np.float64)
    return float(np.linalg.norm(m - m.mean(axis=0), axis=1).max())


def sweep_frame(seed: int, radius: float):
    """The sweep's similarity for ``seed``: a uniform random rotation; scale 0.1 when seed % 4 == 0, 10
    when seed % 4 == 1, log-uniform in [0.1, 10] otherwise; a shift of ``k`` scene radii (``radius``,
    in the splats' units: times the scale) in a random direction, ``k`` = 100 when seed % 3 == 0,
    log-uniform in [0.1, 100] otherwise: a `Frame`."""
    from r360gpu.io.frames import Frame
    from r360gpu.synthetic.frames import random_similarity

    rng = np.random.default_rng(seed)
    scale = {0: (0.1, 0.1), 1: (10.0, 10.0)}.get(seed % 4, (0.1, 10.0))
    frame = random_similarity(rng, scale=scale, shift=0.0)
    k = 100.0 if seed % 3 == 0 else float(10 ** rng.uniform(-1, 2))
    d = rng.normal(size=3)
    m = frame.m
    m[:3, 3] = k * frame.scale * radius * d / np.linalg.norm(d)
    return Frame.from_matrix(m, f"sweep similarity (seed {seed}, shift {k:.3g} scene radii)")
