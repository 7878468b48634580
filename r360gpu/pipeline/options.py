"""Scoring options: what ``r360gpu score`` and ``r360gpu demo`` take on the command line."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

from ..metrics.geometric import GhtParams
from ..metrics.semantic import XI_SWEEP


@dataclass
class EvaluateOptions:
    """Scoring options (the CLI flags of ``r360gpu score``).

    xis: acc_seg thresholds reported (0.3 is s_sem).
    compat: None/False (paper mode), "public" (True means it) or
        "public-default": score as the public scripts do (see
        :mod:`r360gpu.aggregate.compat`).
    ght: GHT parameters (a :class:`~r360gpu.metrics.geometric.GhtParams`; a
        dict with its fields is accepted and converted).
    reference_free: True forces s_str = 1 - sim(pre, post) even with a
        reference; None follows each bundle's option.
    depth: "expected" or "median" depth; None follows each bundle.
    views: glob patterns selecting views by name (None: the bundle's views).
    boundary: run the mask-boundary sweep (E15..D15).
    lpips_model: path of an LPIPS ONNX model (None: LPIPS not computed).
    pictures: write a contact sheet per (method, view) and plots.
    fit_views: views of the pre rendering a fitted probe learns from.
    controls: also score the controls of each scene (the unedited pre
        scored as if it were a method, and the reference likewise), from
        which each axis gets a validity verdict (``aggregate.validity``).
    n_boot, n_perm, seed: statistics of the aggregate tables.
    """

    xis: tuple = XI_SWEEP
    compat: bool | str | None = None
    ght: GhtParams = field(default_factory=GhtParams)
    reference_free: bool | None = None
    depth: str | None = None
    views: tuple | None = None
    boundary: bool = True
    lpips_model: str | None = None
    pictures: bool = True
    fit_views: int = 8
    controls: bool = True
    n_boot: int = 20000
    n_perm: int = 5000
    seed: int = 0
    antialiased: bool = False  # render every splat scene in the antialiased mode (score --antialiased)
    orbit: int = 0  # score --orbit N: N more cameras around the target, results under scenes.S.orbit (.orbit)
    residuals: bool = False  # score --residuals: residuals/SCENE/METHOD.ply per splat method (.residuals)

    def __post_init__(self):
        from ..metrics.compat import check_compat

        self.compat = check_compat(self.compat)
        if isinstance(self.ght, dict):
            self.ght = GhtParams(**self.ght)

    def scoring_key(self) -> dict:
        """The options that change per-view values (part of the view cache key).

        Pictures, controls (cached under their own names) and the statistics
        of the aggregate tables are left out: they do not change a method's
        per-view value.
        """
        d = asdict(self)  # the GhtParams becomes {"nu", "tau", "kappa", "omega"}
        for k in ("pictures", "n_boot", "n_perm", "seed", "controls", "orbit", "residuals"):
            d.pop(k)
        d["xis"] = [float(x) for x in self.xis]
        d["views"] = None if self.views is None else list(self.views)
        return d


def default_probes():
    """The weight-free built-in probes: (semantic list, structural list) (see probes.registry)."""
    from ..probes.registry import default_probes as registry_defaults

    return registry_defaults()
