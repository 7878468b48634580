"""Writing synthetic scenes as scene bundles (the ``scene.toml`` format of r360gpu).

One bundle folder per scene::

    <out>/<scene>/
        scene.toml              name, prompt, cameras, masks, [pre], [reference], [methods.*]
        synthetic.json          how it was made: seed, sizes, Gaussian counts, view kinds, methods
        cameras/                COLMAP binary model (cameras.bin, images.bin, points3D.bin)
          (or transforms.json beside scene.toml with camera_format="transforms")
        masks/<view>.png        target masks, 0 / 255
        pre.ply                 original reconstruction (INRIA 3DGS .ply)
        reference.ply           the scene without the target (hidden background present)
        methods/<method>.ply    one per simulated method (see r360gpu.synthetic.methods)

Every file is written atomically; ``scene.toml`` is written last (and
removed first when a bundle is regenerated), so a folder holding one is
complete.  The same arguments give byte-identical files on the same
machine; masks come from renders, so another adapter may differ in a few
boundary pixels.
"""
from __future__ import annotations

import json
import os
import sys
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np

from .. import __version__
from ..errors import InputError
from ..io import Gaussians, save_colmap, save_ply, save_transforms_json
from ..util.atomic import write_bytes, write_text
from .garden import make_garden, make_garden_open
from .masks import target_masks
from .methods import DEFAULT_METHODS, EXPECTED, METHODS
from .room import make_room
from .scene import SyntheticScene

#: Scene builders by name (``garden_open``, the bench in open space, only by name: the default
#: benchmark is room and garden).
SCENES: dict[str, Callable[..., SyntheticScene]] = {"room": make_room, "garden": make_garden,
                                                   "garden_open": make_garden_open}
CAMERA_FORMATS = ("colmap", "transforms")
#: Marker file of a synthetic bundle (a folder holding it may be overwritten).
MARKER = "synthetic.json"
#: Written after everything else: the generator's parameters and each file's size and SHA-256, so an
#: unchanged bundle is reused instead of regenerated (:func:`generate_benchmark`).


def _rng(*keys) -> np.random.Generator:
    """A generator seeded from the seed and names (stable across Python runs, unlike hash())."""
    words = [k if isinstance(k, int) else zlib.crc32(str(k).encode("utf-8")) for k in keys]
    return np.random.default_rng(np.random.SeedSequence(words))


def _check_seed(seed) -> None:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed!r}")


def _check_camera_format(camera_format) -> None:
    if camera_format not in CAMERA_FORMATS:
        raise InputError(f"camera_format must be one of {', '.join(CAMERA_FORMATS)}, got {camera_format!r}")


def _check_args(seed, n_views, width, height, detail) -> None:
    _check_seed(seed)
    if isinstance(n_views, bool) or not isinstance(n_views, (int, np.integer)) or n_views < 1:
        raise InputError(f"n_views must be a positive integer, got {n_views!r}")
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 16 <= v <= 8192:
            raise InputError(f"{name} must be an integer in 16..8192, got {v!r}")
    if isinstance(detail, bool) or not isinstance(detail, (int, float, np.floating)) \
            or not (np.isfinite(detail) and 0.01 <= detail <= 16):
        raise InputError(f"detail must be a number in 0.01..16, got {detail!r}")


def make_scene(name: str, *, seed: int = 0, n_views: int = 20, width: int = 480, height: int = 360,
               detail: float = 1.0) -> SyntheticScene:
    """Build scene ``name`` (see :data:`SCENES`) deterministically from ``seed``.

    detail scales the number of Gaussians (1.0: 50k-80k per scene; 0.25: a
    quarter, for tests).
    """
    if name not in SCENES:
        raise InputError(f"unknown synthetic scene {name!r}; known: {', '.join(SCENES)}")
    _check_args(seed, n_views, width, height, detail)
    return SCENES[name](_rng(int(seed), "scene", name), n_views=int(n_views), width=int(width),
                        height=int(height), detail=float(detail))


def make_method(scene: SyntheticScene, method: str, *, seed: int = 0) -> Gaussians:
    """The edited scene of simulated method ``method`` (see :data:`~r360gpu.synthetic.methods.METHODS`)."""
    if method not in METHODS:
        raise InputError(f"unknown synthetic method {method!r}; known: {', '.join(METHODS)}")
    return METHODS[method](scene, _rng(int(seed), "method", scene.name, method))


