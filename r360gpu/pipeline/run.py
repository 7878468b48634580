"""One scene's run: its views, sources, target masks and probes, opened once.

A :class:`SceneRun` is what the per-view stages (:mod:`.stages`) read.  It
holds

* ``pres``: the pre-removal sources by name, and ``pre_of``: which one each
  method is compared against (every method uses the scene's ``pre`` today; a
  method that brings its own pre adds an entry here and nothing else changes);
* ``reference`` (or None) and ``methods``: the other sources;
* ``controls``: {control: source name}, the sources scored as if they were
  methods to show what each axis reads on an unedited scene ("identity": the
  pre) and on a real removal ("reference");
* the target masks (read on first use, dropped once the view is done);
* the probes, already wrapped in the probe cache, and LPIPS;
* ``warnings``: a :class:`WarningLog` the stages add to.

Everything it is built from (a bundle spec, :class:`~.options.EvaluateOptions`,
probe objects) is picklable, so another process can open the same run and
score a chunk of its views (:func:`r360gpu.pipeline.stages.score_view`).
"""
from __future__ import annotations

import fnmatch
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError


@dataclass
class Timer:
    """Seconds spent per stage, summed over the run."""

    totals: dict = field(default_factory=dict)

    def add(self, stage: str, t0: float) -> float:
        t = time.perf_counter()
        self.totals[stage] = self.totals.get(stage, 0.0) + t - t0
        return t


@dataclass
class WarningLog:
    """Doubtful but usable inputs met during the run, each with where it was met."""

    items: list = field(default_factory=list)
    log: object = None  # print-like; each warning is printed once when given

    def add(self, message: str, *, scene=None, method=None, view=None, file=None) -> None:
        item = {"scene": scene, "method": method, "view": view, "file": None if file is None else str(file),
                "message": message}
        if item not in self.items:
            self.items.append(item)
            if self.log is not None:
                self.log(f"warning: {message}")


def select_views(names: list[str], patterns) -> list[str]:
    """The views whose name matches one of the glob patterns (all without patterns)."""
    if not patterns:
        return list(names)
    out = [n for n in names if any(fnmatch.fnmatchcase(n, p) for p in patterns)]
    if not out:
        raise InputError(f"no view matches {list(patterns)} (views are named like {names[:3]})")
    return out


class SceneRun:
    """The opened sources, masks and probes of one scene (see the module docstring)."""

    def __init__(self, bundle, opts, ctx, sem_probes, str_probes, *, cache, timer: Timer, warnings: WarningLog,
                 fit: bool = True):
        from ..metrics.fidelity import LpipsModel
        from ..render.sources import open_source

        self.bundle, self.opts, self.ctx = bundle, opts, ctx
        self.timer, self.warnings = timer, warnings
        self.views = select_views(bundle.views, opts.views)
        self.depth_mode = opts.depth or bundle.options.depth
        ref_free = bundle.reference is None or (opts.reference_free if opts.reference_free is not None
                                                else bundle.options.reference_free)
        self.mode = "reference_free" if ref_free else "reference"
        t0 = time.perf_counter()

        def src(spec):
            return open_source(spec, ctx=ctx, background=bundle.options.background, depth=self.depth_mode)

        self.pres = {"pre": src(bundle.pre)}
        self.reference = src(bundle.reference) if bundle.reference else None
        self.methods = {m: src(s) for m, s in bundle.methods.items()}
        self.pre_of = {m: "pre" for m in bundle.methods}
        # The controls, scored like methods but never ranked: {control: source
        # name}.  Their cells are cached under the source's name, which no
        # method may take (bundle.model.RESERVED_METHOD_NAMES).
        self.controls = {}
        if opts.controls:
            self.controls["identity"] = "pre"
            if self.reference is not None:
                self.controls["reference"] = "reference"
        for src_name in self.controls.values():
            self.pre_of[src_name] = "pre"
        timer.add("load", t0)
        self._masks: dict = {}
        self._fit_renders: dict = {}
        if fit:  # False: the probes come fitted already (a worker of .distributed gets the driver's fit)
            self._fit(sem_probes + str_probes)
        self.sem = [cache.wrap_probe(p) for p in sem_probes]
        self.stru = [cache.wrap_probe(p) for p in str_probes]
        self.probes_desc = {"semantic": [p.describe() for p in self.sem],
                            "structural": [p.describe() for p in self.stru]}
        self.lpips = LpipsModel(opts.lpips_model) if opts.lpips_model and self.reference is not None else None

    @property
    def pre(self):
        """The scene's own pre-removal source."""
        return self.pres["pre"]

    def camera(self, view: str):
        return self.bundle.cameras.get(view) if self.bundle.cameras else None

    def mask(self, view: str) -> np.ndarray:
        """The view's target mask (bool, H x W), read once."""
        if view not in self._masks:
            from ..io import load_mask

            c = self.camera(view)
            m = self.bundle.masks[view]
            if isinstance(m, np.ndarray):  # a scene built from objects (scene_from_objects)
                self._masks[view] = m != 0
            else:
                self._masks[view] = load_mask(m, shape=None if c is None else (c.height, c.width))
        return self._masks[view]

    def render_pre(self, name: str, view: str):
        """The view rendered by pre source ``name``; the fit's renders are used once more, not redone."""
        hit = self._fit_renders.pop((name, view), None)
        return hit if hit is not None else self.pres[name].images(view, self.camera(view))

    def done(self, view: str) -> None:
        """Drop what was kept for ``view``."""
        self._masks.pop(view, None)
        for key in [k for k in self._fit_renders if k[1] == view]:
            del self._fit_renders[key]

    def _fit(self, probes) -> None:
        """Probes that learn from the scene (the built-in appearance probe) fit on
        pre renderings of up to ``fit_views`` views with a visible target."""
        fitted = [p for p in probes if hasattr(p, "fit")]
        if not fitted:
            return
        t0 = time.perf_counter()
        with_target = [v for v in self.views if self.mask(v).any()]
        pick = []
        if with_target:
            idx = np.linspace(0, len(with_target) - 1, min(self.opts.fit_views, len(with_target))).round().astype(int)
            pick = list(dict.fromkeys(with_target[i] for i in idx))
        renders = [self.pre.images(v, self.camera(v)) for v in pick]
        self._fit_renders = {("pre", v): r for v, r in zip(pick, renders)}
        for p in fitted:
            p.fit([r.rgb for r in renders], [self.mask(v) for v in pick])
        self.timer.add("fit probes", t0)

    def describe_sources(self) -> dict:
        return {"pre": self.pre.describe(),
                "reference": self.reference.describe() if self.reference else None,
                "methods": {m: s.describe() for m, s in self.methods.items()}}

    def release(self) -> None:
        for s in [*self.pres.values(), self.reference, *self.methods.values()]:
            if s is not None:
                s.release()
