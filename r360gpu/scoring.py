"""Scoring scene bundles end to end: load -> render -> probe -> measure -> aggregate.

:func:`evaluate` is the library entry point behind ``r360gpu score`` and
``r360gpu demo``.  Per scene it keeps every reconstruction (pre, reference,
each method) on the device, walks the evaluation views once, and for each
view renders pre / reference / every method, runs the probes (outputs cached
on disk by image content), and measures the three axes plus fidelity and the
mask-boundary sweep.  Each (scene, method, view) result is written to a
cache file as soon as it exists, so a killed run resumes where it stopped;
``force=True`` recomputes everything.
"""
from __future__ import annotations

import fnmatch
import hashlib
import json
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .errors import InputError
from .metrics.semantic import XI_SWEEP

CACHE_DIR = ".r360cache"


@dataclass
class EvaluateOptions:
    """Scoring options (the CLI flags of ``r360gpu score``).

    xis: acc_seg thresholds reported (0.3 is s_sem).
    compat: geometric axis in the reference pipeline's 8-bit mode.
    ght: GHT parameters (nu, tau, kappa, omega).
    reference_free: True forces s_str = 1 - sim(pre, post) even with a
        reference; None follows each bundle's option.
    depth: "expected" or "median" depth; None follows each bundle.
    views: glob patterns selecting views by name (None: the bundle's views).
    boundary: run the mask-boundary sweep (E15..D15).
    lpips_model: path of an LPIPS ONNX model (None: LPIPS not computed).
    pictures: write a contact sheet per (method, view) and plots.
    fit_views: views of the pre rendering a fitted probe learns from.
    n_boot, n_perm, seed: statistics of the aggregate tables.
    """

    xis: tuple = XI_SWEEP
    compat: bool = False
    ght: dict = field(default_factory=lambda: {"nu": 1000.0, "tau": 300.0, "kappa": 0.0, "omega": 0.0})
    reference_free: bool | None = None
    depth: str | None = None
    views: tuple | None = None
    boundary: bool = True
    lpips_model: str | None = None
    pictures: bool = True
    fit_views: int = 8
    n_boot: int = 20000
    n_perm: int = 5000
    seed: int = 0

    def scoring_key(self) -> dict:
        """The options that change per-view values (for the cache key)."""
        d = asdict(self)
        for k in ("pictures", "n_boot", "n_perm", "seed"):
            d.pop(k)
        d["xis"] = [float(x) for x in self.xis]
        d["views"] = None if self.views is None else list(self.views)
        return d


def default_probes():
    """The weight-free built-in probes: (semantic list, structural list)."""
    from .probes.registry import default_probes as registry_defaults

    return registry_defaults()


