"""Sanity checks of a view's depth pair before its acc_depth is trusted.

The geometric axis follows the public reference's missing-depth rule (dD = 0
where either depth is missing), so two input problems give a plausible but
wrong number without any error:

* a method whose depth is missing (0 or non-finite) over the whole view while
  pre has depth: every dD is 0 and acc_depth falls to 0;
* the same on the pre side (pre's depth all 0, NaN or Inf in a view), checked
  and noted the same way: every dD is 0 there too;
* depth in another unit than pre's (a renders folder of 16-bit PNGs in
  millimetres beside a splat scene in metres): the per-view threshold is
  chosen on a histogram dominated by the unit change.

:func:`check_view` detects both, warns (recorded in results.json through
:mod:`r360gpu.util.warning_log`) and returns a note that the pipeline stores
in the view's geometric record, so the axis can say how many of its views
rest on a doubtful depth (:func:`geo_notes`).  The unit test compares D_post
with D_pre on pixels valid in both *outside* the target (where nothing should
have changed): a median ratio beyond :data:`UNIT_RATIO` either way is a
warning naming the source and ``depth_scale``.  It runs once per (scene,
method), on the first view with at least :data:`MIN_PIXELS` such pixels.
"""
from __future__ import annotations

import numpy as np

from ..util import warning_log

UNIT_RATIO = 3.0
MIN_PIXELS = 16
NOTE_NO_DEPTH = "no valid post depth"
NOTE_NO_PRE_DEPTH = "no valid pre depth"
NOTE_UNIT = "depth unit differs from pre"


def _host(depth) -> np.ndarray | None:
    if depth is None:
        return None
    from ..gpu.context import DeviceDepth

    if isinstance(depth, DeviceDepth):
        from ..render.sources import host_depth  # noqa: layer below the pipeline that calls us

        depth = host_depth(depth)
    return np.asarray(depth, np.float32)


def _valid(d: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.isfinite(d) & (d > 0)


def unit_ratio(d_pre, d_post, mask) -> float | None:
    """Median D_post / D_pre over pixels valid in both and outside the target (None: too few)."""
    pre, post = _host(d_pre), _host(d_post)
    m = np.asarray(mask) != 0
    both = _valid(pre) & _valid(post) & ~m
    if int(both.sum()) < MIN_PIXELS:
        return None
    return float(np.median(post[both] / pre[both]))


def check_view(scene: str, method: str, view: str, d_pre, d_post, mask, *, source=None,
               label=None, pre_source=None) -> str | None:
    """Warn about a doubtful depth pair; returns the note for the view's record (None: fine).

    source: the method's file or folder (named in the warning); label: how
    the bundle names it (``[methods.NAME]``).  pre_source: pre's depth file of the view, or a
    callable giving it (called only to warn).
    """
    if d_pre is None or d_post is None:
        return None
    pre, post = _host(d_pre), _host(d_post)
    label = label or f"[methods.{method}]"
    pre_valid = int(_valid(pre).sum())
    if not pre_valid:
        warning_log.warn(f"pre has no valid depth (all 0, NaN or Inf) in this view: {label}'s acc_depth counts "
                         f"no pixel as changed (the reference's missing-depth rule); check pre's depth output",
                         file=pre_source() if callable(pre_source) else pre_source, scene=scene, method=method,
                         view=view)
        return NOTE_NO_PRE_DEPTH
    if not _valid(post).any():
        warning_log.warn(f"{label} has no valid depth (all 0 or NaN) in this view while pre has depth at "
                         f"{pre_valid} pixels: its acc_depth counts no pixel as changed (the reference's "
                         f"missing-depth rule); check the method's depth output",
                         file=source, scene=scene, method=method, view=view)
        return NOTE_NO_DEPTH
    key = ("depth-unit", scene, method)
    r = None if warning_log.seen(key) else unit_ratio(pre, post, mask)
    if r is None:
        return None
    warning_log.once(key)
    if r > UNIT_RATIO or r < 1.0 / UNIT_RATIO:
        warning_log.warn(f"{label}'s depth is {r:.3g} times pre's outside the target (median D_post/D_pre over "
                         f"pixels valid in both): a different depth unit? Set depth_scale = {1.0 / r:.3g} "
                         f"on {label} (renders) so every source uses pre's unit",
                         file=source, scene=scene, method=method, view=view)
        return NOTE_UNIT
    return None


def annotate(record, note: str | None) -> None:
    """Store ``note`` in a ViewRecord's geometric summary (no-op without note or geometry)."""
    if note and record.geometric is not None:
        record.geometric["depth_note"] = note


def geo_notes(geometric: list[dict]) -> dict:
    """{note: number of views} over a method's geometric summaries ({} when none is doubtful)."""
    out: dict[str, int] = {}
    for g in geometric:
        n = g.get("depth_note") if isinstance(g, dict) else None
        if n:
            out[n] = out.get(n, 0) + 1
    return out