def encode_mask(mask: np.ndarray) -> bytes:
    """(H, W) bool mask -> 8-bit grey PNG bytes (target = 255)."""
    ok, buf = cv2.imencode(".png", np.where(np.asarray(mask, bool), 255, 0).astype(np.uint8))
    if not ok:
        raise RuntimeError("OpenCV could not encode a PNG")
    return buf.tobytes()


def _toml_str(s: str) -> str:
    # A JSON string of printable text is a valid TOML basic string.
    return json.dumps(s, ensure_ascii=True)


def scene_toml(scene: SyntheticScene, methods: Sequence[str], *, seed: int, cameras: str) -> str:
    """The text of the bundle's ``scene.toml`` (paths relative to the bundle folder)."""
    lines = [
        f"# Synthetic Remove360-style scene made by r360gpu.synthetic {__version__} (seed {seed}); "
        "details in synthetic.json.",
        f"name = {_toml_str(scene.name)}",
        f"prompt = {_toml_str(scene.prompt)}",
        f"cameras = {_toml_str(cameras)}",
        'masks = "masks"',
        "",
        "[pre]",
        'scene = "pre.ply"',
        "",
        "# The scene without the target, as a capture after the physical removal would give it.",
        "[reference]",
        'scene = "reference.ply"',
    ]
    for m in methods:
        doc = (METHODS[m].__doc__ or "").strip().splitlines()[0]
        lines += ["", f"# {m}: {doc}", f"[methods.{m}]", f"scene = {_toml_str(f'methods/{m}.ply')}"]
    lines += ["", "# The known failure of each simulated method and the axes that should catch it (the report",
              "# checks whether they did)."]
    for m in methods:
        failure, axes = EXPECTED[m]
        lines += ["", f"[expected.{m}]", f"failure = {_toml_str(failure)}",
                  "caught_by = [" + ", ".join(_toml_str(a) for a in axes) + "]"]
    return "\n".join(lines) + "\n"


def _prepare(folder: Path) -> None:
    """Make ``folder`` ready to (re)write a bundle into; refuse to touch foreign folders."""
    if folder.exists() and not folder.is_dir():
        raise InputError("exists and is not a folder", folder)
    if folder.is_dir() and any(folder.iterdir()) and not (folder / MARKER).is_file():
        raise InputError(f"folder is not empty and holds no {MARKER} (not a synthetic bundle); "
                         "refusing to overwrite it", folder)
    folder.mkdir(parents=True, exist_ok=True)
    # Gone first, written last: a half-regenerated folder is never taken for a bundle.
    (folder / "scene.toml").unlink(missing_ok=True)
    # Marked ours before anything is written, so a generation stopped half-way (Ctrl-C) is
    # regenerated by the next run, not refused as a foreign folder; the full marker comes last.
    write_text(folder / MARKER, json.dumps({"generator": "r360gpu.synthetic", "complete": False}) + "\n")


def _remove_stale(folder: Path, views: set[str], methods: set[str], camera_format: str) -> None:
    """Delete files of an earlier generation that this one did not write (only our own names)."""
    for p in (folder / "masks").glob("view_*.png"):
        if p.stem not in views:
            p.unlink()
    for p in (folder / "methods").glob("*.ply"):
        if p.stem not in methods:
            p.unlink()
    if camera_format == "colmap":
        (folder / "transforms.json").unlink(missing_ok=True)
    else:
        for f in ("cameras.bin", "images.bin", "points3D.bin"):
            (folder / "cameras" / f).unlink(missing_ok=True)
        if (folder / "cameras").is_dir() and not any((folder / "cameras").iterdir()):
            (folder / "cameras").rmdir()


def _sha256(path: Path) -> str:
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 22), b""):
            h.update(chunk)
    return h.hexdigest()


def _bundle_files(folder: Path) -> dict[str, str]:
    """{relative path: sha256} of the files a bundle is made of (not the marker, not scene.toml)."""
    return {p.relative_to(folder).as_posix(): _sha256(p) for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name not in (MARKER, "scene.toml") and not p.name.startswith(".")}


