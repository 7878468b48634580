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

Projection (INRIA 3DGS)
    Gaussians with camera depth ``Z <= NEAR_PLANE`` (scene units) are culled.
    The EWA Jacobian is evaluated with the mean's direction ``X/Z`` clamped to
    the image's half-extent plus ``FRUSTUM_GUARD`` times the half field of view
    on each side (INRIA's 1.3 x tan(fov/2) for a centred principal point).
    ``COV2D_BLUR`` is added to the 2D covariance's diagonal.  The screen
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
    ``alpha < NO_COVERAGE_ALPHA`` have no coverage: both depths are 0 there.
    With ``NO_COVERAGE_ALPHA = MEDIAN_T = 0.5`` a pixel has a median depth
    exactly when it is covered, and a mostly transparent pixel never gets the
    depth of a faint floater; the rule is the same for every scene.
"""
from __future__ import annotations

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
