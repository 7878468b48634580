"""Target masks of a synthetic scene: the visible pixels of the target, like annotated masks.

Per view the target alone and the background alone (the reference scene) are
rendered; a pixel is target when the target covers it (alpha > 0.5) and is
in front of whatever the background shows there::

    M(p) = alpha_target(p) > 0.5  and  (D_target(p) < D_background(p) + MASK_DEPTH_EPS
                                         or the background does not cover p)

with D the expected depth of each render.  Pixels where an occluder (a plant,
a tree, a table) is in front of the target are therefore not target, and a
view that does not frame the target has an empty mask.
"""
from __future__ import annotations

import numpy as np

from ..render import NO_COVERAGE_ALPHA, Renderer
from .scene import SyntheticScene

#: Depth slack (metres) in the "target in front" test: where the target touches the floor
#: the two depths agree up to the Gaussians' thickness.
MASK_DEPTH_EPS = 0.02
#: A pixel belongs to the target's silhouette when the target alone covers more than this.
MASK_ALPHA = 0.5


def target_masks(scene: SyntheticScene, *, ctx=None, progress: bool = False, reference=None, cameras=None,
                 kept=None) -> dict[str, np.ndarray]:
    """Target mask (H, W) bool of every camera of ``scene``, by camera name.

    Renders each view twice (target alone, background alone) on ``ctx``
    (default: the shared GPU context).  reference: the source the background
    is rendered from (default: ``scene.background`` in memory) and cameras:
    the cameras (default: ``scene.cameras``); :func:`~.bundle.write_bundle`
    passes the bundle's own reference file and cameras as scoring reads them,
    so the masks are those of the files, and each background render can be
    kept for scoring in ``kept`` (a :class:`~r360gpu.render.kept.KeptRenders`).
    """
    from ..render.sources import SceneSource

    target = Renderer(scene.target, ctx=ctx if reference is None else reference.renderer.ctx)
    background = reference if reference is not None else SceneSource(scene.background, ctx=target.ctx)
    cams = list(scene.cameras if cameras is None else cameras)
    if progress:
        from ..util.progress import progress as report

        cams = report(cams, desc=f"{scene.name}: masks", unit="view")
    masks = {}
    try:
        for cam in cams:
            t = target.render(cam)
            b = background.images(cam.name, cam)
            in_front = (t.depth < b.depth + MASK_DEPTH_EPS) | (b.alpha < NO_COVERAGE_ALPHA)
            masks[cam.name] = (t.alpha > MASK_ALPHA) & in_front
            if kept is not None:
                kept.keep(background, cam, b)
    finally:
        target.release()
        if reference is None:
            background.release()
    return masks
