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


#: The methods by name, in the order bundles list them.
METHODS: dict[str, Callable[[SyntheticScene, np.random.Generator], Gaussians]] = {
    "clean": clean,
    "floaters": floaters,
    "recoloured": recoloured,
    "hole": hole,
    "over_removal": over_removal,
}

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
}

__all__ = ["METHODS", "EXPECTED", "clean", "floaters", "recoloured", "hole", "over_removal", "retrained",
           "background_colour_behind"]