def _digest(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


@dataclass
class _Timer:
    totals: dict = field(default_factory=dict)

    def add(self, stage: str, t0: float) -> float:
        t = time.perf_counter()
        self.totals[stage] = self.totals.get(stage, 0.0) + t - t0
        return t


def _select_views(names: list[str], patterns) -> list[str]:
    if not patterns:
        return list(names)
    out = [n for n in names if any(fnmatch.fnmatchcase(n, p) for p in patterns)]
    if not out:
        raise InputError(f"no view matches {list(patterns)} (views are named like {names[:3]})")
    return out


def evaluate(
    bundles,
    *,
    out=None,
    semantic_probes=None,
    structural_probes=None,
    options: EvaluateOptions | None = None,
    ctx=None,
    adapter: str | None = None,
    device=None,
    force: bool = False,
    progress: bool = True,
    log=print,
) -> dict:
    """Score one or more scene bundles; returns the results document (a dict).

    bundles: bundle folders, :class:`~r360gpu.bundle.Bundle` objects, or
        scenes built from in-memory objects with :func:`scene_from_objects`
        (Gaussians, or renders and depths already on the device).
    out: output folder for results.json, tables, pictures and report.html
        (None: nothing is written and nothing is cached).
    semantic_probes, structural_probes: lists of probes (default: the
        weight-free built-ins).  With several probes per axis the axes use the
        "most alarming" reading per view; each probe's own axes are kept.
    ctx / adapter / device: the GPU context, an adapter choice, or a caller's
        ``wgpu.GPUDevice``.
    """
    from .bundle import Bundle, load_bundle
    from .gpu import get_context
    from .probes.cache import ProbeCache, cached

    opts = options or EvaluateOptions()
    ctx = ctx or get_context(adapter, device=device)
    if semantic_probes is None or structural_probes is None:
        d_sem, d_str = default_probes()
        semantic_probes = d_sem if semantic_probes is None else semantic_probes
        structural_probes = d_str if structural_probes is None else structural_probes
    if isinstance(bundles, (str, Path, Bundle)):
        bundles = [bundles]
    loaded = [b if isinstance(b, Bundle) else load_bundle(b) for b in bundles]
    names = [b.name for b in loaded]
    if len(set(names)) != len(names):
        raise InputError(f"two bundles share a scene name: {names}")
    methods = list(loaded[0].methods)
    out = Path(out) if out is not None else None
    cache_root = out / CACHE_DIR if out is not None else None
    if force and cache_root is not None and cache_root.exists():
        shutil.rmtree(cache_root)
    probe_cache = ProbeCache(cache_root / "probes") if cache_root is not None else None

    timer = _Timer()
    results = {
        "schema": "r360gpu.results/1",
        "r360gpu_version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "adapter": ctx.describe(),
        "options": {**opts.scoring_key(), "n_boot": opts.n_boot, "n_perm": opts.n_perm, "seed": opts.seed},
        "probes": {},
        "scenes": {},
    }
    t_start = time.perf_counter()
    n_views_done = 0
    for bundle in loaded:
        if list(bundle.methods) != methods:
            log(f"note: scene {bundle.name} has methods {list(bundle.methods)}; "
                f"cross-scene tables need the same methods everywhere ({methods})")
        scene_res, n = _evaluate_scene(
            bundle, opts, ctx, semantic_probes, structural_probes, probe_cache, cache_root, out, timer, progress, log
        )
        results["scenes"][bundle.name] = scene_res
        results["probes"] = scene_res.pop("_probes")
        n_views_done += n
    results["timing"] = {"stages_s": {k: round(v, 3) for k, v in timer.totals.items()},
                         "total_s": round(time.perf_counter() - t_start, 3),
                         "views": n_views_done}
    _aggregate(results, opts)
    return results


def _aggregate(results: dict, opts: EvaluateOptions) -> None:
    from .aggregate import aggregate_tables
    from .aggregate.results import axis_cells

    cells = axis_cells(results["scenes"])
    if cells is None:
        results["aggregate"] = None
        results.setdefault("notes", []).append(
            "aggregate tables need every scene to have the same methods and all three axes")
        return
    results["aggregate"] = aggregate_tables(cells, n_boot=opts.n_boot, n_perm=opts.n_perm, seed=opts.seed)
    # The xi sweep and the boundary sweep, pooled over views like the Overall row.
    sens: dict = {"xi": {}, "boundary": {}}
    for m in cells.methods:
        acc = {}
        bnd: dict = {}
        weights = 0
        for s in cells.scenes:
            ax = results["scenes"][s]["methods"][m]["axes"]
            w = ax.get("n_views") or 0
            weights += w
            for k, v in (ax.get("acc_seg") or {}).items():
                if v is not None:
                    acc.setdefault(k, []).append((v, w))
            for row, vals in (ax.get("boundary") or {}).items():
                for lab, v in vals.items():
                    if v is not None:
                        bnd.setdefault(row, {}).setdefault(lab, []).append((v, w))
        sens["xi"][m] = {k: _wmean(v) for k, v in acc.items()}
        sens["boundary"][m] = {row: {lab: _wmean(v) for lab, v in labs.items()} for row, labs in bnd.items()}
    results["sensitivity"] = sens


def _wmean(pairs):
    w = sum(p[1] for p in pairs)
    if w <= 0:
        return float(np.mean([p[0] for p in pairs])) if pairs else None
    return float(sum(v * wt for v, wt in pairs) / w)


def _evaluate_scene(bundle, opts, ctx, sem_probes, str_probes, probe_cache, cache_root, out, timer, progress, log):
    from .io import load_mask
    from .metrics.fidelity import LpipsModel
    from .probes.cache import cached
    from .render.sources import open_source

    views = _select_views(bundle.views, opts.views)
    depth_mode = opts.depth or bundle.options.depth
    background = bundle.options.background
    ref_free = bundle.reference is None or (opts.reference_free if opts.reference_free is not None
                                            else bundle.options.reference_free)
    mode = "reference_free" if ref_free else "reference"
    t0 = time.perf_counter()
    src_pre = open_source(bundle.pre, ctx=ctx, background=background, depth=depth_mode)
    src_ref = open_source(bundle.reference, ctx=ctx, background=background, depth=depth_mode) if bundle.reference else None
    src_methods = {m: open_source(s, ctx=ctx, background=background, depth=depth_mode) for m, s in bundle.methods.items()}
    timer.add("load", t0)

    cam = (lambda v: bundle.cameras.get(v)) if bundle.cameras else (lambda v: None)
    masks = {}

    def mask_of(v):
        if v not in masks:
            c = cam(v)
            m = bundle.masks[v]
            if isinstance(m, np.ndarray):  # a scene built from objects (scene_from_objects)
                masks[v] = m != 0
            else:
                masks[v] = load_mask(m, shape=None if c is None else (c.height, c.width))
        return masks[v]

    # Probes that learn from the scene (the built-in appearance probe) fit on
    # pre renderings of views with a visible target.
    fitted = [p for p in sem_probes + str_probes if getattr(p, "learns_from_scene", False)]
    if fitted:
        t0 = time.perf_counter()
        with_target = [v for v in views if mask_of(v).any()]
        pick = [with_target[i] for i in np.linspace(0, len(with_target) - 1, min(opts.fit_views, len(with_target))).round().astype(int)] if with_target else []
        imgs = [src_pre.images(v, cam(v)).rgb for v in dict.fromkeys(pick)]
        for p in fitted:
            p.fit(imgs, [mask_of(v) for v in dict.fromkeys(pick)])
        timer.add("fit probes", t0)

    wrap = (lambda p: cached(p, probe_cache)) if probe_cache is not None else (lambda p: p)
    sem = [wrap(p) for p in sem_probes]
    stru = [wrap(p) for p in str_probes]
    probes_desc = {"semantic": [p.describe() for p in sem], "structural": [p.describe() for p in stru]}
    lpips = LpipsModel(opts.lpips_model) if opts.lpips_model and src_ref is not None else None

    key = _digest({"version": __version__, "bundle": _fingerprint(bundle, src_pre, src_ref, src_methods),
                   "options": opts.scoring_key(),
                   "probes": probes_desc, "mode": mode, "depth": depth_mode,
                   "lpips": lpips.describe() if lpips else None})
    view_cache = cache_root / "views" / key / bundle.name if cache_root is not None else None

    records: dict = {m: [] for m in bundle.methods}
    boundaries: dict = {m: [] for m in bundle.methods}
    pictures: dict = {m: {} for m in bundle.methods}
    bar = _progress(views, bundle.name, progress)
    for v in bar:
        cached_cells = {m: _load_cell(view_cache, m, v) for m in bundle.methods} if view_cache else {}
        if view_cache and all(cached_cells.values()):
            for m, cell in cached_cells.items():
                _collect(cell, records[m], boundaries[m], pictures[m], v)
            continue
        cells = _score_view(
            bundle, v, cam(v), mask_of(v), src_pre, src_ref, src_methods, sem, stru, mode, lpips,
            opts, ctx, timer, out, probes_desc,
        )
        for m, cell in cells.items():
            if view_cache is not None:
                from .util.atomic import write_json

                write_json(view_cache / m / f"{v}.json", cell, allow_nan=False)
            _collect(cell, records[m], boundaries[m], pictures[m], v)
        masks.pop(v, None)
    for s in [src_pre, src_ref, *src_methods.values()]:
        if s is not None:
            s.release()

    from .aggregate.results import method_axes

    scene = {
        "prompt": bundle.prompt,
        "n_views": len(views),
        "views": views,
        "reference": bundle.reference is not None,
        "structural_mode": mode,
        "depth": depth_mode,
        "sources": {"pre": src_pre.describe(), "reference": src_ref.describe() if src_ref else None,
                    "methods": {m: s.describe() for m, s in src_methods.items()}},
        "methods": {},
        "_probes": probes_desc,
    }
    for m in bundle.methods:
        axes = method_axes(records[m], xis=opts.xis, boundary=boundaries[m] if opts.boundary else None)
        scene["methods"][m] = {"axes": axes, "views": [r.to_dict() for r in records[m]], "pictures": pictures[m]}
    return scene, len(views)


def _fingerprint(bundle, src_pre, src_ref, src_methods) -> str:
    """The bundle's file fingerprint, or for scenes built from objects a hash
    of the sources' descriptions and the target masks."""
    from .bundle import SourceSpec

    specs = [bundle.pre, bundle.reference, *bundle.methods.values()]
    if all(s is None or isinstance(s, SourceSpec) for s in specs) and not any(
            isinstance(m, np.ndarray) for m in bundle.masks.values()):
        return bundle.fingerprint()
    h = hashlib.sha256()
    for s in [src_pre, src_ref, *src_methods.values()]:
        h.update(json.dumps(None if s is None else s.describe(), sort_keys=True, default=str).encode())
    for v in bundle.views:
        m = bundle.masks[v]
        h.update(np.ascontiguousarray(m).tobytes() if isinstance(m, np.ndarray) else str(m).encode())
    return h.hexdigest()


def scene_from_objects(name: str, prompt: str, masks: dict, pre, methods: dict, *, reference=None,
                       cameras: dict | None = None, background=(0.0, 0.0, 0.0), depth: str = "expected",
                       reference_free: bool = False):
    """A scene to pass to :func:`evaluate` without files.

    masks: {view: bool (H, W) target mask}; the keys are the evaluation views.
    pre, reference, methods[...]: each a :class:`~r360gpu.io.Gaussians`
        (rendered here at ``cameras``), a
        :class:`~r360gpu.render.sources.DeviceViewsSource` (renders another
        GPU pipeline already holds on the device), or a bundle ``SourceSpec``.
    cameras: {view: Camera}, needed when any source is rendered here.
    """
    from .bundle import Bundle, BundleOptions

    views = sorted(masks)
    if not views:
        raise InputError(f"scene {name!r}: no views (masks is empty)")
    if not methods:
        raise InputError(f"scene {name!r}: no methods")
    missing = [v for v in views if cameras is not None and v not in cameras]
    if missing:
        raise InputError(f"scene {name!r}: views without a camera: {missing[:5]}")
    return Bundle(root=Path("."), name=name, prompt=prompt, views=views,
                  cameras=None if cameras is None else {v: cameras[v] for v in views},
                  masks={v: np.asarray(masks[v]) for v in views}, pre=pre, reference=reference,
                  methods=dict(methods),
                  options=BundleOptions(background=tuple(background), depth=depth, reference_free=reference_free),
                  layout="objects")


def _progress(views, name, enabled):
    if not enabled:
        return views
    from tqdm import tqdm

    return tqdm(views, desc=f"scoring {name}", unit="view", dynamic_ncols=True, leave=True)


def _load_cell(view_cache, method, view):
    p = view_cache / method / f"{view}.json"
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None  # a damaged cache entry is recomputed


def _collect(cell, records, boundaries, pictures, view):
    from .metrics.record import ViewRecord

    records.append(ViewRecord.from_dict(cell["record"]))
    boundaries.append(cell.get("boundary"))
    if cell.get("picture"):
        pictures[view] = cell["picture"]


def _probe_views(view, images, rendering, method=None):
    from .probes.base import ProbeView

    return [ProbeView(name=view, image=images.rgb, rendering=rendering, method=method)]


def _score_view(bundle, v, camera, mask, src_pre, src_ref, src_methods, sem, stru, mode, lpips, opts, ctx, timer,
                out, probes_desc):
    from .metrics.fidelity import fidelity_view
    from .metrics.geometric import GhtParams, acc_depth_view
    from .metrics.record import ViewRecord
    from .metrics.semantic import semantic_view
    from .metrics.sensitivity import NOT_GIVEN, BoundaryInput, boundary_sensitivity
    from .metrics.structural import structural_view

    t = time.perf_counter()
    pre = src_pre.images(v, camera)
    ref = src_ref.images(v, camera) if src_ref is not None else None
    t = timer.add("render", t)
    for img, what in ((pre, "pre"), (ref, "reference")):
        if img is not None and img.rgb.shape[:2] != mask.shape:
            raise InputError(f"view {v}: the {what} rendering is {img.rgb.shape[1]}x{img.rgb.shape[0]} "
                             f"but the target mask is {mask.shape[1]}x{mask.shape[0]} (W x H)")
    prompt = bundle.prompt
    sem_pre = {p.name: p.predict(_probe_views(v, pre, "pre"), prompt)[0] for p in sem}
    if mode == "reference":
        str_first = {p.name: p.predict(_probe_views(v, ref, "ref"))[0] for p in stru}
    else:
        str_pre = {p.name: p.predict(_probe_views(v, pre, "pre"))[0] for p in stru}
    t = timer.add("probe", t)
    ght = GhtParams(**opts.ght)
    cells = {}
    for m, src in src_methods.items():
        post = src.images(v, camera)
        t = timer.add("render", t)
        if post.rgb.shape[:2] != mask.shape:
            raise InputError(f"view {v}: method {m}'s rendering is {post.rgb.shape[1]}x{post.rgb.shape[0]} "
                             f"but the target mask is {mask.shape[1]}x{mask.shape[0]} (W x H)")
        sem_post = {p.name: p.predict(_probe_views(v, post, "post", m), prompt)[0] for p in sem}
        str_post = {p.name: p.predict(_probe_views(v, post, "post", m))[0] for p in stru}
        t = timer.add("probe", t)
        sem_views = [semantic_view(sem_pre[p.name], sem_post[p.name], mask, view=v, ctx=ctx) for p in sem]
        if mode == "reference":
            pairs = {p.name: (str_post[p.name], str_first[p.name]) for p in stru}
        else:
            pairs = {p.name: (str_pre[p.name], str_post[p.name]) for p in stru}
        str_views = [structural_view(a, b, mask, mode=mode, view=v, ctx=ctx) for a, b in pairs.values()]
        geo = None
        if pre.depth is not None and post.depth is not None:
            geo = acc_depth_view(pre.depth, post.depth, mask, compat=opts.compat, ght_params=ght, ctx=ctx)
        fid = fidelity_view(post.rgb, ref.rgb, lpips) if ref is not None else None
        record = ViewRecord.build(v, bundle.name, m, probes=probes_desc["semantic"] + probes_desc["structural"],
                                  semantic=sem_views, structural=str_views, geometric=geo, fidelity=fid)
        boundary = None
        if opts.boundary and sem and stru:
            p0s, p0t = sem[0].name, stru[0].name
            a, b = pairs[p0t]
            table = boundary_sensitivity(
                [BoundaryInput(mask, pred_pre=sem_pre[p0s], pred_post=sem_post[p0s], masks_a=a, masks_b=b,
                               geometric=geo if geo is not None else NOT_GIVEN, view=v)],
                geometric=geo is not None, structural_mode=mode, xis=opts.xis, compat=opts.compat,
                ght_params=ght, ctx=ctx,
            )
            boundary = {row: table.row(row) for row in table.rows}
        t = timer.add("measure", t)
        picture = None
        if out is not None and opts.pictures:
            first = sem[0].name if sem else None
            structural = []
            if stru:
                a, b = pairs[stru[0].name]
                other = ("I_ref", ref) if mode == "reference" else ("I_pre", pre)
                names = (("I_post", post), other) if mode == "reference" else (other, ("I_post", post))
                structural = [(f"{stru[0].name} on {n}", img.rgb, ms) for (n, img), ms in zip(names, (a, b))]
            picture = _write_picture(
                out, bundle.name, m, v, pre, post, ref, mask, geo, opts.compat,
                semantic=(sem_pre[first], sem_post[first]) if first else None, structural=structural,
            )
            t = timer.add("pictures", t)
        cells[m] = {"record": record.to_dict(), "boundary": boundary, "picture": picture}
    return cells


def _write_picture(out, scene, method, view, pre, post, ref, mask, geo, compat, *, semantic, structural):
    """The per-view contact sheet; returns its path relative to ``out``."""
    from .metrics.compat import compat_quantise, depth_delta
    from .report.pictures import view_contact_sheet

    from .render.sources import host_depth

    delta = threshold = changed = None
    if geo is not None:
        delta = depth_delta(host_depth(pre.depth), host_depth(post.depth))
        changed, threshold = geo.changed, geo.threshold
        if compat:  # the heat map then shows the 8-bit gray levels the threshold applies to
            delta = compat_quantise(delta)
    rel = Path("pictures") / scene / method / f"{view}.png"
    view_contact_sheet(
        out / rel, title=f"{scene} / {method} / {view}", pre=pre.rgb, post=post.rgb, target=mask,
        ref=None if ref is None else ref.rgb, delta=delta, threshold=threshold, changed=changed,
        semantic_pre=None if semantic is None else semantic[0].union(),
        semantic_post=None if semantic is None else semantic[1].union(),
        structural=[(t, rgb, ms.masks) for t, rgb, ms in structural],
    )
    return rel.as_posix()