def reusable_bundle(folder: str | os.PathLike, request: dict) -> bool:
    """True when ``folder`` holds a complete synthetic bundle made for ``request`` whose files
    still have the contents they were written with (so regenerating would give the same bytes)."""
    folder = Path(folder)
    try:
        meta = json.loads((folder / MARKER).read_text(encoding="utf-8"))
        toml = (folder / "scene.toml").read_bytes()
    except (OSError, ValueError):
        return False
    import hashlib

    return (isinstance(meta, dict) and meta.get("request") == request
            and meta.get("scene_toml_sha256") == hashlib.sha256(toml).hexdigest()
            and meta.get("files") == _bundle_files(folder))


def _masks_of_files(scene: SyntheticScene, folder: Path, cameras: str, *, ctx, progress: bool, kept):
    """The target masks drawn from the bundle's own reference.ply and cameras, read back as scoring
    reads them (the file's Gaussians differ from the in-memory ones in the last bits of their scales and
    rotations), so that the masks belong to the files and the renders can serve scoring."""
    from ..io.load import load_cameras
    from ..render.sources import SceneSource

    reference = SceneSource(str(folder / "reference.ply"), ctx=ctx)
    try:
        return target_masks(scene, progress=progress, reference=reference, cameras=load_cameras(folder / cameras),
                            kept=kept)
    finally:
        reference.release()


def _write_methods(scene: SyntheticScene, folder: Path, methods: Sequence[str], seed: int) -> dict[str, int]:
    """Write every method's edited scene; their Gaussian counts by method."""
    counts = {}
    for m in methods:
        g = make_method(scene, m, seed=seed)
        save_ply(folder / "methods" / f"{m}.ply", g)
        counts[m] = g.n
    return counts


def write_bundle(scene: SyntheticScene, folder: str | os.PathLike, *, seed: int = 0,
                 methods: Sequence[str] | None = None, camera_format: str = "colmap", ctx=None,
                 progress: bool = False, request: dict | None = None, kept=None) -> Path:
    """Write ``scene`` as a bundle into ``folder`` (created; an earlier synthetic bundle there
    is replaced) and return the folder.

    seed: the seed of the method edits (use the scene's seed).  methods:
    names from :data:`~r360gpu.synthetic.methods.METHODS` (default:
    :data:`~r360gpu.synthetic.methods.DEFAULT_METHODS`, in that order).
    camera_format: "colmap" (``cameras/`` binary model) or
    "transforms" (``transforms.json``).  ctx: GPU context for the mask renders.
    request: the arguments the bundle was made from, recorded in the marker
    with the files' SHA-256 so :func:`reusable_bundle` can tell it is current.
    kept: a :class:`~r360gpu.render.kept.KeptRenders` that receives the
    reference renders the masks are drawn from, for scoring to use.
    """
    methods = list(DEFAULT_METHODS) if methods is None else list(methods)
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise InputError(f"unknown or no methods {unknown}; known: {', '.join(METHODS)}")
    _check_seed(seed)
    _check_camera_format(camera_format)
    folder = Path(folder)
    _prepare(folder)

    steps = ["cameras", "pre", "reference", "masks", *methods]
    bar = None
    if progress and sys.stderr.isatty():  # (a redrawn bar is noise in a log; the masks report their own lines)
        from tqdm import tqdm

        bar = tqdm(total=len(steps), desc=scene.name, unit="file", leave=False)

    def done(step: str) -> None:
        if bar is not None:
            bar.set_postfix_str(step)
            bar.update(1)

    try:
        if camera_format == "colmap":
            save_colmap(folder / "cameras", scene.cameras, binary=True)
            cameras = "cameras"
        else:
            save_transforms_json(folder / "transforms.json", scene.cameras)
            cameras = "transforms.json"
        done("cameras")
        save_ply(folder / "pre.ply", scene.pre)
        done("pre")
        save_ply(folder / "reference.ply", scene.background)
        done("reference")
        # the method edits are host work (numpy, k-d trees, file writing): made beside the mask renders
        with ThreadPoolExecutor(1, thread_name_prefix="r360-synthetic") as pool:
            edited = pool.submit(_write_methods, scene, folder, methods, seed)
            masks = _masks_of_files(scene, folder, cameras, ctx=ctx, progress=progress, kept=kept)
            for name, mask in masks.items():
                write_bytes(folder / "masks" / f"{name}.png", encode_mask(mask))
            done("masks")
            counts = edited.result()
        for m in methods:
            done(m)
    finally:
        if bar is not None:
            bar.close()

    _remove_stale(folder, set(masks), set(methods), camera_format)
    cam0 = scene.cameras[0]
    meta = {
        "generator": "r360gpu.synthetic",
        "r360gpu_version": __version__,
        "scene": scene.name,
        "prompt": scene.prompt,
        "seed": int(seed),
        "width": cam0.width,
        "height": cam0.height,
        "n_views": len(scene.cameras),
        "gaussians": {"pre": scene.pre.n, "reference": scene.background.n, "target": scene.target.n,
                      "hidden": int(scene.hidden.sum()), "neighbourhood": int(scene.in_neighbourhood().sum()),
                      "methods": counts},
        "view_kinds": dict(scene.view_kinds),
        "mask_pixels": {name: int(m.sum()) for name, m in masks.items()},
        "methods": {m: " ".join((METHODS[m].__doc__ or "").split()) for m in methods},
    }
    toml = scene_toml(scene, methods, seed=seed, cameras=cameras)
    if request is not None:
        import hashlib

        meta.update(request=request, files=_bundle_files(folder),
                    scene_toml_sha256=hashlib.sha256(toml.encode("utf-8")).hexdigest())
    write_text(folder / MARKER, json.dumps(meta, indent=2) + "\n")
    write_text(folder / "scene.toml", toml)
    return folder


