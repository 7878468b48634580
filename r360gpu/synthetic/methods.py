"""Simulated removal methods with known failure modes.

Each method maps a :class:`~r360gpu.synthetic.scene.SyntheticScene` and a
generator to the edited scene a removal method would produce.  All of them
start from the background re-optimised the way a real method's fine-tuning
leaves it (:func:`retrained`: the same surfaces, a few millimetres and a few
colour levels off), then:

========================  ======================================================
``clean``                 the target removed and the scene completed: the
                          background, hidden part included (≈ the reference).
``floaters``              completed, but :data:`FLOATER_FRACTION` of the
                          target's Gaussians stay behind, shrunk and scattered:
                          semi-transparent residue where the object was.
``recoloured``            the target's Gaussians stay in place (same means,
                          scales, rotations, opacities) recoloured to the
                          background behind them: "looks removed, isn't".
``hole``                  the target removed, no completion: the background the
                          target hid from every camera is missing.
``over_removal``          completed, but everything in the target's
                          neighbourhood that is not shell (furniture, rug,
                          paving, plants) is removed too.
``backside``              completed, but a film of the target's colours stays
                          on the ground under it, its view-dependent colour
                          fitted to the capture: the ground's own seen from
                          the capture's arc, the target's from the side the
                          capture never faced (only an orbit sees it).
========================  ======================================================

Gaussian order in every result: background first (as in the scene, minus
removed ones), then what is left of the target.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from ..io import Gaussians
from ..protocol import AXES
from .primitives import rgb_to_sh, sh_to_rgb
from .scene import SyntheticScene

#: Position noise (metres, per axis) of a re-optimised background.
RETRAIN_POSITION_SIGMA = 0.002
#: Colour noise (RGB units) of a re-optimised background.
RETRAIN_COLOUR_SIGMA = 0.015
#: Log-scale noise of a re-optimised background.
RETRAIN_SCALE_SIGMA = 0.03
#: Fraction of the target's Gaussians the ``floaters`` method leaves behind.
FLOATER_FRACTION = 0.45
#: Scatter (metres, per axis) of the floaters around where the target's Gaussians were.
FLOATER_SCATTER = 0.03
#: Background Gaussians averaged to recolour one target Gaussian (``recoloured``).
RECOLOUR_NEIGHBOURS = 8
#: Ray march of :func:`background_colour_behind`: step and reach (metres), and how close
#: (metres) to a background Gaussian a sample must come to count as hitting the background.
RAY_STEP, RAY_LENGTH, RAY_HIT = 0.04, 8.0, 0.1


def retrained(g: Gaussians, rng: np.random.Generator) -> Gaussians:
    """``g`` with small independent noise on positions, scales and colours (see the constants)."""
    n = g.n
    rgb = sh_to_rgb(g.sh) + rng.normal(0.0, RETRAIN_COLOUR_SIGMA, (n, 3))
    sh = np.array(g.sh, np.float64)
    sh[:, 0, :] = rgb_to_sh(np.clip(rgb, 0.0, 1.0))[:, 0, :]
    return Gaussians(
        means=g.means + rng.normal(0.0, RETRAIN_POSITION_SIGMA, (n, 3)),
        scales=g.scales * np.exp(rng.normal(0.0, RETRAIN_SCALE_SIGMA, (n, 3))),
        quats=g.quats, opacities=g.opacities, sh=sh,
    )


def clean(scene: SyntheticScene, rng: np.random.Generator) -> Gaussians:
    """The target removed and the scene completed."""
    return retrained(scene.background, rng)


def floaters(scene: SyntheticScene, rng: np.random.Generator) -> Gaussians:
    """Completed, plus a fraction of the target left as shrunk, scattered, fainter floaters.

    :data:`FLOATER_FRACTION` of the target's Gaussians (a random subset) are
    kept with their colours, moved by N(0, :data:`FLOATER_SCATTER`) per axis,
    scaled by U(0.45, 0.85) and their opacity by U(0.45, 0.95).
    """
    t = scene.target
    keep = np.sort(rng.choice(t.n, size=max(1, int(round(FLOATER_FRACTION * t.n))), replace=False))
    m = len(keep)
    residue = Gaussians(
        means=t.means[keep] + rng.normal(0.0, FLOATER_SCATTER, (m, 3)),
        scales=t.scales[keep] * rng.uniform(0.45, 0.85, (m, 1)),
        quats=t.quats[keep],
        opacities=t.opacities[keep] * rng.uniform(0.45, 0.95, m),
        sh=t.sh[keep],
    )
    return Gaussians.concat([retrained(scene.background, rng), residue])


def background_colour_behind(scene: SyntheticScene) -> np.ndarray:
    """(N_target, 3) RGB of the background behind each target Gaussian, seen from the
    centroid of the cameras that aim at the target.

    The line of sight from that centroid through the Gaussian is marched
    beyond it in steps of :data:`RAY_STEP` up to :data:`RAY_LENGTH`; the
    first sample within :data:`RAY_HIT` of a visible (not hidden) background
    Gaussian is where the background shows (a Gaussian whose ray meets
    nothing uses its own position).  The colour is the mean of the
    :data:`RECOLOUR_NEIGHBOURS` nearest visible background Gaussians there.
    """
    aimed = [c.center for c in scene.cameras if scene.view_kinds.get(c.name) != "away"]
    eye = np.mean(aimed if aimed else [c.center for c in scene.cameras], axis=0)
    m = np.asarray(scene.target.means, np.float64)
    d = m - eye
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    visible = ~scene.hidden
    tree = cKDTree(np.asarray(scene.background.means, np.float64)[visible])
    hit = m.copy()
    pending = np.arange(len(m))
    for step in np.arange(RAY_STEP, RAY_LENGTH + RAY_STEP / 2, RAY_STEP):
        if not len(pending):
            break
        probe = m[pending] + step * d[pending]
        dist, _ = tree.query(probe, k=1, distance_upper_bound=RAY_HIT)
        found = np.isfinite(dist)
        hit[pending[found]] = probe[found]
        pending = pending[~found]
    _, idx = tree.query(hit, k=RECOLOUR_NEIGHBOURS)
    colours = sh_to_rgb(scene.background.sh)[visible]
    return colours[idx].mean(axis=1)


def recoloured(scene: SyntheticScene, rng: np.random.Generator) -> Gaussians:
    """The target's geometry kept exactly, its colours replaced by the background behind it."""
    t = scene.target
    rgb = np.clip(background_colour_behind(scene) + rng.normal(0.0, RETRAIN_COLOUR_SIGMA, (t.n, 3)), 0.0, 1.0)
    disguised = Gaussians(t.means, t.scales, t.quats, t.opacities, rgb_to_sh(rgb))
    return Gaussians.concat([retrained(scene.background, rng), disguised])


