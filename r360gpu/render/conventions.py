"""The renderer's conventions and constants, defined once (the oracle uses them too).

Coordinates
    Cameras are world-to-camera ``R`` (3, 3), ``t`` (3,) in OpenCV axes (x right,
    y down, z forward), pinhole ``fx, fy, cx, cy`` in pixels.  A camera-space
    point (X, Y, Z) projects to ``(fx X / Z + cx, fy Y / Z + cy)`` in image
    coordinates where pixel (u, v) covers [u, u+1) x [v, v+1), i.e. its centre
    is at (u + 0.5, v + 0.5) (the COLMAP convention).  This is what INRIA 3DGS
    computes (its ``ndc2Pix(v, S) = ((v + 1) S - 1) / 2`` puts the centre of
    pixel u at NDC ``(2u + 1) / S - 1``) and what gsplat computes (pixel centre
    ``u + 0.5`` against ``fx X / Z + cx``).  Internally the kernels work in
    pixel-index coordinates ``fx X / Z + cx - 0.5`` where pixel (u, v) sits at
    (u, v).

Principal point (option ``principal_point``)
    ``"camera"`` (default): the camera's ``cx, cy`` as above (gsplat, and
    INRIA forks that build the projection from cx, cy).  ``"centre"``:
    ``cx = width / 2, cy = height / 2`` whatever the camera says, as INRIA's
    original renderer, whose projection matrix comes from the field of view
    alone.

Projection (INRIA 3DGS)
    Gaussians with camera depth ``Z <= near`` (scene units) are culled; option
    ``near``, default ``NEAR_PLANE`` = 0.2 as INRIA (gsplat's default is
    0.01 and culls ``Z < near``).
    The EWA Jacobian is evaluated with the mean's direction ``X/Z`` clamped to
    the image's half-extent plus ``FRUSTUM_GUARD`` times the half field of view
    on each side (INRIA's 1.3 x tan(fov/2) for a centred principal point).
    ``COV2D_BLUR`` is added to the 2D covariance's diagonal.

Antialiased mode (option ``antialiased``, default off)
    The opacity of each Gaussian is multiplied by
    ``sqrt(max(AA_MIN_RATIO, det(cov2d) / det(cov2d + COV2D_BLUR I)))``, the
    determinants taken before and after the blur: gsplat's
    ``rasterize_mode="antialiased"`` (``add_blur`` in
    ``gsplat/cuda/include/Utils.cuh``, floor ``MIN_COMPENSATION**2``), INRIA's
    ``antialiasing=True`` and Mip-Splatting's 2D filter (whose blur is its
    own ``kernel_size``).  Scenes trained that way look too dense without it.
    The compensated opacity is what every later rule (culling below
    ``ALPHA_MIN``, the blend) sees.  The screen
    footprint is the tile rectangle of a square of radius ``ceil(3 sqrt(l1))``
    (l1: the larger eigenvalue, at least ``mid + sqrt(0.1)``) around the mean;
    the GPU uses the smaller opacity-aware radius where it is smaller, which
    changes no pixel (see ``render_project.wgsl``).

Colour
    ``max(SH(dir) + 0.5, 0)`` per channel with ``dir`` the unit vector from
    the camera centre ``-R^T t`` to the mean (:mod:`r360gpu.io.sh`); not
    clamped above (clip when converting to 8 bits).

Compositing (INRIA 3DGS, 16 x 16 tiles, front to back by camera depth Z;
equal depths keep Gaussian index order)
    ``alpha = min(ALPHA_MAX, opacity * exp(power))``, skipped when
    ``power > 0`` or ``alpha < ALPHA_MIN``; a pixel stops before the Gaussian
    that would take its transmittance ``T`` below ``T_MIN``.
    ``rgb = sum(w c) + T background`` with ``w = alpha T``; ``alpha = 1 - T``.

Depth outputs (camera-space Z, scene units)
    ``depth = sum(w Z) / sum(w)`` (expected depth) and ``median_depth`` = Z of
    the first Gaussian after which ``T <= MEDIAN_T``.  Pixels with
    ``alpha < no_coverage_alpha`` (option, default ``NO_COVERAGE_ALPHA``) have
    no coverage: both depths are 0 there.  With ``NO_COVERAGE_ALPHA = MEDIAN_T
    = 0.5`` a pixel has a median depth exactly when it is covered, and a
    mostly transparent pixel never gets the depth of a faint floater; the
    rule is the same for every scene.  ``no_coverage_alpha = 0`` keeps the
    expected depth wherever anything was blended, as gsplat's expected depth
    (``render_mode="ED"``: accumulated ``w Z`` over accumulated alpha); the
    median depth stays 0 where ``T`` never reached ``MEDIAN_T``.

The options are the fields of :class:`RenderOptions` (keywords of
:func:`r360gpu.render.render` and :class:`~r360gpu.render.Renderer`, per-source
keys of a bundle's scene.toml).  Values that the WGSL kernels also need reach
them as pipeline ``override`` constants (:data:`SHADER_CONSTANTS`), so this
module is the one place they are written.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import InputError

#: Side of a square screen tile in pixels.
TILE = 16
#: Gaussians at camera depth Z <= NEAR_PLANE (scene units) are culled (INRIA 3DGS).
NEAR_PLANE = 0.2
#: Extra half field of view (fraction of tan(fov/2)) allowed when clamping the EWA Jacobian.
FRUSTUM_GUARD = 0.3
#: Added to both diagonal entries of the 2D covariance (pixels^2).
COV2D_BLUR = 0.3
#: Largest alpha of one Gaussian at one pixel.
ALPHA_MAX = 0.99
#: Contributions with alpha below this are skipped.
ALPHA_MIN = 1.0 / 255.0
#: A pixel stops before a Gaussian that would take its transmittance below this.
T_MIN = 1e-4
#: The median depth is the depth of the Gaussian at which T first drops to <= MEDIAN_T.
MEDIAN_T = 0.5
#: Pixels with alpha below this have no depth (depth and median depth are 0).
NO_COVERAGE_ALPHA = 0.5
#: Screen radius in standard deviations (of the larger 2D axis).
SIGMA_EXTENT = 3.0
#: Floor of det / det_blurred in the antialiased mode (gsplat's MIN_COMPENSATION = 0.005, squared; INRIA's 0.000025).
AA_MIN_RATIO = 2.5e-5
#: Values of the ``principal_point`` option.
PRINCIPAL_POINTS = ("camera", "centre")


@dataclass(frozen=True)
class RenderOptions:
    """The conventions a method's own renderer may differ in (see the module docstring).

    antialiased: multiply opacities by the antialiasing compensation.
    near: cull Gaussians at camera depth <= near (scene units).
    no_coverage_alpha: depths are 0 where alpha is below this (0 keeps them).
    principal_point: "camera" (cx, cy) or "centre" (image centre, INRIA's original renderer).
    """

    antialiased: bool = False
    near: float = NEAR_PLANE
    no_coverage_alpha: float = NO_COVERAGE_ALPHA
    principal_point: str = "camera"

    def __post_init__(self):
        if not isinstance(self.antialiased, bool):
            raise InputError(f"antialiased must be true or false, got {self.antialiased!r}")
        if isinstance(self.near, bool) or not isinstance(self.near, (int, float)) or \
                not (math.isfinite(self.near) and self.near > 0):
            raise InputError(f"near plane must be a positive number, got {self.near!r}")
        a = self.no_coverage_alpha
        if isinstance(a, bool) or not isinstance(a, (int, float)) or not (0.0 <= a <= 1.0):
            raise InputError(f"no_coverage_alpha must be a number in [0, 1], got {a!r}")
        if self.principal_point not in PRINCIPAL_POINTS:
            raise InputError(f"principal_point must be one of {', '.join(PRINCIPAL_POINTS)}, "
                             f"got {self.principal_point!r}")
        object.__setattr__(self, "near", float(self.near))
        object.__setattr__(self, "no_coverage_alpha", float(a))

    def replace(self, **changes) -> "RenderOptions":
        """A copy with ``changes`` (keys that are None keep their value)."""
        from dataclasses import asdict

        d = asdict(self)
        d.update({k: v for k, v in changes.items() if v is not None})
        return RenderOptions(**d)


#: The ``override`` constants of shaders/composite.wgsl, the compositing rule every pass over the tile
#: lists that blends as the renderer does includes (the rasteriser, target lifting).
COMPOSITE_CONSTANTS = {"ALPHA_MAX": ALPHA_MAX, "ALPHA_MIN": ALPHA_MIN, "T_MIN": T_MIN}

#: The constants the render kernels declare as WGSL ``override``s, by their WGSL name.
SHADER_CONSTANTS = {
    "render_project": {"TILE": float(TILE), "COV2D_BLUR": COV2D_BLUR, "ALPHA_MIN": ALPHA_MIN,
                       "AA_MIN_RATIO": AA_MIN_RATIO, "SIGMA_EXTENT": SIGMA_EXTENT},
    "render_bin": {"TILE": float(TILE), "ALPHA_MIN": ALPHA_MIN},
    "render_rasterize": {**COMPOSITE_CONSTANTS, "MEDIAN_T": MEDIAN_T},
}
