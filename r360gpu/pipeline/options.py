"""Scoring options: what ``r360gpu score`` and ``r360gpu demo`` take on the command line."""
from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, field
from numbers import Integral, Real

from ..errors import InputError
from ..metrics.compat import check_compat
from ..metrics.geometric import GhtParams
from ..probes.providers import choose, plan
from ..probes.registry import default_probes  # noqa: F401  (the pipeline's default probes)
from ..protocol import N_BOOT, N_PERM, XI_SWEEP


@dataclass
class EvaluateOptions:
    """Scoring options (the CLI flags of ``r360gpu score``).

    xis: acc_seg thresholds reported (0.3 is s_sem).
    compat: None/False (paper mode), "public" (True means it) or
        "public-default": score as the public scripts do (see
        `r360gpu.aggregate.compat`).
    ght: GHT parameters (a `GhtParams`; a
        dict with its fields is accepted and converted).
    reference_free: True forces s_str = 1 - sim(pre, post) even with a
        reference; None follows each bundle's option.
    depth: "expected" or "median" depth; None follows each bundle.
    views: glob patterns selecting views by name, case-sensitive
        (`r360gpu.bundle.views.matching`; None: the bundle's views);
        applied once per scene, where it is loaded (`evaluate`).
    boundary: run the mask-boundary sweep (E15..D15).
    lpips_model: path of an LPIPS ONNX model (None: LPIPS not computed).
    probe_device: the onnxruntime execution provider of LPIPS (and, on the
        command line, of the learned probes): "auto" (default: a GPU provider
        for the renderer's GPU when onnxruntime has one, else the CPU),
        "cpu", "cuda", "tensorrt", "webgpu", "directml", "coreml"
        (`r360gpu.probes.providers`).
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
    probe_device: str = "auto"
    pictures: bool = True
    fit_views: int = 8
    controls: bool = True
    n_boot: int = N_BOOT
    n_perm: int = N_PERM
    seed: int = 0
    antialiased: bool = False  # render every splat scene in the antialiased mode (score --antialiased)
    orbit: int = 0  # score --orbit N: N more cameras around the target, results under scenes.S.orbit (.orbit)
    # --orbit-radius X: the orbit's radius, a multiple of the capture cameras' median distance to the target
    orbit_radius: float = 1.0
    # --orbit-elevation LO HI: degrees above the capture's horizon (None: the capture cameras' span)
    orbit_elevation: tuple | None = None
    # --orbit-azimuth FROM TO: degrees around the capture's up, 0 toward the first capture camera
    orbit_azimuth: tuple = (0.0, 360.0)
    residuals: bool = False  # score --residuals: residuals/SCENE/METHOD.ply per splat method (.residuals)
    # score --prune-residuals Q: each splat method re-scored without its top-Q residual Gaussians, as an
    # unranked METHOD+pruned under scenes.S.pruned (.residuals); implies residuals
    prune_residuals: int | float | None = None

    def __post_init__(self):
        self.compat = check_compat(self.compat)
        if isinstance(self.ght, dict):
            unknown = sorted(set(self.ght) - set(GhtParams().as_dict()))
            if unknown:
                raise InputError(f"ght: unknown parameter(s) {', '.join(map(str, unknown))} "
                                 f"(known: {', '.join(GhtParams().as_dict())})")
            self.ght = GhtParams(**self.ght)
        self._check()

    def _check(self) -> None:
        """InputError for an option no run can use: the checks of the CLI flags and of the library,
        made when the options are built, before any view is scored."""
        xis = tuple(self.xis) if isinstance(self.xis, (list, tuple)) else None
        if not xis:
            raise InputError(f"xis (--xi) must be a non-empty list of thresholds, got {self.xis!r}")
        for x in xis:
            if isinstance(x, bool) or not isinstance(x, Real) or not math.isfinite(x) or not 0.0 < x <= 1.0:
                raise InputError(f"xi (--xi) values must lie in (0, 1], got {x!r}")
        for flag, value, low in (("n_boot (--n-boot)", self.n_boot, 1), ("n_perm (--n-perm)", self.n_perm, 1),
                                 ("fit_views", self.fit_views, 1), ("seed (--seed)", self.seed, 0)):
            if isinstance(value, bool) or not isinstance(value, Integral) or value < low:
                raise InputError(f"{flag} must be an integer >= {low}, got {value!r}")
        from ..lift.orbit import check_pose_count

        check_pose_count(self.orbit)
        self._check_orbit_shape()
        for flag, value in (("boundary (--no-boundary)", self.boundary), ("pictures (--no-pictures)", self.pictures),
                            ("controls (--no-controls)", self.controls), ("antialiased (--antialiased)",
                                                                         self.antialiased),
                            ("residuals (--residuals)", self.residuals)):
            if not isinstance(value, bool):
                raise InputError(f"{flag} must be True or False, got {value!r}")
        if self.reference_free is not None and not isinstance(self.reference_free, bool):
            raise InputError(f"reference_free (--reference-free) must be None, True or False, "
                             f"got {self.reference_free!r}")
        if self.lpips_model is not None and not (isinstance(self.lpips_model, (str, os.PathLike))
                                                 and str(self.lpips_model).strip()):
            raise InputError(f"lpips_model (--lpips) must be the path of an ONNX model, got {self.lpips_model!r}")
        ght = self.ght
        if not isinstance(ght, GhtParams):
            raise InputError(f"ght must be a GhtParams or a dict of its fields, got {type(ght).__name__}")
        for name, value in ght.as_dict().items():
            if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value) or value < 0:
                raise InputError(f"ght.{name} must be a finite number >= 0, got {value!r}")
        if ght.omega > 1:
            raise InputError(f"ght.omega must lie in [0, 1], got {ght.omega!r}")
        choose(self.probe_device)  # an unknown name
        if self.lpips_model and self.probe_device != "auto":
            plan(self.probe_device)  # a provider asked for by name that onnxruntime lacks
        from .residuals import check_prune

        check_prune(self.prune_residuals)
        if self.depth not in (None, "expected", "median"):
            raise InputError(f"depth (--depth) must be 'expected' or 'median', got {self.depth!r}")
        if self.views is not None:
            views = tuple(self.views) if isinstance(self.views, (list, tuple)) else None
            if not views or not all(isinstance(v, str) and v.strip() for v in views):
                raise InputError(f"views (--views) must be a non-empty list of view names or patterns, "
                                 f"got {self.views!r}")

    def _check_orbit_shape(self) -> None:
        """InputError unless the orbit's radius, elevations and azimuths can place cameras."""
        def number(x) -> bool:
            return not isinstance(x, bool) and isinstance(x, Real) and math.isfinite(x)

        def pair(value) -> bool:
            return isinstance(value, (list, tuple)) and len(value) == 2 and all(map(number, value))

        if not number(self.orbit_radius) or self.orbit_radius <= 0:
            raise InputError(f"orbit_radius (--orbit-radius) must be a number > 0 (a multiple of the capture's "
                             f"distance to the target), got {self.orbit_radius!r}")
        el = self.orbit_elevation
        if el is not None and not (pair(el) and -90 <= el[0] <= el[1] <= 90):
            raise InputError(f"orbit_elevation (--orbit-elevation) must be None or degrees (lo, hi) with "
                             f"-90 <= lo <= hi <= 90, got {el!r}")
        az = self.orbit_azimuth
        if not (pair(az) and az[0] < az[1] <= az[0] + 360):
            raise InputError(f"orbit_azimuth (--orbit-azimuth) must be degrees (from, to) with from < to <= "
                             f"from + 360, got {az!r}")

    def orbit_shape(self) -> dict:
        """The keywords of `r360gpu.lift.orbit.orbit_cameras` these options give."""
        return {"radius": float(self.orbit_radius),
                "elevation": None if self.orbit_elevation is None else tuple(map(float, self.orbit_elevation)),
                "azimuth": tuple(map(float, self.orbit_azimuth))}

    def scoring_key(self) -> dict:
        """The options that change per-view values (part of the view cache key).

        Pictures, controls (cached under their own names) and the statistics
        of the aggregate tables are left out: they do not change a method's
        per-view value.
        """
        d = asdict(self)  # the GhtParams becomes {"nu", "tau", "kappa", "omega"}
        for k in ("pictures", "n_boot", "n_perm", "seed", "controls", "orbit", "orbit_radius", "orbit_elevation",
                  "orbit_azimuth", "residuals", "prune_residuals"):
            d.pop(k)
        if not self.lpips_model:
            d.pop("probe_device")  # then it changes no per-view value (the probes' providers are in their keys)
        d["xis"] = [float(x) for x in self.xis]
        d["views"] = None if self.views is None else list(self.views)
        return d
