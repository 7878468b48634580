"""Pictures as a report sink: the stages hand each (method, view) over, the sink writes its contact sheet.

The sheet's path (relative to ``out``) goes into the view's cache cell, so
the view cache knows which pictures a run has written.
"""
from __future__ import annotations

from pathlib import Path


class PictureSink:
    """Writes per-(method, view) contact sheets under ``out/pictures`` (does nothing when disabled)."""

    def __init__(self, out: Path | None, enabled: bool, *, ctx=None):
        self.out = out
        self.enabled = out is not None and enabled
        self.ctx = ctx  # the run's GPU context: depth on a caller's device is read back through it

    def method_view(self, scene: str, method: str, view: str, *, pre, post, ref, mask, geo, compat: bool,
                    semantic, structural, record: dict | None = None) -> str | None:
        """Write the sheet of one method at one view; returns its path relative to ``out``.

        pre, post, ref: ViewImages; geo: GeometricView or None; semantic:
        (pre, post) predictions of the first semantic probe or None;
        structural: [(title, rgb, MaskSet)] of the first structural probe;
        record: the view's record (its numbers are drawn on the sheet).
        """
        if not self.enabled:
            return None
        from ..metrics.compat import compat_quantise, depth_delta
        from ..render.sources import host_depth
        from ..report.pictures import view_contact_sheet

        delta = threshold = changed = None
        if geo is not None:
            delta = depth_delta(host_depth(pre.depth, self.ctx), host_depth(post.depth, self.ctx))
            changed, threshold = geo.changed, geo.threshold
            if compat:  # the heat map then shows the 8-bit gray levels the threshold applies to
                delta = compat_quantise(delta)
        rel = Path("pictures") / scene / method / f"{view}.png"
        view_contact_sheet(
            self.out / rel, title=f"{scene} / {method} / {view}", pre=pre.rgb, post=post.rgb, target=mask,
            ref=None if ref is None else ref.rgb, delta=delta, threshold=threshold, changed=changed,
            semantic_pre=None if semantic is None else semantic[0].union(),
            semantic_post=None if semantic is None else semantic[1].union(),
            structural=[(t, rgb, ms.masks) for t, rgb, ms in structural], record=record,
        )
        return rel.as_posix()
