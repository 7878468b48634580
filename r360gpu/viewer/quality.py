"""Progressive rendering: fewer pixels while the camera moves, full resolution once it rests.

:class:`ResolutionPolicy` picks the linear render scale of each frame.  While
the camera moved within the last ``still_delay`` seconds the scale is the
*moving scale*: ``moving_scale`` when fixed, else adaptive — the largest
scale whose predicted render time (seconds per pixel, measured on the frames
rendered so far, times the pixel count) fits ``frame_budget``, clamped to
[``min_scale``, 1] (on a fast GPU that is 1: no reduction at all).  Once the
camera has rested for ``still_delay`` the scale is 1 (refine).
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class ResolutionPolicy:
    """See the module docstring.  Times in seconds; scales are linear (0.5 = a quarter of the pixels)."""

    still_delay: float = 0.3
    frame_budget: float = 1.0 / 30.0
    min_scale: float = 0.25
    moving_scale: float | None = None
    seconds_per_pixel: float | None = None  # running estimate
    smoothing: float = 0.5

    def observe(self, pixels: int, seconds: float) -> None:
        """Record that rendering ``pixels`` pixels took ``seconds`` (all scenes of one frame)."""
        if pixels <= 0 or not (seconds >= 0) or not math.isfinite(seconds):
            return
        spp = seconds / pixels
        if self.seconds_per_pixel is None:
            self.seconds_per_pixel = spp
        else:
            self.seconds_per_pixel = self.smoothing * self.seconds_per_pixel + (1 - self.smoothing) * spp

    def moving(self, full_pixels: int) -> float:
        """Scale while moving, for a frame of ``full_pixels`` pixels at scale 1."""
        if self.moving_scale is not None:
            return float(min(1.0, max(self.min_scale, self.moving_scale)))
        if self.seconds_per_pixel is None or full_pixels <= 0:
            return 0.5
        predicted = self.seconds_per_pixel * full_pixels
        if predicted <= self.frame_budget:
            return 1.0
        return float(min(1.0, max(self.min_scale, math.sqrt(self.frame_budget / predicted))))

    def scale(self, since_motion: float, full_pixels: int) -> float:
        """The scale of a frame ``since_motion`` seconds after the camera last moved."""
        if since_motion >= self.still_delay:
            return 1.0
        return self.moving(full_pixels)

    def quantised(self, scale: float) -> float:
        """``scale`` rounded down to a multiple of 1/16 (at least ``min_scale``), so moving frames
        reuse a few render sizes instead of a new one per frame."""
        if scale >= 1.0:
            return 1.0
        return max(self.min_scale, math.floor(scale * 16.0) / 16.0)