def hole(scene: SyntheticScene, rng: np.random.Generator) -> Gaussians:
    """The target removed without completion: the hidden background is missing."""
    return retrained(scene.background.subset(~scene.hidden), rng)


def over_removal(scene: SyntheticScene, rng: np.random.Generator) -> Gaussians:
    """Completed, but the non-shell background in the target's neighbourhood is removed too."""
    return retrained(scene.background.subset(~scene.in_neighbourhood()), rng)


#: The ``backside`` film covers the ground within this horizontal distance (metres) of the target, so
#: that a view from behind, looking through where the target was, sees film on the ground beyond it.
BACKSIDE_SPREAD = 0.6
#: Ground is the top surface per cell of this size (metres), no higher than this above the target's feet.
BACKSIDE_CELL = 0.05
#: Height (metres) of the ``backside`` film above the ground it copies.
BACKSIDE_LIFT = 0.01


def capture_front(scene: SyntheticScene) -> np.ndarray:
    """(3,) horizontal unit vector from the target towards the cameras that aim at it (world z up)."""
    aimed = [c.center for c in scene.cameras if scene.view_kinds.get(c.name) != "away"]
    eye = np.mean(aimed if aimed else [c.center for c in scene.cameras], axis=0)
    d = eye - np.asarray(scene.target.means, np.float64).mean(axis=0)
    d[2] = 0.0
    return d / np.linalg.norm(d)


