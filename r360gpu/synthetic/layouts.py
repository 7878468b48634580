"""A splat bundle written again in the layouts trainers and the public evaluation code leave.

`write_layouts` converts a bundle (scene.toml; splat sources in its cameras'
frame, COLMAP or any camera file r360gpu reads) into four folders that score
as the bundle does, so that every walkthrough of docs/your-scene.md has data to run on::

    <out>/inria/<scene>/         output/<source>/point_cloud/iteration_30000/point_cloud.ply
                                 output/<source>/cameras.json, masks/, scene.toml
    <out>/gsplat/<scene>/        colmap/sparse/0/{cameras,images,points3D}.bin, results/ply/point_cloud_29999.ply
                                 (pre), results/<source>.ply, masks/, scene.toml (frame = "gsplat")
    <out>/nerfstudio/<scene>/    data/transforms.json, exports/<source>/splat.ply with its
                                 dataparser_transforms.json, masks/, scene.toml
    <out>/public/<method>/<scene>_<prompt>/   rgb/{before,after,reference}/<view>.png (16-bit),
                                 depth/{before,after,reference}/<view>.npy (float32), masks/, prompt.txt

gsplat's PLYs are in gsplat's normalised world (``normalize_world_space``,
recomputed by :func:`r360gpu.io.frames.gsplat_normalization` from the cameras
and the sparse points; the sparse points are 3000 of pre's centres, as a
COLMAP model of the scene would hold); nerfstudio's are in a dataparser frame
(poses centred on their mean, turned by 30 degrees about z and scaled into
[-1, 1], like ``auto_orient_and_center_poses`` and ``auto_scale_poses``).  The
renderer's near plane is in the splats' units, so those two layouts give each
source ``near = scale x`` :data:`~r360gpu.render.conventions.NEAR_PLANE`: the
same Gaussians culled as in the bundle.  Moving splats into another frame
needs degree-0 colour (`moved_gaussians`).

The public layout holds one method per folder (named ``after`` when scored)
and the r360gpu extension ``rgb/reference``; its renders are r360gpu's own, so
it scores as the bundle up to the 16-bit rounding of the colours.

Each layout folder is written beside its final place and renamed into it;
an earlier folder written by this module (it holds :data:`MARKER`) is
replaced, any other existing folder is refused.
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from ..io import load_cameras, load_gaussians, save_cameras_json, save_colmap, save_ply, save_transforms_json
from ..io.colmap_points import save_points3d
from ..io.frames import DATAPARSER_TRANSFORMS, Frame, gsplat_normalization
from ..io.gaussians import Gaussians
from .bundle import _toml_str
from .frames import moved_gaussians

LAYOUTS = ("inria", "gsplat", "nerfstudio", "public")
#: Marker of a folder written here (a folder holding it may be replaced).
MARKER = "r360-layout.json"
#: How many of pre's centres stand in for gsplat's COLMAP sparse points.
SPARSE_POINTS = 3000


def write_layouts(bundle: str | os.PathLike, out: str | os.PathLike, *, layouts=LAYOUTS, ctx=None) -> dict:
    """Write the bundle at ``bundle`` in each of ``layouts`` under ``out`` (see the module docstring);
    returns {layout: [folders written]}."""
    from ..bundle import load_bundle

    unknown = [x for x in layouts if x not in LAYOUTS]
    if unknown or not layouts:
        raise InputError(f"unknown or no layouts {unknown}; known: {', '.join(LAYOUTS)}")
    b = load_bundle(bundle)
    sources = {"pre": b.pre, **({"reference": b.reference} if b.reference is not None else {}), **b.methods}
    for name, spec in sources.items():
        if spec.kind != "scene" or spec.frame is not None:
            raise InputError(f"source {name!r} is not a splat file in the cameras' frame; only such bundles "
                             "are converted", b.config or b.root)
    cameras = load_cameras(b.cameras_path)  # every camera, not only the evaluation views
    splats = {name: load_gaussians(spec.path) for name, spec in sources.items()}
    out = Path(out)
    written: dict[str, list[Path]] = {}
    for layout in layouts:
        if layout == "public":
            shared: dict = {}
            written[layout] = [_public(b, m, out / "public" / m / f"{b.name}_{b.prompt}", ctx, shared)
                               for m in b.methods]
        else:
            writer = {"inria": _inria, "gsplat": _gsplat, "nerfstudio": _nerfstudio}[layout]
            written[layout] = [_into(out / layout / b.name, lambda d: writer(b, cameras, splats, d))]
    return written


def _into(folder: Path, write) -> Path:
    """Run ``write(tmp)`` into a fresh folder beside ``folder``, then put it in ``folder``'s place."""
    if folder.exists() and not (folder / MARKER).is_file():
        raise InputError(f"exists and holds no {MARKER} (not written by r360gpu); refusing to replace it", folder)
    tmp = folder.with_name(f".{folder.name}.writing")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        write(tmp)
        (tmp / MARKER).write_text(json.dumps({"generator": "r360gpu.synthetic.layouts"}) + "\n")
        if folder.exists():
            shutil.rmtree(folder)
        tmp.rename(folder)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return folder


def _masks(b, folder: Path) -> None:
    (folder / "masks").mkdir()
    for view, path in b.masks.items():
        shutil.copy(path, folder / "masks" / f"{view}.png")


