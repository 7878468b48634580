"""Object masks at the inpainting benchmarks' test views from r360gpu's lifted target, for methods without masks.

A method scored without ``object_mask/`` and without ``--masks`` has no masked metrics.  Given
pre's splats (``--pre``, the reconstruction with the object) and the object as scene.toml's
``[target]`` gives it (``--target``: `parse_target`), the target is made concrete over pre's
Gaussians by the code ``score`` runs (`r360gpu.lift.resolve.lifted_target`) and its mask is
rendered at each test camera (`r360gpu.lift.masks.TargetMaskRenderer`): a binary mask, the same
in default and compat mode.  results.json and the report mark those masks as lifted.

``--target`` forms (``{scene}`` allowed in paths):

* ``FILE.npy`` / ``FILE.ply``: pre's Gaussian indices (``[target].indices``);
* ``box:X0,Y0,Z0,X1,Y1,Z1``: the Gaussians whose centre is in that box, in pre's coordinates;
* ``masks:FOLDER``: masks of some cameras of the camera set (``<image stem>.png``, e.g. 360-USID's
  training ``object_masks/``), lifted onto pre's Gaussians; each camera is scaled to its mask's size.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..bundle.model import Bundle, SourceSpec
from ..bundle.target import TargetSpec
from ..errors import InputError
from ..io.box import Box
from ..io.inpaint_folders import SceneFiles
from ..io.load import latest_inria_iteration, load_cameras
from ..io.masks import mask_size
from ..io.photo_cameras import ASPECT_TOLERANCE
from ..lift.masks import TargetMaskRenderer
from ..lift.resolve import lifted_target
from ..render.sources import SceneSource
from ..util.warning_log import warn

#: What results.json and the report say of masks made here.
LIFTED_NOTE = "lifted target: r360gpu's target over pre's Gaussians, rendered at the test cameras"


@dataclass
class LiftedMasks:
    """The lifted target's masks at a scene's test views ((H, W) float64 0/1, view order) and the record."""

    masks: list[np.ndarray]
    record: dict


def parse_target(value: str) -> tuple[str, object]:
    """``--target`` as (kind, value): ("indices", path template), ("box", Box) or ("masks", folder template)."""
    if value.startswith("box:"):
        try:
            v = [float(x) for x in value[4:].split(",")]
        except ValueError:
            v = []
        if len(v) != 6:
            raise InputError(f"--target box:X0,Y0,Z0,X1,Y1,Z1 takes 6 numbers, got {value[4:]!r}")
        return "box", Box.from_table({"min": v[:3], "max": v[3:]}, where="--target box")
    if value.startswith("masks:"):
        return "masks", value[6:]
    return "indices", value


def _spec(kind: str, value, scene: str) -> TargetSpec:
    if kind == "box":
        return TargetSpec(box=value)
    path = Path(value.replace("{scene}", scene))
    if not path.exists():
        raise InputError(f"no target {kind} here (--target)", path)
    return TargetSpec(indices=path) if kind == "indices" else TargetSpec(masks=path)


def _mask_views(folder: Path, camera_set: Path) -> tuple[dict, dict]:
    """({stem: camera scaled to its mask}, {stem: mask file}) of the masks in ``folder`` named after an
    image of the camera set."""
    if not folder.is_dir():
        raise InputError("--target masks: is not a folder", folder)
    cams = {c.name.replace("\\", "/").rsplit("/", 1)[-1].split(".")[0]: c for c in load_cameras(camera_set)}
    out_c, out_m = {}, {}
    for f in sorted(folder.iterdir()):
        if f.suffix.lower() != ".png" or f.stem not in cams:
            continue
        h, w = mask_size(f)
        c = cams[f.stem]
        if abs((w / h) / (c.width / c.height) - 1.0) > ASPECT_TOLERANCE:
            raise InputError(f"mask is {w}x{h} but camera {c.name!r} of {camera_set} is {c.width}x{c.height}, "
                             f"another aspect ratio", f)
        out_c[f.stem], out_m[f.stem] = replace(c.resized(w, h), name=f.stem), f
    if not out_m:
        raise InputError(f"no <image stem>.png mask here names an image of the camera set {camera_set}", folder)
    return out_c, out_m


def scene_bundle(scene: SceneFiles, pre: str, target: str, frame: str | None, *, reference: str | None = None,
                 methods: dict[str, Path] | None = None) -> Bundle:
    """A `Bundle` of ``scene``'s test views (the cameras of its photographs) with pre, the target as
    ``--target`` gives it, and the reference and methods' splat files (paths with {scene} filled), each
    in the world frame ``frame`` names: what lifting and the orbit read."""
    from ..io.frames import resolve_frame

    if scene.cameras is None:
        raise InputError(f"scene {scene.name}: the lifted target needs the test cameras (sparse/0 or --cameras)",
                         scene.folder)
    kind, value = parse_target(target)
    spec = _spec(kind, value, scene.name)
    cams, masks = _mask_views(spec.masks, scene.camera_set) if kind == "masks" else ({}, {})

    def source(path) -> SourceSpec:
        path = Path(str(path).replace("{scene}", scene.name))
        if path.is_dir():
            path = latest_inria_iteration(path)
        if not path.is_file():
            raise InputError("no splat scene here", path)
        return SourceSpec("scene", path, frame=resolve_frame(frame, scene=path, cameras=scene.camera_set))

    test = {c.name: c for c in scene.cameras}
    return Bundle(root=scene.folder, name=scene.name, prompt="", views=list(test), cameras={**cams, **test},
                  masks=masks, pre=source(pre), reference=None if reference is None else source(reference),
                  methods={m: source(p) for m, p in (methods or {}).items()}, layout="objects", target=spec)


def lifted_masks(scene: SceneFiles, pre: str, target: str, frame: str | None) -> LiftedMasks:
    """The lifted target's masks at ``scene``'s test cameras; ``pre`` the splat template ({scene} allowed),
    ``target`` the ``--target`` value, ``frame`` pre's world frame as ``--frame`` names it."""
    bundle = scene_bundle(scene, pre, target, frame)
    src = SceneSource(str(bundle.pre.path), frame=bundle.pre.frame)
    try:
        lifted, _ = lifted_target(bundle, src.gaussians, ctx=src.renderer.ctx, options=src.render_options,
                                  frame=src.frame, warn=warn)
        r = TargetMaskRenderer(src.gaussians, lifted.target, ctx=src.renderer.ctx, options=src.render_options,
                               frame=src.frame)
        try:
            out = [r.mask(c).astype(np.float64) for c in scene.cameras]
        finally:
            r.release()
    finally:
        src.release()
    record = {"source": lifted.source, "target": target, "pre": str(bundle.pre.path),
              "gaussians": int(lifted.target.sum()), "of": int(src.gaussians.n), "lifted_from": list(lifted.views),
              "note": LIFTED_NOTE}
    return LiftedMasks(out, record)