def backside_sh(ground: np.ndarray, own: np.ndarray, front: np.ndarray, degree: int = 3) -> np.ndarray:
    """(n, K, 3) SH coefficients whose colour is ``ground`` (n, 3) seen from ``front`` (3,) and
    ``own`` (n, 3) seen from the opposite side: colour(d) = ground + (own - ground) w(d) with
    w = ((1 + d . front) / 2)^3, a cubic in the view direction d (camera to Gaussian), so degree-3
    SH hold it exactly; w <= 0.03 wherever the capture looks from within 70 degrees of its front."""
    from ..io.sh import sh_basis

    # Least squares on a dense direction set recovers the exact cubic (it lies in the span).
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(4000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    basis = sh_basis(dirs, degree)                      # (D, K)
    # d runs from the camera to the Gaussian: the capture (standing at +front) looks along -front.
    w = ((1.0 + dirs @ front) / 2.0) ** 3
    coef_w, *_ = np.linalg.lstsq(basis, w, rcond=None)  # (K,)
    coef_1, *_ = np.linalg.lstsq(basis, np.ones(len(dirs)), rcond=None)
    # colour = SH + 0.5 = ground + (own - ground) w  ->  SH = (ground - 0.5) * 1 + (own - ground) * w
    return (coef_1[None, :, None] * (ground - 0.5)[:, None, :]
            + coef_w[None, :, None] * (own - ground)[:, None, :])


def backside(scene: SyntheticScene, rng: np.random.Generator) -> Gaussians:
    """Completed, plus a film of the target's colours on the ground around it, visible only from behind.

    Every Gaussian of the ground's top surface within :data:`BACKSIDE_SPREAD`
    of the target's footprint (and no higher than its feet) is copied
    :data:`BACKSIDE_LIFT` higher, with a view-dependent colour (:func:`backside_sh`): its own
    from the capture's side, the nearest target Gaussian's from the opposite
    side.  The capture's views see the ground where the ground should be
    (same place, same colour, same texture); an orbit behind the target sees
    the object's colours on it.
    """
    bg, t = scene.background, scene.target
    means = np.asarray(bg.means, np.float64)
    tm = np.asarray(t.means, np.float64)
    low = np.flatnonzero(means[:, 2] < tm[:, 2].min() + BACKSIDE_CELL)  # at the target's feet or below
    dist, nearest = cKDTree(tm[:, :2]).query(means[low, :2])
    near = dist < BACKSIDE_SPREAD
    foot, nearest = low[near], nearest[near]
    # Only the top surface (the paving, not the lawn under it): within BACKSIDE_LIFT x 3 of the highest
    # Gaussian of its BACKSIDE_CELL-wide cell.
    cell = np.floor(means[foot, :2] / BACKSIDE_CELL).astype(np.int64)
    _, inverse = np.unique(cell, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    top = np.full(inverse.max() + 1 if len(inverse) else 0, -np.inf)
    np.maximum.at(top, inverse, means[foot, 2])
    surface = means[foot, 2] >= top[inverse] - 3 * BACKSIDE_LIFT
    foot, nearest = foot[surface], nearest[surface]
    film = Gaussians(means[foot] + [0.0, 0.0, BACKSIDE_LIFT], bg.scales[foot], bg.quats[foot], bg.opacities[foot],
                     backside_sh(sh_to_rgb(bg.sh)[foot], sh_to_rgb(t.sh)[nearest], capture_front(scene)))
    return Gaussians.concat([retrained(bg, rng), film])


#: The methods by name, in the order bundles list them.
METHODS: dict[str, Callable[[SyntheticScene, np.random.Generator], Gaussians]] = {
    "clean": clean,
    "floaters": floaters,
    "recoloured": recoloured,
    "hole": hole,
    "over_removal": over_removal,
    "backside": backside,
}
#: The methods a benchmark gets by default: ``backside`` is left out (ask for it by name) because
#: only an orbit (``score --orbit N``) can see its failure, and the default run has none.
DEFAULT_METHODS: tuple = tuple(m for m in METHODS if m != "backside")

#: Per method: its failure in one sentence and the axes that should catch it (fall low).  Written
#: into the bundle's scene.toml as [expected.METHOD] (see r360gpu.bundle.expected), so the report
#: can check each against the scores without knowing the methods.
EXPECTED: dict[str, tuple[str, tuple[str, ...]]] = {
    "clean": ("none: removed and completed like the reference", ()),
    "floaters": ("residue of the target (shrunk, scattered, fainter Gaussians) where it was: it keeps the "
                 "object's colours, stays near its depth and breaks the completed structure",
                 AXES),
    "recoloured": ("the target's Gaussians kept in place, recoloured like the background: looks removed, "
                   "the geometry is unchanged", ("s_geo",)),
    "hole": ("removed without completion: the background the target hid is missing, so the region "
             "disagrees with the reference", ("s_str",)),
    "over_removal": ("the target's surroundings removed too: the completed region disagrees with the "
                     "reference", ("s_str",)),
    "backside": ("a film of the target's colours on the ground of its footprint, coloured like the ground "
                 "from the capture's side: invisible from the capture views, seen by an orbit (--orbit)", ()),
}

__all__ = ["METHODS", "DEFAULT_METHODS", "EXPECTED", "clean", "floaters", "recoloured", "hole", "over_removal", "backside",
           "retrained", "background_colour_behind", "backside_sh", "capture_front"]