def _toml(b, cameras: str, scenes: dict[str, str], *, top: str = "", near: float | None = None) -> str:
    lines = [f"name = {_toml_str(b.name)}", f"prompt = {_toml_str(b.prompt)}", f"cameras = {_toml_str(cameras)}",
             'masks = "masks"', *([top] if top else [])]
    for name, path in scenes.items():
        table = name if name in ("pre", "reference") else f"methods.{name}"
        lines += ["", f"[{table}]", f"scene = {_toml_str(path)}"]
        if near is not None:
            lines.append(f"near = {near!r}    # the near plane in the splats' units")
    return "\n".join(lines) + "\n"


def _inria(b, cameras, splats, folder: Path) -> None:
    _masks(b, folder)
    for name, g in splats.items():
        run = folder / "output" / name
        save_ply(run / "point_cloud" / "iteration_30000" / "point_cloud.ply", g)
        save_cameras_json(run / "cameras.json", cameras)
    (folder / "scene.toml").write_text(_toml(b, "output/pre/cameras.json", {n: f"output/{n}" for n in splats}))


def _degree0(name: str, g: Gaussians) -> Gaussians:
    if g.sh.shape[1] > 1 and np.any(g.sh[:, 1:]):
        raise InputError(f"source {name!r} has view-dependent colour (SH degree {g.sh_degree}); moving it into a "
                         "trainer's frame would need its spherical harmonics rotated")
    return g.with_sh_degree(0)


def _near(frame: Frame) -> float:
    from ..render.conventions import NEAR_PLANE

    return NEAR_PLANE * frame.scale


def _gsplat(b, cameras, splats, folder: Path) -> None:
    _masks(b, folder)
    sparse = folder / "colmap" / "sparse" / "0"
    save_colmap(sparse, cameras, binary=True)
    pre = splats["pre"]
    points = pre.means[np.random.default_rng(0).choice(pre.n, min(SPARSE_POINTS, pre.n), replace=False)]
    save_points3d(sparse, points)
    frame = gsplat_normalization(sorted(cameras, key=lambda c: c.name), np.asarray(points, np.float64))
    paths = {n: ("results/ply/point_cloud_29999.ply" if n == "pre" else f"results/{n}.ply") for n in splats}
    for name, g in splats.items():
        save_ply(folder / paths[name], moved_gaussians(_degree0(name, g), frame))
    (folder / "scene.toml").write_text(_toml(b, "colmap", paths, top='frame = "gsplat"', near=_near(frame)))


def nerfstudio_like_frame(cameras) -> Frame:
    """A dataparser frame as nerfstudio's would be: the poses centred on their mean, turned by 30
    degrees about z, and scaled so that the farthest camera centre is 1 from the origin."""
    centres = np.stack([c.center for c in cameras])
    a = np.radians(30.0)
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    shift = -turn @ centres.mean(axis=0)
    scale = 1.0 / np.max(np.linalg.norm(centres @ turn.T + shift, axis=1))
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = scale * turn, scale * shift
    return Frame.from_matrix(m, "nerfstudio-like dataparser transform")


def _nerfstudio(b, cameras, splats, folder: Path) -> None:
    _masks(b, folder)
    save_transforms_json(folder / "data" / "transforms.json", cameras)
    frame = nerfstudio_like_frame(cameras)
    transform = np.concatenate([frame.rotation, frame.translation[:, None] / frame.scale], axis=1)
    for name, g in splats.items():
        export = folder / "exports" / name
        save_ply(export / "splat.ply", moved_gaussians(_degree0(name, g), frame))
        (export / DATAPARSER_TRANSFORMS).write_text(json.dumps({"transform": transform.tolist(),
                                                                "scale": frame.scale}, indent=2) + "\n")
    (folder / "scene.toml").write_text(_toml(b, "data/transforms.json", {n: f"exports/{n}/splat.ply" for n in splats},
                                             near=_near(frame)))


def _rendered(b, spec, ctx) -> dict[str, tuple[bytes, np.ndarray]]:
    """{view: (16-bit RGB PNG bytes, float32 depth)} of a splat source at the bundle's evaluation views."""
    from ..render.sources import open_source

    source = open_source(spec, ctx=ctx, background=b.options.background, depth=b.options.depth)
    out = {}
    try:
        for view in b.views:
            im = source.images(view, b.cameras[view])
            rgb = np.round(np.clip(im.rgb, 0.0, 1.0) * 65535.0).astype(np.uint16)
            ok, png = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            if not ok:
                raise RuntimeError("OpenCV could not encode a PNG")
            out[view] = (png.tobytes(), np.asarray(im.depth, np.float32))
    finally:
        source.release()
    return out


def _public(b, method: str, folder: Path, ctx, shared: dict) -> Path:
    """One method's public folder; ``shared`` keeps pre's and the reference's renders for the next method."""
    def write(tmp: Path) -> None:
        _masks(b, tmp)
        (tmp / "prompt.txt").write_text(b.prompt + "\n")
        sides = {"before": b.pre, "after": b.methods[method]}
        if b.reference is not None:
            sides["reference"] = b.reference
        for side, spec in sides.items():
            renders = shared.get(side) or _rendered(b, spec, ctx)
            if side != "after":
                shared[side] = renders
            for sub in ("rgb", "depth"):
                (tmp / sub / side).mkdir(parents=True)
            for view, (png, depth) in renders.items():
                (tmp / "rgb" / side / f"{view}.png").write_bytes(png)
                np.save(tmp / "depth" / side / f"{view}.npy", depth)

    return _into(folder, write)
