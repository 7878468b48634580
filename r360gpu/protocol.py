"""The Remove360 protocol's constants and r360gpu's result schemas, defined once.

Every number here is fixed by the protocol (the paper's Sec. 3 and Supp. A.4; definitions and
values on the docs page "The protocol", docs/protocol.md), not a tuning choice of this
implementation -- except `MIN_SCENES_TO_RANK`, r360gpu's own rule, with its reason beside it.
Everything else in the package imports them from here, and
``tests/test_protocol_constants.py`` fails when one of these literals is written again
elsewhere (as a default argument, a module constant, a tuple of the axis names or a schema
string).  Rendering conventions live in
`r360gpu.render.conventions`, in the same spirit.

Semantic axis (``eq:acc_seg``)
    `XI_DEFAULT`: a view counts as detected when ``IoU(M_post, M) >= xi``;
    ``s_sem = acc_seg`` at this xi.  `XI_SWEEP`: the thresholds of the
    sensitivity sweep.  `XI_PUBLIC`: the thresholds the public scripts report.

Structural axis (``eq:sim_sam``)
    `RETAIN_IOU`: a probe mask is retained when its IoU with the target mask
    is at least this.  `STRUCTURAL_MODES`: with a reference ``sim_SAM(I_post, I_ref)``,
    without one ``1 - sim_SAM(I_pre, I_post)``.

Geometric axis (``eq:acc_depth``)
    GHT (Barron, ECCV 2020) on a `GHT_BINS`-bin histogram of |dD| with the reference
    parameters `GHT_NU`, `GHT_TAU`, `GHT_KAPPA`, `GHT_OMEGA`.

Aggregation (``eq:rqs``, Supp. A.4)
    `AXES`: the three axes, in the order RQS, ranks and tables use; RQS is their
    geometric mean, the cube root of their product.  The reliability statistics use
    `N_BOOT` paired bootstrap resamples, `N_PERM` permutations and a
    `CI_LEVEL` confidence interval, stated only from `MIN_SCENES_TO_RANK` scenes
    on; the boundary sweep erodes and dilates the target
    by `BOUNDARY_PX` pixels.

Schemas
    `RESULTS_SCHEMA` names ``results.json``; `VIEW_RECORD_SCHEMA` one cached
    per-view record.  A reader refuses any other name.
"""
from __future__ import annotations

#: The paper's detection threshold: s_sem = acc_seg at this xi.
XI_DEFAULT: float = 0.3
#: Thresholds of the sensitivity sweep (Supp. "threshold sensitivity").
XI_SWEEP: tuple[float, ...] = (0.3, 0.5, 0.7, 0.9)
#: Thresholds the public Remove360 scripts report (compat mode scores them).
XI_PUBLIC: tuple[float, ...] = (0.3, 0.5)

#: Minimum IoU with the target mask for a structural-probe mask to be retained.
RETAIN_IOU: float = 0.1
#: Structural comparison modes (eq. structural_axis): against the reference, or pre vs post.
STRUCTURAL_MODES: tuple[str, str] = ("reference", "reference_free")

#: GHT reference parameters (Remove360's depth_diff.py) and histogram size.
GHT_NU: float = 1000.0
GHT_TAU: float = 300.0
GHT_KAPPA: float = 0.0
GHT_OMEGA: float = 0.0
GHT_BINS: int = 256

#: The three axes, in the order RQS, ranks, tables and CSV columns use.
AXES: tuple[str, str, str] = ("s_sem", "s_geo", "s_str")

#: Paired scene-level bootstrap resamples, permutations, confidence level (Supp. A.4).
N_BOOT: int = 20000
N_PERM: int = 5000
CI_LEVEL: float = 0.95
#: Fewest scenes for which r360gpu states how sure a ranking is (the interval and P(beats best));
#: r360gpu's rule, not the paper's.  S scenes give only C(2S-1, S) distinct paired resamples: 3 for 2
#: scenes, 35 for 4, 126 for 5 (the first count past 100).  With 2 or 3 scenes the 95% interval is
#: exactly the scenes' range (all S draws of the lowest scene have probability S^-S >= 1/27 > 2.5%),
#: and with 4 it rests on a handful of resamples: the numbers would restate the scenes while looking
#: like a statement about the methods.
MIN_SCENES_TO_RANK: int = 5

#: Boundary sensitivity: erode and dilate the target mask by these radii (pixels).
BOUNDARY_PX: tuple[int, ...] = (5, 10, 15)

#: Schema names (name/version) of the documents r360gpu writes.
RESULTS_SCHEMA: str = "r360gpu.results/1"
VIEW_RECORD_SCHEMA: str = "r360gpu.view_record/1"
#: results.json of the ``inpaint`` command (the inpainting benchmarks: 360-USID, SPIn-NeRF).
INPAINT_SCHEMA: str = "r360gpu.inpaint/1"

__all__ = [
    "AXES", "BOUNDARY_PX", "CI_LEVEL", "GHT_BINS", "GHT_KAPPA", "GHT_NU", "GHT_OMEGA", "GHT_TAU", "INPAINT_SCHEMA",
    "MIN_SCENES_TO_RANK", "N_BOOT", "N_PERM", "RESULTS_SCHEMA", "RETAIN_IOU", "STRUCTURAL_MODES",
    "VIEW_RECORD_SCHEMA", "XI_DEFAULT", "XI_PUBLIC", "XI_SWEEP",
]
