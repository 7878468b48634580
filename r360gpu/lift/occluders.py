"""Masks that cover an occluder: lifted Gaussians that sit in front of the object and that other views contradict.

A target mask made by rendering the object's own Gaussians alone covers the
object's whole silhouette, including where something in front of it hides
it in that view.  Lifting such a mask votes the occluder in: in the view
whose mask covers it, its compositing weight falls inside the mask.  Two
things give it away, and both are needed (each alone also fits clean masks):

* in the view that voted it in (its largest ``w_in``), it lies in front of
  the lifted object: its centre's depth is less than the ``w_in``-weighted
  median depth of the lifted Gaussians there (their visible surface) by
  :data:`FRONT_MARGIN` times the lifted object's radius
  (`LiftedTarget.extent`): a convex object's own front is at most about
  0.3 radii ahead of its visible surface, an irregular real one more (on
  the PlayCanvas biker, masks of the visible target put 3-5% of the lifted
  weight 0.5 radii ahead, 0.2-1% one radius ahead:
  ``bench/real_scene_lift.py``);
* and another given view sees it outside its mask (``w_out`` there at least
  :data:`CONTRADICTED_SHARE` of the ``w_in`` that voted it in), unless it is
  :data:`FAR_FRONT` radii in front, out of the object's reach.

Background seen through the object's gaps is contradicted too, but lies
behind it; the object's own rim is in front of nothing.  The masks are
doubtful when such Gaussians hold at least :data:`MIN_OCCLUDER_SHARE` of the
lifted target's ``w_in``; the views whose masks voted them in are named.

Only an occluder out of the object's reach is caught: material hugging the
object (within a radius of its surface, inside the given views' visual hull)
is what the masks of an object would also cover, and is not told apart by the
masks.

**With a reference** (the scene after the removal) the masks can be checked
pixel by pixel, whatever the occluder's shape: the target is what the removal
takes away, so a mask pixel where pre and the reference show the same surface
(every colour channel within :data:`UNCHANGED_RGB`, depth within
:data:`UNCHANGED_DEPTH` of pre's) covers something that is still there: an
occluder in front of the object, or a mask wider than the object
(:func:`unchanged_pixels`).  A given mask is doubtful when at least
:data:`MIN_UNCHANGED_SHARE` of its pixels are unchanged.  Both conditions are
needed: colour alone matches where the object looks like what it hid, depth
alone where it lies flat on it.  A reference captured and reconstructed
apart from pre agrees with it less than a removal made in the same scene,
which makes this check miss occluders, not invent them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..io.frames import in_frame
from .target import MIN_WEIGHT, LiftedTarget, _weighted_quantile

#: Another view contradicts a lifted Gaussian when its weight outside that view's mask is at least
#: this share of the weight inside the mask that voted it in.
CONTRADICTED_SHARE = 0.25
#: In front of the object: nearer than its visible surface's median depth by this many object radii.
FRONT_MARGIN = 1.0
#: ...and by this many, out of the object's reach (no contradiction needed).
FAR_FRONT = 1.5
#: The masks are doubtful when the occluder-like Gaussians hold this share of the lifted w_in.
MIN_OCCLUDER_SHARE = 0.02
#: A pixel is unchanged by the removal when pre and the reference differ there by at most this in
#: every colour channel (8 levels of an 8-bit image) ...
UNCHANGED_RGB = 8 / 255
#: ... and their depths (both covered) by at most this share of pre's.
UNCHANGED_DEPTH = 0.05
#: A given mask is doubtful when this share of its pixels is unchanged by the removal.
MIN_UNCHANGED_SHARE = 0.2


@dataclass(frozen=True)
class Occluders:
    """The lifted Gaussians that look like an occluder (see the module docstring).

    gaussians: (N,) bool over pre's Gaussians; share: their share of the lifted target's ``w_in``;
    by_view: {view name: how many of them that view's mask voted in}, largest first.
    """

    gaussians: np.ndarray
    share: float
    by_view: dict

    @property
    def doubtful(self) -> bool:
        return self.share >= MIN_OCCLUDER_SHARE

    def message(self, paths: dict | None = None) -> str:
        """A warning naming the masks that voted the occluder in (``paths``: {view: file}) and the fix."""
        paths = paths or {}
        named = ", ".join(f"{paths.get(v, f'view {v!r}')} ({k})" for v, k in self.by_view.items())
        return (f"{int(self.gaussians.sum())} lifted target Gaussians ({100 * self.share:.0f}% of the target's "
                f"weight) look like an occluder in front of the object: the masks of {named} cover them, other "
                f"given views see them outside their masks; masks made by rendering the object alone cover what "
                f"hides it. Give masks of the visible object only (e.g. render the whole scene and keep the "
                f"pixels the object's Gaussians hold), or drop those views")


def find_occluders(scene, cameras, lifted: LiftedTarget, *, frame=None) -> Occluders:
    """The occluder-like Gaussians of ``lifted`` (lifted from masks with ``per_view=True``) over
    ``scene`` (pre's Gaussians), seen by ``cameras`` (the lifted views, in order; ``frame`` as
    `lift_target`)."""
    if lifted.w_views is None:
        raise ValueError("find_occluders needs a target lifted with per_view=True")
    w_in_v, w_out_v = lifted.w_views[:, 0], lifted.w_views[:, 1]
    sel = lifted.target
    voter = np.argmax(w_in_v, axis=0)
    w_vote = np.take_along_axis(w_in_v, voter[None], axis=0)[0]
    others = np.arange(len(cameras))[:, None] != voter[None, :]
    contradicted = (others & (w_out_v >= MIN_WEIGHT) & (w_out_v >= CONTRADICTED_SHARE * w_vote)).any(axis=0)
    means = np.asarray(scene.means, np.float64)
    _, radius = lifted.extent(means)
    front = np.zeros(lifted.n, bool)
    for k, cam in enumerate(cameras):
        c = in_frame(frame, cam)
        votes = sel & (voter == k)
        if not votes.any():
            continue
        depth = means @ np.asarray(c.R, np.float64)[2] + float(c.t[2])
        seen = sel & (w_in_v[k] > 0)
        median = _weighted_quantile(depth[seen], w_in_v[k][seen], 0.5)
        ahead = (median - depth) / radius
        front |= votes & (((ahead > FRONT_MARGIN) & contradicted) | (ahead > FAR_FRONT))
    occ = sel & front
    share = float(lifted.w_in[occ].sum() / max(lifted.w_in[sel].sum(), 1e-12))
    counts = np.bincount(voter[occ], minlength=len(cameras))
    names = [lifted.views[k] if k < len(lifted.views) else str(k) for k in range(len(cameras))]
    by_view = {names[k]: int(counts[k]) for k in np.argsort(-counts, kind="stable") if counts[k]}
    return Occluders(occ, share, by_view)


def drop_occluders(lifted: LiftedTarget, occ: Occluders) -> LiftedTarget:
    """``lifted`` without the occluder-like Gaussians."""
    from dataclasses import replace

    return replace(lifted, target=lifted.target & ~occ.gaussians)


def unchanged_pixels(pre, reference) -> np.ndarray:
    """(H, W) bool: where ``pre`` and ``reference`` (images with ``rgb`` (H, W, 3) and ``depth`` (H, W),
    0 = no coverage, in one unit) show the same surface, or nothing at all in the same colour: the removal
    did not change it (module docstring)."""
    if pre.depth is None or reference.depth is None:
        raise ValueError("unchanged_pixels needs the depth of pre and of the reference")
    same_rgb = np.abs(np.asarray(pre.rgb, np.float32) - np.asarray(reference.rgb, np.float32)).max(axis=-1) \
        <= UNCHANGED_RGB
    d_pre, d_ref = np.asarray(pre.depth, np.float32), np.asarray(reference.depth, np.float32)
    same_depth = (d_pre > 0) & (d_ref > 0) & (np.abs(d_pre - d_ref) <= UNCHANGED_DEPTH * d_pre)
    return same_rgb & (same_depth | ((d_pre == 0) & (d_ref == 0)))  # or nothing there, before and after


@dataclass(frozen=True)
class UnchangedMasks:
    """Given masks against a reference: {view: share of the mask's pixels the removal did not change}."""

    shares: dict

    @property
    def doubtful(self) -> dict:
        """{view: share} of the masks with at least :data:`MIN_UNCHANGED_SHARE` unchanged, largest first."""
        bad = {v: s for v, s in self.shares.items() if s >= MIN_UNCHANGED_SHARE}
        return dict(sorted(bad.items(), key=lambda kv: -kv[1]))

    def message(self, paths: dict | None = None) -> str:
        paths = paths or {}
        named = ", ".join(f"{paths.get(v, f'view {v!r}')} ({100 * s:.0f}% of its pixels)"
                          for v, s in self.doubtful.items())
        return (f"given masks cover pixels where pre and the reference show the same surface (colour and depth), "
                f"so something the removal left in place: {named}. That is an occluder in front of the object "
                f"(masks made by rendering the object alone cover it) or masks wider than the object. Give masks "
                f"of the visible object only, or drop those views")


def unchanged_masks(masks: dict, pre_images: dict, reference_images: dict) -> UnchangedMasks:
    """The share of each given mask ({view: (H, W) bool}) unchanged between pre's and the reference's
    images there ({view: images}, see `unchanged_pixels`); views without a reference image are left out."""
    shares = {}
    for v, m in masks.items():
        if v in reference_images and m.any():
            shares[v] = float(unchanged_pixels(pre_images[v], reference_images[v])[m].mean())
    return UnchangedMasks(shares)
