"""Aggregation over views, scenes and methods: RQS, ranks, reliability, axis association.

Public API:

* :class:`AxisCells`, :data:`AXES` -- the scenes x methods grid of axis values;
* :func:`read_axes_csv` -- load such a grid from CSV;
* :func:`rqs`, :func:`scene_axis`, :func:`pool_over_scenes` -- eq:rqs and pooling;
* :func:`axis_ranks`, :func:`rank_summary` -- per-axis ranks, AvgRank/MedRank/worst;
* :func:`reliability` -- scene-macro statistics and paired bootstrap;
* :func:`spearman_association`, :func:`axis_association` -- axis redundancy;
* :func:`aggregate_tables` -- all of the above as one JSON-ready dict;
* :func:`aggregate_results` -- those tables and the pooled xi/boundary sweeps of a results document.
"""
from __future__ import annotations

from .association import AXIS_PAIRS, Association, axis_association, spearman_association
from .axes_csv import read_axes_csv
from .cells import AXES, AxisCells
from .pooling import aggregate_results, pooled_sensitivity
from .ranks import RankSummary, axis_ranks, rank_summary
from .reliability import Reliability, reliability
from .rqs import pool_over_scenes, rqs, scene_axis
from .summary import aggregate_tables

__all__ = [
    "AXES", "AXIS_PAIRS", "Association", "AxisCells", "RankSummary", "Reliability",
    "aggregate_results", "aggregate_tables", "axis_association", "axis_ranks", "pool_over_scenes", "rank_summary",
    "pooled_sensitivity", "read_axes_csv", "reliability", "rqs", "scene_axis", "spearman_association",
]
