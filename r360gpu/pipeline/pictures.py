"""Pictures as a report sink: the stages hand each (method, view) over, the sink writes its contact sheet.

The sheet's path (relative to ``out``) goes into the view's cache cell, so
the view cache knows which pictures a run has written.
"""
from __future__ import annotations

from pathlib import Path


class PictureSink:
    """Writes per-(method, view) contact sheets under ``out/pictures`` (does nothing when disabled)."""

    def __init__(self, out: Path | None, enabled: bool):
        self.out = out
        self.enabled = out is not None and enabled

    def path_for(self, scene: str, method: str, view: str) -> str | None:
        """Where the sheet of (scene, method, view) goes, relative to ``out`` (None without pictures)."""
        return (Path("pictures") / scene / method / f"{view}.png").as_posix() if self.enabled else None

    def method_view(self, *, scene: str, method: str, view: str, pre_rgb, post_rgb, ref_rgb, pre_depth, post_depth,
                    mask, geo, compat: bool, semantic, structural) -> str:
        """Write the sheet of one method at one view (host arrays only); returns its relative path.

        geo: GeometricView or None; semantic: (pre, post) predictions of the
        first semantic probe or None; structural: [(title, rgb, MaskSet)] of
        the first structural probe.
        """
        from ..metrics.compat import compat_quantise, depth_delta
        from ..report.pictures import view_contact_sheet

        delta = threshold = changed = None
        if geo is not None:
            delta = depth_delta(pre_depth, post_depth)
            changed, threshold = geo.changed, geo.threshold
            if compat:  # the heat map then shows the 8-bit gray levels the threshold applies to
                delta = compat_quantise(delta)
        rel = self.path_for(scene, method, view)
        view_contact_sheet(
            self.out / rel, title=f"{scene} / {method} / {view}", pre=pre_rgb, post=post_rgb, target=mask,
            ref=ref_rgb, delta=delta, threshold=threshold, changed=changed,
            semantic_pre=None if semantic is None else semantic[0].union(),
            semantic_post=None if semantic is None else semantic[1].union(),
            structural=[(t, rgb, ms.masks) for t, rgb, ms in structural],
        )
        return rel
