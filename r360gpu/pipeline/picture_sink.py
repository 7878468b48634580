"""Pictures as a report sink: the stages hand each (method, view) over, the sink writes its contact sheet.

The sheet's path (relative to ``out``) goes into the view's cache cell, so
the view cache knows which pictures a run has written.  With an
``embed_cache`` folder the sink also makes the JPEG report.html will embed
the sheet as, here in the writer thread rather than at the end of the run.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..kernels.depth_change import no_depth
from ..metrics.compat import compat_quantise, depth_delta
from ..util.memo import ByIdentity


@dataclass
class PictureJob:
    """One method's contact sheet at one view, on host arrays only.

    pre_depth / post_depth: D_pre, D_post (None without a geometric view); geo: the GeometricView or
    None; compat: the heat map in the public scripts' 8-bit gray levels; semantic: (pre, post)
    predictions of the first semantic probe or None; structural: [(title, rgb, MaskSet)] of the
    first structural probe; record: the view's :class:`~r360gpu.metrics.record.ViewRecord` (its
    numbers are drawn on the sheet, so they survive copying it) or None.
    """

    scene: str
    method: str
    view: str
    pre_rgb: object
    post_rgb: object
    ref_rgb: object
    pre_depth: object
    post_depth: object
    mask: object
    geo: object
    compat: bool
    semantic: tuple | None = None
    structural: list = field(default_factory=list)
    record: object = None


class PictureSink:
    """Writes per-(method, view) contact sheets under ``out/pictures`` (does nothing when disabled)."""

    def __init__(self, out: Path | None, enabled: bool, embed_cache: Path | None = None):
        self.out = out
        self.enabled = out is not None and enabled
        self.embed_cache = embed_cache

    def path_for(self, scene: str, method: str, view: str) -> str | None:
        """Where the sheet of (scene, method, view) goes, relative to ``out`` (None without pictures)."""
        return (Path("pictures") / scene / method / f"{view}.png").as_posix() if self.enabled else None

    def method_view(self, job: PictureJob, *, shrink=None, panels=None) -> str:
        """Write the sheet of one method at one view; returns its relative path.

        shrink / panels: a view's :class:`_Shrink` and panel memo, shared by its methods' sheets
        (:meth:`view`).
        """
        from ..report.contact_sheets import view_contact_sheet

        geo, pre_rgb, post_rgb, ref_rgb, mask = job.geo, job.pre_rgb, job.post_rgb, job.ref_rgb, job.mask
        semantic, record, post_depth = job.semantic, job.record, job.post_depth
        delta = threshold = changed = None
        if geo is not None:
            delta = depth_delta(job.pre_depth, post_depth)
            changed, threshold = geo.changed, geo.threshold
            if job.compat:  # the heat map then shows the 8-bit gray levels the threshold applies to
                delta = compat_quantise(delta)
        # Everything but the heat map is brought to the panel size first (once per array
        # and view when a _Shrink is shared): the panels resize exactly so, so the sheet is the same.
        small = shrink or _Shrink.for_view(pre_rgb)
        rel = self.path_for(job.scene, job.method, job.view)
        view_contact_sheet(
            self.out / rel, title=f"{job.scene} / {job.method} / {job.view}", pre=small.rgb(pre_rgb),
            post=small.rgb(post_rgb),
            target=small.mask(mask), ref=None if ref_rgb is None else small.rgb(ref_rgb), delta=delta,
            threshold=threshold, changed=None if changed is None else small.mask(changed),
            no_depth=None if geo is None else small.mask(no_depth(post_depth)),
            semantic_pre=None if semantic is None else small.union(semantic[0]),
            semantic_post=None if semantic is None else small.union(semantic[1]),
            structural=[(t, small.rgb(rgb), small.masks(ms.masks)) for t, rgb, ms in job.structural],
            width=small.width, record=None if record is None else record.to_dict(), embed_cache=self.embed_cache,
            memo=panels,
        )
        return rel

    def view(self, jobs: list[PictureJob]) -> None:
        """Write the sheets of one view's methods, converting the images they share once."""
        if not jobs:
            return
        shrink, panels = _Shrink.for_view(jobs[0].pre_rgb), ByIdentity()  # panels of I_pre, I_ref: made once
        for job in jobs:
            self.method_view(job, shrink=shrink, panels=panels)


class _Shrink:
    """RGB images and masks at a panel's size, made once per array (keyed by identity).

    Uses the picture module's own conversion and resizing
    (:func:`~r360gpu.report.contact_sheets.rgb8_at`, nearest resize for masks), so
    a panel made from the result is the panel made from the full-size input.
    """

    def __init__(self, width: int):
        self.width = width
        self._memo = ByIdentity()

    @classmethod
    def for_view(cls, pre_rgb) -> "_Shrink":
        """At the panel width of a view as wide as ``pre_rgb``."""
        from ..report.contact_sheets import panel_width_for

        return cls(panel_width_for(np.shape(pre_rgb)[1]))

    def rgb(self, a):
        from ..report.contact_sheets import rgb8_at

        return self._memo.get("rgb", (a,), lambda: rgb8_at(a, self.width))

    def _size(self, shape):
        from ..report.contact_sheets import panel_size

        return panel_size(shape, self.width)

    def mask(self, m):
        from ..report.contact_sheets import resize_mask

        return self._memo.get("mask", (m,), lambda: resize_mask(np.asarray(m) != 0, self._size(np.shape(m))))

    def union(self, prediction):
        """A semantic prediction's union mask, at the panel size."""
        return self._memo.get("union", (prediction,), lambda: self.mask(prediction.union()))

    def masks(self, stack):
        from ..util.resize import resize_nearest

        def make(x):
            a = np.asarray(x)
            if a.ndim == 2:
                a = a[None]
            if a.ndim != 3 or not a.shape[0]:
                return a != 0
            w, h = self._size(a.shape[1:])
            # the whole stack at once, and nearest picks pixels, so "!= 0" after it is the same as before it
            return resize_nearest(a, (h, w)) != 0

        return self._memo.get("masks", (stack,), lambda: make(stack))
