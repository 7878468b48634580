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
* the probes, already wrapped in the probe cache, and LPIPS; probes that
  learn from the scene are fitted (as per-scene copies) on pre renders that
  are then reused for scoring those views, or, when a fit record in the
  cache says what the fit gives, only once a view has to be scored;
* ``kept``: renders made before the run (:class:`~r360gpu.render.kept.KeptRenders`,
  e.g. the synthetic generator's reference renders), used instead of rendering
  a view again.

Everything it is built from (a bundle spec, :class:`~.options.EvaluateOptions`,
probe objects) is picklable, so another process can open the same run and
score a chunk of its views (:func:`r360gpu.pipeline.stages.score_view`).
"""
from __future__ import annotations

import copy
import json
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..metrics import frame_check
from ..probes.providers import choose
from ..util import warning_log
from ..util.filehash import forget_decoded
from .cache import changed_inputs, digest, fingerprint


@dataclass
class Timer:
    """Seconds spent per stage, summed over the run and over the threads that ran it
    (stages overlap, so the sum may exceed the wall time)."""

    totals: dict = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def add(self, stage: str, t0: float) -> float:
        t = time.perf_counter()
        with self._lock:
            self.totals[stage] = self.totals.get(stage, 0.0) + t - t0
        return t

    def add_seconds(self, stage: str, seconds: float) -> None:
        """Add seconds measured elsewhere (a Ray task's stage totals)."""
        with self._lock:
            self.totals[stage] = self.totals.get(stage, 0.0) + seconds


def open_pres(bundle, src) -> tuple[dict, dict]:
    """The scene's pre sources by name and the pre each method uses: ``({name: source}, {method: name})``.

    "pre" is the scene's default, shared by every method without its own; a
    method's own pre (``bundle.method_pres``) is a separate source named
    ``pre/<method>``.  Equal specs (or the same object) are opened once and
    shared, so no view is rendered twice.
    """
    from ..bundle.model import SourceSpec, pre_name

    def key(spec):
        return spec if isinstance(spec, SourceSpec) else id(spec)

    pres = {"pre": src(bundle.pre)}
    names = {key(bundle.pre): "pre"}
    pre_of = {}
    for m in bundle.methods:
        spec = bundle.method_pres.get(m)
        if spec is None:
            pre_of[m] = "pre"
            continue
        if key(spec) not in names:
            names[key(spec)] = pre_name(m)
            pres[pre_name(m)] = src(spec)
        pre_of[m] = names[key(spec)]
    return pres, pre_of


class SceneRun:
    """The opened sources, masks and probes of one scene (see the module docstring)."""

    def __init__(self, bundle, opts, ctx, sem_probes, str_probes, *, cache, timer: Timer, fit: bool = True,
                 kept=None, check_frames: bool = True):
        from ..bundle import is_from_objects
        from ..bundle.views import require_target
        from ..metrics.fidelity import LpipsModel

        self.bundle, self.opts, self.ctx = bundle, opts, ctx
        self.timer, self.kept = timer, kept
        self.views = list(bundle.views)  # selected once, where the bundle was loaded (bundle.views.narrow_views)
        self.depth_mode = opts.depth or bundle.options.depth
        ref_free = bundle.reference is None or (opts.reference_free if opts.reference_free is not None
                                                else bundle.options.reference_free)
        self.mode = "reference_free" if ref_free else "reference"
        self._open_sources()
        self.target_record = self.target_lifted = None
        loaded = bundle  # the key is made of what was loaded: the target's masks are rendered from it
        if bundle.target is not None:  # [target]: a mask for every view (r360gpu.lift)
            from ..lift.resolve import resolve_lifted

            t0 = time.perf_counter()
            bundle, self.target_record, self.target_lifted = resolve_lifted(bundle, self.pre, ctx=ctx,
                                                                            warn=warning_log.warn)
            self.bundle = bundle
            timer.add("target", t0)
        self._masks: dict = {}
        self._fit_renders: dict = {}
        self._checked_refs: dict = {}  # {view: the reference's render the frame check made}
        require_target(self.views, self.mask, bundle.masks)
        # The digests the key is made of, kept to check, before a view's cells are stored, that the
        # bytes decoded for it are these (cache.changed_inputs: hash while reading, util.filehash).
        self.file_digests = None if is_from_objects(loaded) else loaded.file_digests()
        self._view_readers: dict = {}
        self.fingerprint = fingerprint(loaded, [*self.pres.values(), self.reference, *self.methods.values()],
                                       digests=self.file_digests)
        # the driver checks that pre's cameras see its splats (workers score what the driver accepted);
        # a what-if's cameras are the capture's, already checked, or derived from them (the orbit)
        self.frame_check = self.check_frames(cache) if fit and check_frames else {}
        #: which probes the scene runs and why ({axis: {"probes", "source", "why"}}: the third value of
        #: :func:`r360gpu.probes.registry.scene_probes`, given by whoever chose the probes; {}: not told)
        self.probe_selection: dict = {}
        self._open_probes(sem_probes, str_probes, cache, fit)
        self.lpips = (LpipsModel(opts.lpips_model, choose(opts.probe_device, ctx.adapter_info))
                      if opts.lpips_model and self.reference is not None else None)

    def _open_sources(self) -> None:
        """The pre sources, the reference, the methods and the controls, opened (timed as "load")."""
        from ..bundle import is_from_objects
        from ..render.sources import open_source

        bundle, t0 = self.bundle, time.perf_counter()
        if not is_from_objects(bundle):  # what an earlier run in this process decoded is not this run's
            forget_decoded(bundle.file_digests_paths())

        def src(spec):
            return open_source(spec, ctx=self.ctx, background=bundle.options.background, depth=self.depth_mode)

        self.pres, self.pre_of = open_pres(bundle, src)
        self.reference = src(bundle.reference) if bundle.reference else None
        self.methods = {m: src(s) for m, s in bundle.methods.items()}
        # The controls, scored like methods but never ranked: {control: source
        # name}.  Their cells are cached under the source's name, which no
        # method may take (bundle.model.RESERVED_METHOD_NAMES).
        self.controls = {}
        if self.opts.controls:
            self.controls["identity"] = "pre"
            if self.reference is not None:
                self.controls["reference"] = "reference"
        for src_name in self.controls.values():
            self.pre_of[src_name] = "pre"
        self.timer.add("load", t0)

    def _open_probes(self, sem_probes, str_probes, cache, fit: bool) -> None:
        """The probes, wrapped in the probe cache; those that learn from the scene fitted now, or
        (``fit_pending``) once a view has to be scored when a fit record gives their descriptions."""
        # Probes that learn from the scene are fitted as copies, one per scene: the caller's
        # objects stay as given, so the fit record's key (their description) is the same every run.
        learns = lambda p: getattr(p, "learns_from_scene", False)  # noqa: E731 (probes.base.Probe.fit)
        sem_probes = [copy.deepcopy(p) if learns(p) else p for p in sem_probes]
        str_probes = [copy.deepcopy(p) if learns(p) else p for p in str_probes]
        # fit=False: the probes come fitted already (a worker of .distributed gets the driver's fit)
        self._to_fit = [p for p in sem_probes + str_probes if learns(p)] if fit else []
        self.sem = [cache.wrap_probe(p) for p in sem_probes]
        self.stru = [cache.wrap_probe(p) for p in str_probes]
        self.fit_pending = False
        if self._to_fit:
            # what the fit reads: pre's renders of the picked views and their masks
            self._fit_key = digest({"bundle": self.fingerprint, "views": self._fit_views(), "depth": self.depth_mode,
                                    "pre": self.pre.describe(), "probes": self._describe(),
                                    "own_pres": {n: src.describe() for n, src in self.pres.items() if n != "pre"}})
            recorded = None if self.fingerprint is None else cache.load_fit(self._fit_key)
            if recorded is None:
                self.fit()
                if self.fingerprint is not None:
                    cache.store_fit(self._fit_key, self._describe())
            else:
                self.fit_pending = True
        self.probes_desc = recorded if self.fit_pending else self._describe()

    def measure_settings(self, *, boundary_sweep: bool = True):
        """How the run measures a view (:class:`~r360gpu.metrics.measure.MeasureSettings`), with the
        probes as described now (a pending fit changes their description); ``boundary_sweep`` False:
        without the sweep (the controls)."""
        from ..metrics.measure import MeasureSettings

        opts = self.opts
        return MeasureSettings(mode=self.mode, probes=self.probes_desc["semantic"] + self.probes_desc["structural"],
                               boundary=boundary_sweep and opts.boundary, xis=opts.xis, compat=opts.compat,
                               ght_params=opts.ght, lpips_model=self.lpips, ctx=self.ctx)

    @property
    def pre(self):
        """The scene's own pre-removal source."""
        return self.pres["pre"]

    def camera(self, view: str):
        return self.bundle.cameras.get(view) if self.bundle.cameras else None

    def view_files(self, view: str) -> list[str]:
        """The input files the scores of ``view`` are decoded from (none for scenes from objects)."""
        if self.file_digests is None:
            return []
        return self.bundle.view_files(view, self._view_readers)

    def changed_inputs(self, view: str, decoded: dict | None = None) -> list[str]:
        """Inputs of ``view`` decoded from other bytes than the cache key's (see cache.changed_inputs)."""
        return changed_inputs(self.file_digests, self.view_files(view), decoded)

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
        return hit if hit is not None else self.images(self.pres[name], view)

    def render_reference(self, view: str):
        """The view rendered by the reference; the frame check's render is used once more, not redone."""
        hit = self._checked_refs.pop(view, None)
        return hit if hit is not None else self.images(self.reference, view)

    def images(self, source, view: str):
        """``source`` rendered at the view's camera: a kept render when there is one."""
        cam = self.camera(view)
        hit = self.kept.take(source, cam) if self.kept is not None else None
        return hit if hit is not None else source.images(view, cam)

    def done(self, view: str) -> None:
        """Drop what was kept for ``view``."""
        self._masks.pop(view, None)
        self._checked_refs.pop(view, None)
        for key in [k for k in list(self._fit_renders) if k[1] == view]:
            self._fit_renders.pop(key, None)

    def _describe(self) -> dict:
        """The probes' descriptions as JSON gives them back (lists, not tuples), so a fresh one
        compares equal to a recorded one."""
        return json.loads(json.dumps({"semantic": [p.describe() for p in self.sem],
                                      "structural": [p.describe() for p in self.stru]}, default=str))

    def _fit_views(self) -> list:
        """Up to ``fit_views`` views with a visible target, evenly spread."""
        with_target = [v for v in self.views if self.mask(v).any()]
        if not with_target:
            return []
        idx = np.linspace(0, len(with_target) - 1, min(self.opts.fit_views, len(with_target))).round().astype(int)
        return list(dict.fromkeys(with_target[i] for i in idx))

    def fit(self) -> bool:
        """Fit the probes that learn from the scene (the built-in appearance probe) on pre
        renderings of the fit views; the renders are kept for scoring those views.

        With methods that bring their own pre, the fit sees the fit views of every pre
        source: each pipeline renders the scene its own way, and a probe fitted on one of
        them alone can miss the object in another's renders (IoU_pre 0 for that method).

        Returns True when the probes' descriptions differ from ``probes_desc``
        (which then came from a fit record that no longer holds).
        """
        t0 = time.perf_counter()
        pick = self._fit_views()
        kept = self._fit_renders  # (the frame check's renders are these views' too, where they meet)
        self._fit_renders = {(name, v): kept[name, v] if (name, v) in kept else self.images(src, v)
                             for name, src in self.pres.items() for v in pick}
        for p in self._to_fit:
            p.fit([r.rgb for r in self._fit_renders.values()], [self.mask(v) for _, v in self._fit_renders])
        self.timer.add("fit probes", t0)
        desc = self._describe()
        stale = getattr(self, "probes_desc", desc) != desc
        self.probes_desc, self.fit_pending = desc, False
        return stale

    def check_frames(self, cache) -> dict:
        """Render each splat-scene pre source at a few evaluation views with a target and check
        that its cameras see it (:mod:`r360gpu.metrics.frame_check`): an InputError when they
        miss the splats, a note kept in the verdict when the target's outline has little depth
        step; the renders are kept for scoring.  The verdict is cached with the bundle's
        fingerprint (a rerun renders nothing for it).  Returns {pre name: verdict dict} of the
        sources checked."""
        from ..render.sources import host_depth

        pick = frame_check.checked_views([v for v in self.views if self.mask(v).any()])
        if not pick:
            return {}
        out = {}
        for name, src in self.pres.items():
            if src.kind != "scene" or self.camera(pick[0]) is None:
                continue  # renders made elsewhere are images already: no frame to get wrong
            key = digest({"frame_check": self.fingerprint, "views": pick, "source": src.describe(),
                          "check": frame_check.CHECK_VERSION})
            recorded = None if self.fingerprint is None else cache.load_fit(key, "frames")
            if recorded is not None:
                verdict = frame_check.FrameVerdict.from_dict(recorded)
            else:
                t0 = time.perf_counter()
                seen = []
                for v in pick:
                    img = self.images(src, v)
                    self._fit_renders[name, v] = img  # render_pre takes it when the view is scored
                    seen.append((v, self.camera(v), img.alpha, host_depth(img.depth, self.ctx), self.mask(v), img.rgb))
                verdict = frame_check.check_views(seen, self._reference_images)
                self.timer.add("frame check", t0)
                if self.fingerprint is not None:
                    cache.store_fit(key, verdict.to_dict(), "frames")
            out[name] = verdict.to_dict()
            if verdict.level == "note":
                out[name]["note"] = frame_check.note_message(verdict)
            elif verdict.missed:
                frame = src.frame  # a scene source's (render.sources.SceneSource)
                raise InputError(f"scene {self.bundle.name}: " + frame_check.mismatch_message(
                    verdict, source=str(src.path), frame=None if frame is None else frame.origin,
                    cameras=None if self.bundle.cameras_path is None else str(self.bundle.cameras_path)))
        return out

    def _reference_images(self, view: str):
        """The reference at ``view`` for the frame check (host arrays), or None without one."""
        from ..render.sources import ViewImages, host_depth

        if self.reference is None:
            return None
        img = self._checked_refs[view] = self.render_reference(view)  # render_reference takes it when scored
        return ViewImages(img.rgb, host_depth(img.depth, self.ctx), img.alpha)

    def describe_sources(self) -> dict:
        out = {"pre": self.pre.describe(),
               "reference": self.reference.describe() if self.reference else None,
               "methods": {m: s.describe() for m, s in self.methods.items()}}
        own = {m: self.pres[n].describe() for m, n in self.pre_of.items() if n != "pre"}
        if own:
            out["method_pres"] = own
        return out

    def release(self) -> None:
        for s in [*self.pres.values(), self.reference, *self.methods.values()]:
            if s is not None:
                s.release()
