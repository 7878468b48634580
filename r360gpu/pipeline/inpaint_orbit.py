"""The inpainting metrics at orbit poses, against the reference reconstruction's renders (``inpaint --orbit N``).

No photograph exists away from the captured test views, so there the stand-in for the scene
without the object is the reference reconstruction (``--reference``, a splat scene of the scene
without it).  The poses are those of ``score --orbit`` (`r360gpu.pipeline.orbit.orbit_bundle`:
N cameras around the target lifted onto pre, placed and checked against the scene's test cameras,
dropping poses inside geometry or where the target is unseen), the masks the target's at each pose.  Every method given as a splat scene is rendered
there and scored with the benchmark's PSNR / SSIM / masked PSNR / masked SSIM against the
reference's render; a method given as renders cannot be rendered there and is listed under
``no_orbit``.  The values go in a table of their own, marked "against the reference
reconstruction, not photographs", never into the photograph means.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..io.inpaint_folders import SceneFiles
from ..metrics.inpainting import InpaintScene, score_views, summarise
from ..render.sources import SceneSource
from ..util.warning_log import warn, where
from .inpaint_target import scene_bundle
from .orbit import RENDERINGS_ONLY, orbit_bundle

#: How the orbit's values are marked in results.json and the tables.
AGAINST_REFERENCE = "against the reference reconstruction, not photographs"


@dataclass
class OrbitScene:
    """One scene's orbit: the poses kept and dropped (``info``, as ``score --orbit`` records them) and
    each splat method's values against the reference's renders."""

    scene: str
    info: dict
    results: list[InpaintScene] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"against": AGAINST_REFERENCE, **self.info, "methods": {r.method: r.to_dict() for r in self.results}}


def _render(spec, cams, ctx=None) -> list[np.ndarray]:
    src = SceneSource(str(spec.path), frame=spec.frame, ctx=ctx)
    try:
        return [src.images(c.name, c).rgb for c in cams]
    finally:
        src.release()


def orbit_scores(scene: SceneFiles, n: int, *, pre: str, target: str, reference: str, frame: str | None,
                mode: str, quantise=None, models: dict | None = None) -> OrbitScene:
    """The orbit of ``scene`` at ``n`` requested poses (see the module docstring).  quantise: applied to
    every render in compat mode (the 8 bits the benchmark's renders are saved with).  models: the
    LPIPS exports (``lpips``, ``lpips_spatial``) as `r360gpu.metrics.inpainting.score_views` takes them."""
    splats = {m.name: m.scene for m in scene.methods if m.scene is not None}
    with where(scene=scene.name):
        bundle = scene_bundle(scene, pre, target, frame, reference=reference, methods=splats)
        orbit, info = orbit_bundle(bundle, n, warn=warn)
    info = {**info, "no_orbit": {m.name: RENDERINGS_ONLY for m in scene.methods if m.scene is None}}
    out = OrbitScene(scene.name, info)
    if orbit is None:
        return out
    cams = [orbit.cameras[v] for v in orbit.views]
    prep = quantise if (mode == "compat" and quantise is not None) else (lambda x: x)
    ref = [prep(r) for r in _render(bundle.reference, cams)]
    rendered = {m: [prep(r) for r in _render(spec, cams)] for m, spec in orbit.methods.items()}
    views: dict[str, list] = {m: [] for m in rendered}
    for k, c in enumerate(cams):
        weights = orbit.masks[c.name].astype(np.float64)
        recs = score_views(c.name, ref[k], [rendered[m][k] for m in rendered], [weights] * len(rendered), mode=mode,
                           **(models or {}))
        for m, rec in zip(rendered, recs):
            views[m].append(rec)
    out.results = [summarise(scene.name, m, views[m], mode=mode, masks="lifted target at the orbit poses")
                   for m in rendered]
    return out
