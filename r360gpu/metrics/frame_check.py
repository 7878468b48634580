"""Do the cameras see the splats?  A check of pre's renders for a world-frame mismatch.

A splat scene exported in another world frame than its cameras (nerfstudio's
dataparser frame, gsplat's normalised world; :mod:`r360gpu.io.frames`)
renders mostly empty images at the evaluation views, or renders the scene
somewhere else than where the target masks say the object is.  Scoring such
a scene gives numbers that mean nothing, so the pipeline renders pre at a few
evaluation views with a visible target before scoring and reads, per view:

* ``coverage``: the fraction of the image pre renders something solid in
  (alpha >= :data:`SOLID_ALPHA`);
* ``touched``: the fraction of the image pre draws anything in (alpha >
  :data:`TOUCHED_ALPHA`, one 8-bit step);
* ``target``: the fraction of the target mask's pixels pre renders something in
  (the object to remove is part of pre, so a correctly framed pre covers it).

* ``edges``: whether pre's depth jumps where the target's outline is
  (:func:`silhouette_edges`): the object to remove stands out of its
  surroundings, so a correctly framed pre has depth edges along the mask's
  outline far more often than elsewhere.  This reads geometry, not coverage:
  an enclosed scene (a room, a garden under a sky dome) is covered at any
  camera, but only correctly framed splats put the object's outline where
  the masks are.  (A flat target, e.g. a poster on a wall, has no such
  edge: the check then warns without cause.)

Verdict (:func:`frame_verdict`):

* ``"refuse"``: at every checked view pre draws anything in less than
  :data:`EMPTY` of the image: the cameras look at nothing;
* ``"warn"``: at half of the checked views or more, pre covers less than
  :data:`MOSTLY_EMPTY` of the image, or less than :data:`TARGET_COVERED` of the
  target; or the median ``edges`` ratio is below :data:`EDGE_RATIO_MIN`;
* ``"ok"`` otherwise.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: A pixel where pre's alpha reaches this is rendered.
SOLID_ALPHA = 0.5
#: A pixel where pre's alpha exceeds this is drawn at all.
TOUCHED_ALPHA = 1.0 / 255.0
#: Drawn fraction below this: pre renders nothing at the view.
EMPTY = 0.01
#: Coverage below this: the view is mostly empty.
MOSTLY_EMPTY = 0.1
#: Target coverage below this: the target mask falls where pre renders little.
TARGET_COVERED = 0.5
#: Views checked per pre source.
CHECK_VIEWS = 4
#: A relative depth step |grad log D| above this is a depth edge.
EDGE_STEP = 0.05
#: Floor of the image's edge fraction in the edges ratio (an image with almost no edges).
EDGE_FLOOR = 0.01
#: Median edges ratio below this: the target outlines do not follow pre's geometry.  Measured on
#: the synthetic scenes (128x96, 8 views): correctly framed room 6.0, garden 2.1; the room and
#: garden in gsplat's normalised world with unmoved cameras 1.0 (caught) and 1.8 (not caught).
EDGE_RATIO_MIN = 1.5

LIKELY_CAUSE = (
    "the splats and the cameras are probably in different world frames: nerfstudio exports splats in its "
    "dataparser frame (put its dataparser_transforms.json beside the PLY, or set frame = \"PATH\" in scene.toml), "
    "gsplat's simple_trainer normalises the world by default (set frame = \"gsplat\" with the COLMAP model it "
    "trained on as cameras); see docs/your-scene.md")


@dataclass(frozen=True)
class ViewCoverage:
    """What pre renders at one view: solid coverage of the image and of the target (None: empty
    target), the fraction of the image drawn at all, and the silhouette ``edges`` ratio (None:
    not measured)."""

    view: str
    coverage: float
    target: float | None
    touched: float
    edges: float | None = None


def view_coverage(view: str, alpha: np.ndarray, mask: np.ndarray, depth: np.ndarray | None = None) -> ViewCoverage:
    """Coverage of the image and of the target mask by pre's rendered ``alpha`` (H, W), and with
    ``depth`` (H, W) the :func:`silhouette_edges` ratio."""
    alpha = np.asarray(alpha, dtype=np.float32)
    mask = np.asarray(mask, dtype=bool)
    if alpha.shape != mask.shape:
        raise ValueError(f"alpha {alpha.shape} and mask {mask.shape} differ in size")
    alpha = np.nan_to_num(alpha, nan=0.0)
    solid = alpha >= SOLID_ALPHA
    n_target = int(mask.sum())
    target = float(solid[mask].sum()) / n_target if n_target else None
    if not solid.size:
        return ViewCoverage(view, 0.0, target, 0.0)
    edges = None if depth is None or not n_target else silhouette_edges(depth, mask)
    return ViewCoverage(view, float(solid.mean()), target, float((alpha > TOUCHED_ALPHA).mean()), edges)


def silhouette_edges(depth: np.ndarray, mask: np.ndarray) -> float | None:
    """How much more often pre's depth jumps on the target mask's outline than anywhere in the image.

    The fraction of pixels in the mask's outline band (dilation minus erosion by one pixel) where
    the relative depth gradient ``|grad log D|`` exceeds :data:`EDGE_STEP`, divided by that fraction
    over the whole rendered image (floored at :data:`EDGE_FLOOR`).  None when the outline has
    fewer than 10 rendered pixels.
    """
    import cv2

    d = np.nan_to_num(np.asarray(depth, dtype=np.float64), nan=0.0, posinf=0.0)
    valid = d > 0
    gy, gx = np.gradient(np.log(np.where(valid, d, 1.0)))
    edges = (np.hypot(gx, gy) > EDGE_STEP) & valid
    m = np.asarray(mask, np.uint8)
    k = np.ones((3, 3), np.uint8)
    band = (cv2.dilate(m, k) > 0) & ~(cv2.erode(m, k) > 0) & valid
    if band.sum() < 10:
        return None
    return float(edges[band].mean()) / max(float(edges[valid].mean()), EDGE_FLOOR)


@dataclass(frozen=True)
class FrameVerdict:
    level: str  # "ok" | "warn" | "refuse"
    n_views: int
    n_empty: int           # views with coverage < MOSTLY_EMPTY
    n_target_missed: int   # views whose target pre covers less than TARGET_COVERED
    views: tuple
    edges: float | None = None  # median silhouette edges ratio of the views (None: not measured)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["views"] = [asdict(v) for v in self.views]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "FrameVerdict":
        return cls(d["level"], d["n_views"], d["n_empty"], d["n_target_missed"],
                   tuple(ViewCoverage(**v) for v in d["views"]), d.get("edges"))


def frame_verdict(views: list[ViewCoverage]) -> FrameVerdict:
    """The verdict on the checked views (see the module docstring); "ok" when nothing was checked."""
    views = tuple(views)
    n = len(views)
    n_empty = sum(v.coverage < MOSTLY_EMPTY for v in views)
    with_target = [v for v in views if v.target is not None]
    n_missed = sum(v.target < TARGET_COVERED for v in with_target)
    if n and all(v.touched < EMPTY for v in views):
        level = "refuse"
    elif n and (2 * n_empty >= n or (with_target and 2 * n_missed >= len(with_target))):
        level = "warn"
    else:
        level = "ok"
    ratios = [v.edges for v in views if v.edges is not None]
    edges = float(np.median(ratios)) if ratios else None
    if level == "ok" and edges is not None and edges < EDGE_RATIO_MIN:
        level = "warn"
    return FrameVerdict(level, n, n_empty, n_missed, views, edges)


def mismatch_message(verdict: FrameVerdict, *, source: str, frame: str | None, cameras: str | None) -> str:
    """What went wrong, at which views, and the likely cause (for the error or the warning)."""
    listed = ", ".join(f"{v.view} {100 * v.coverage:.0f}%"
                       + ("" if v.target is None else f" (target {100 * v.target:.0f}%)") for v in verdict.views)
    with_target = sum(v.target is not None for v in verdict.views)
    what = ("renders nothing" if verdict.level == "refuse" else
            "renders mostly empty images" if 2 * verdict.n_empty >= verdict.n_views else
            "renders little where the target masks are" if 2 * verdict.n_target_missed >= max(1, with_target) else
            f"has no depth edges along the target masks' outlines (median edges ratio {verdict.edges:.2f} < "
            f"{EDGE_RATIO_MIN}: the object is not where the masks are)")
    framed = f"the cameras were moved by {frame}" if frame else "the cameras were used as they are"
    return (f"pre ({source}) {what} at the checked evaluation views (image covered: {listed}; {framed}"
            f"{'' if cameras is None else f', cameras {cameras}'}): {LIKELY_CAUSE}")