def generate_benchmark(out_dir: str | os.PathLike, *, seed: int = 0, n_views: int = 20, width: int = 480,
                       height: int = 360, scenes: Sequence[str] = ("room", "garden"), detail: float = 1.0,
                       methods: Sequence[str] | None = None, camera_format: str = "colmap", ctx=None,
                       progress: bool = False, reuse: bool = False, reused: list | None = None,
                       kept=None) -> list[Path]:
    """Generate the built-in synthetic benchmark: one bundle per scene under ``out_dir``.

    Returns the bundle folders (``out_dir / scene``) in the order of
    ``scenes``.  See :func:`make_scene` for seed, n_views, width, height and
    detail, :func:`write_bundle` for methods, camera_format and ctx.
    reuse: keep a scene's bundle that was made with the same arguments and
    whose files are unchanged (checked by content) instead of writing it
    again; the names of the scenes kept are appended to ``reused``.
    kept: a :class:`~r360gpu.render.kept.KeptRenders` that receives the
    reference renders of the bundles written (not of those reused).
    """
    scenes = list(scenes)
    unknown = [s for s in scenes if s not in SCENES]
    if unknown or not scenes:
        raise InputError(f"unknown or no scenes {unknown}; known: {', '.join(SCENES)}")
    if len(set(scenes)) != len(scenes):
        raise InputError(f"scenes listed twice: {scenes}")
    _check_args(seed, n_views, width, height, detail)
    _check_camera_format(camera_format)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", out)
    from ..util.code_id import version_id

    # the code that generates and renders a scene is part of what it was made with
    requests = {name: {"r360gpu_version": version_id(), "scene": name, "seed": int(seed), "n_views": int(n_views),
                       "width": int(width), "height": int(height), "detail": float(detail),
                       "methods": list(METHODS) if methods is None else list(methods),
                       "camera_format": camera_format}
                for name in scenes}
    keep = {name for name in scenes if reuse and reusable_bundle(out / name, requests[name])}
    folders = []
    # the next scene is built (numpy) while this one's masks render
    with ThreadPoolExecutor(1, thread_name_prefix="r360-synthetic") as pool:
        made = {name: pool.submit(make_scene, name, seed=seed, n_views=n_views, width=width, height=height,
                                  detail=detail)
                for name in scenes if name not in keep}
        try:
            for name in scenes:
                if name in keep:
                    folders.append(out / name)
                    if reused is not None:
                        reused.append(name)
                    continue
                folders.append(write_bundle(made[name].result(), out / name, seed=seed, methods=methods,
                                            camera_format=camera_format, ctx=ctx, progress=progress,
                                            request=requests[name], kept=kept))
        finally:  # after a failure, scenes not started are not built
            for f in made.values():
                f.cancel()
    return folders

