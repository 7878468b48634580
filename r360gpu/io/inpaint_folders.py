"""The folders of the inpainting benchmarks, read as they are: 360-USID (AuraFusion360) and SPIn-NeRF.

**360-USID.**  A scene folder holds the photographs of the scene without the object in
``test_images/`` (the script globs ``test_images/*jpg``).  A method's output folder holds its
renders at those views in ``renders/`` (``renders/*png``) and may hold ``object_mask/``
(``*.png``); AuraFusion360's script takes the object masks from one fixed folder for every
method (``output/360-USID/{scene}/test/ours_30000/object_mask``, the masks rendered from the
reconstruction before removal), which ``--masks`` gives here.  Files are paired by their
position in natural sort order, as the script's ``natsorted`` does.

**SPIn-NeRF.**  Its data release has, per scene, ``images/`` (or ``images_N/``, downscaled
N times) with 100 photographs: the first 40 in sorted order are the test views, taken after the
object was removed, the other 60 the training views with the object; ``label/`` beside them holds
the object masks, one ``<photo stem>.png`` per photograph (1 = object).  SPIn-NeRF publishes no
evaluation script (SamsungLabs/SPIn-NeRF holds training code only), so the test split (first 40)
follows the data release and the later papers that score on it; ``--n-test`` changes it.  Masks
are taken from ``test_label/`` when the folder has one, else ``label/``, by the photograph's stem.

A method may be a splat scene instead of a folder of renders (`is_splat_method`): it is then
rendered at the test cameras, matched to the photographs by `r360gpu.io.photo_cameras`.

Images are read as the script reads them: PIL, ``.convert("RGB")``, divided by 255 (float32).
Mask files are read two ways: `read_mask_script` as PIL and torchvision's ``to_tensor``
make them (the script's values, compat mode), `read_mask_binary` by the project's rule
(any non-zero pixel is inside, `r360gpu.io.masks.load_mask`; default mode).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..util.warning_log import warn
from .masks import load_mask
from .paths import read_error

#: How many of a SPIn-NeRF scene's sorted photographs are test views.
SPINNERF_N_TEST = 40
_SPINNERF_EXTENSIONS = ("jpg", "JPG", "jpeg", "png")  # what SPIn-NeRF's loader takes
_DIGITS = re.compile(r"(\d+)")
# PIL modes whose samples are wider than 8 bits: convert("RGB") clips them.
_WIDE_MODES = ("I", "I;16", "I;16B", "I;16L", "I;16N", "F")


def natural_key(name: str) -> tuple:
    """Sort key of natural order (``view2`` before ``view10``), as ``natsort.natsorted`` orders names."""
    parts = _DIGITS.split(name)
    return tuple((0, int(p), "") if i % 2 else (1, 0, p) for i, p in enumerate(parts))


def natsorted_glob(folder: Path, suffix: str) -> list[Path]:
    """Files in ``folder`` whose name ends with ``suffix`` (the script's ``glob(folder/*suffix)``: no hidden
    files, case-sensitive), in natural order of their names."""
    return sorted((p for p in folder.iterdir() if p.name.endswith(suffix) and not p.name.startswith(".")
                   and p.is_file()), key=lambda p: natural_key(p.name))


def _open(path: Path, what: str):
    from PIL import Image, UnidentifiedImageError

    try:
        im = Image.open(path)
        im.load()
    except OSError as e:
        if isinstance(e, UnidentifiedImageError) or e.errno is None:
            raise InputError(f"cannot read {what}: not an image PIL can decode ({e})", path) from None
        raise read_error(e, path, what) from None
    except Exception as e:  # PIL raises ValueError/SyntaxError on some corrupt files
        raise InputError(f"cannot read {what}: {e}", path) from None
    return im


def read_image(path: str | os.PathLike, *, compat: bool = False) -> np.ndarray:
    """An image as the script reads it: (H, W, 3) float32 in [0, 1], PIL ``convert("RGB")`` / 255.

    An image with more than 8 bits per sample (16-bit PNG) loses them in ``convert("RGB")``; in
    default mode it is read at full depth (`r360gpu.io.renders.read_rgb`) instead, in compat
    mode as the script reads it, with a warning either way.
    """
    path = Path(path)
    im = _open(path, "image")
    if im.mode in _WIDE_MODES:
        if not compat:
            from .renders import read_rgb

            warn(f"{im.mode} image: read at full depth (the benchmark's script would clip it to 8 bits)", file=path)
            return read_rgb(path)
        warn(f"{im.mode} image: read as the script reads it, clipped to 8 bits by PIL's convert('RGB')", file=path)
    rgb = np.asarray(im.convert("RGB"), dtype=np.float32)
    return rgb / np.float32(255.0)


def read_mask_script(path: str | os.PathLike) -> np.ndarray:
    """The mask tensor the script builds (H, W) float64, before its ``> 0.5`` step: torchvision's
    ``to_tensor`` of the PIL image as it opens (8-bit modes / 255, mode ``1`` as 0/1, 16-bit PNG as
    int16, wrapping values above 32767, 32-bit integer and float modes unscaled).

    A mask with more than one channel is an InputError: the script's ``repeat(1, 3, 1, 1)`` then makes
    a mask of 3 x C channels and its masked PSNR fails with an IndexError.
    """
    path = Path(path)
    im = _open(path, "mask")
    bands = len(im.getbands())
    if bands != 1:
        raise InputError(f"mask in mode {im.mode} has {bands} channels; the benchmark's script fails on it "
                         f"(its masked PSNR raises an IndexError); save it as a one-channel PNG, or score "
                         f"without --compat, which reads any non-zero pixel as the object", path)
    if im.mode == "I;16" or im.mode.startswith("I;16"):
        return np.array(im, dtype=np.int16).astype(np.float64)  # to_tensor's np.int16: wraps above 32767
    if im.mode == "I":
        return np.array(im, dtype=np.int32).astype(np.float64)
    if im.mode == "F":
        return np.array(im, dtype=np.float32).astype(np.float64)
    a = np.array(im, dtype=np.uint8)
    if im.mode == "1":
        a = a * np.uint8(255)
    return (a.astype(np.float32) / np.float32(255.0)).astype(np.float64)


def read_mask_binary(path: str | os.PathLike, shape: tuple[int, int]) -> np.ndarray:
    """The mask by the project's rule (any non-zero pixel is the object) as 0/1 float64 (H, W).
    A mask of another size than ``shape`` is an InputError (the script fails on it too)."""
    from .masks import mask_size

    h, w = mask_size(path)
    if (h, w) != tuple(shape):
        raise InputError(f"mask is {w}x{h} but the photograph is {shape[1]}x{shape[0]}", path)
    return load_mask(path).astype(np.float64)


@dataclass
class MethodFiles:
    """One method's renders of a scene's test views, in view order, and the masks it is scored with.

    scene: the method's splat scene when it is given as one (``renders`` is then empty: the scene is
    rendered at the test cameras, `SceneFiles.cameras`)."""

    name: str
    folder: Path
    renders: list[Path]
    masks: list[Path] | None = None
    mask_folder: Path | None = None
    scene: Path | None = None


@dataclass
class SceneFiles:
    """A scene's test views (photograph names and files) and each method's files.

    cameras: one camera per photograph (`r360gpu.io.photo_cameras`) when a method is a splat
    scene, read from ``camera_set``; None otherwise."""

    name: str
    folder: Path
    photos: list[Path]
    methods: list[MethodFiles] = field(default_factory=list)
    cameras: list | None = None
    camera_set: Path | None = None

    @property
    def views(self) -> list[str]:
        return [p.name for p in self.photos]


def parse_method(spec: str) -> tuple[str, str]:
    """``NAME=FOLDER`` -> (NAME, FOLDER); FOLDER may hold ``{scene}``."""
    name, sep, folder = spec.partition("=")
    if not sep or not name.strip() or not folder.strip():
        raise InputError(f"a method is given as NAME=FOLDER, got {spec!r}")
    return name.strip(), folder


def _scene_folder(template: str, scene: str, several: bool) -> Path:
    """A per-scene folder: ``{scene}`` replaced when present, else FOLDER/scene when several scenes are scored."""
    if "{scene}" in template:
        return Path(template.replace("{scene}", scene))
    return Path(template) / scene if several else Path(template)


def is_splat_method(path: Path) -> bool:
    """Whether a method's path is a splat scene (a file, or an INRIA output folder without ``renders/``)
    rather than a folder of renders."""
    return path.is_file() or (path.is_dir() and (path / "point_cloud").is_dir() and not (path / "renders").is_dir())


def _method_path(template: str, name: str, scene: str, several: bool, n_scenes: int) -> Path:
    """A method's path in a scene; a splat file named without ``{scene}`` serves a lone scene as it is."""
    if "{scene}" not in template and is_splat_method(Path(template)):
        if n_scenes > 1:
            raise InputError(f"method {name!r} is one splat scene for {n_scenes} scenes; name one per scene "
                             f"with {{scene}} in its path", template)
        return Path(template)
    return _scene_folder(template, scene, several)


def _splat_method(name: str, path: Path, masks: list[Path] | None, mask_dir: Path | None) -> MethodFiles:
    from .load import latest_inria_iteration

    scene = latest_inria_iteration(path) if path.is_dir() else path
    return MethodFiles(name, path, [], masks, mask_dir, scene=scene)


def _with_cameras(scene: SceneFiles, cameras: str | None, several: bool, need: bool = False) -> SceneFiles:
    """The scene with its test cameras when a method is a splat scene (or ``need``): from ``cameras``
    ({scene} allowed) or the scene folder's own COLMAP model (``sparse/0``), else its LLFF
    ``poses_bounds.npy``."""
    if not need and not any(m.scene is not None for m in scene.methods):
        return scene
    from .photo_cameras import POSES_BOUNDS, photo_cameras

    where = _scene_folder(cameras, scene.name, several) if cameras is not None else scene.folder
    if cameras is None and not any((scene.folder / d).is_dir() for d in ("sparse/0", "sparse")) \
            and not (scene.folder / POSES_BOUNDS).is_file():
        splats = ", ".join(m.name for m in scene.methods if m.scene is not None)
        why = f"method(s) {splats} are splat scenes, rendered" if splats else "the lifted target is rendered"
        raise InputError(f"{why} at the test cameras, but the scene has no COLMAP model (sparse/0) or "
                         f"{POSES_BOUNDS}; give its cameras with --cameras", scene.folder)
    scene.cameras = photo_cameras(scene.photos, where)
    scene.camera_set = where
    return scene


def _need_dir(path: Path, what: str) -> Path:
    if not path.is_dir():
        raise InputError(f"no {what} folder here" if not path.exists() else f"{what} is not a folder", path)
    return path


def _scene_dirs(data: Path, marker: str, protocol: str) -> list[Path]:
    data = _need_dir(Path(data), "data")
    if (data / marker).is_dir():
        return [data]
    scenes = sorted((p for p in data.iterdir() if (p / marker).is_dir()), key=lambda p: natural_key(p.name))
    if not scenes:
        raise InputError(f"neither a {protocol} scene (no {marker}/ folder) nor a folder of scenes", data)
    return scenes


def _count_check(scene: str, photos: list[Path], photo_dir: Path, files: list[Path], folder: Path, what: str):
    if len(files) != len(photos):
        raise InputError(f"scene {scene}: {len(files)} {what} here but {len(photos)} photographs in {photo_dir} "
                         f"(files are paired by sorted position, so the counts must agree)", folder)


def usid_scenes(data: str | os.PathLike, methods: list[str], *, masks: str | None = None,
                cameras: str | None = None, need_cameras: bool = False) -> list[SceneFiles]:
    """The 360-USID scenes under ``data`` (a scene folder, or a folder of them) with each method's files.

    methods: ``NAME=FOLDER`` each, FOLDER holding ``renders/`` (and possibly ``object_mask/``), with
    ``{scene}`` standing for the scene's name, or, when several scenes are scored, holding one such
    folder per scene.  masks: a folder of ``*.png`` masks (``{scene}`` allowed) used for every method;
    without it a method's own ``object_mask/`` is used when it has one.  A FOLDER that is a splat scene
    (`is_splat_method`) is rendered at the test cameras: those of ``cameras`` ({scene} allowed), by
    default the scene's ``sparse/0``, matched to the photographs by name (also without a splat method
    when ``need_cameras``).
    """
    dirs = _scene_dirs(Path(data), "test_images", "360-USID")
    several = len(dirs) > 1 or not (Path(data) / "test_images").is_dir()
    parsed = [parse_method(m) for m in methods]
    _unique([n for n, _ in parsed])
    out = []
    for d in dirs:
        photo_dir = d / "test_images"
        photos = natsorted_glob(photo_dir, "jpg")
        if not photos:
            raise InputError("no *jpg photographs (the script globs test_images/*jpg)", photo_dir)
        scene = SceneFiles(d.name, d, photos)
        for name, template in parsed:
            path = _method_path(template, name, d.name, several, len(dirs))
            splat = is_splat_method(path)
            folder = path if splat else _need_dir(path, f"method {name!r} output")
            mask_dir = (_need_dir(_scene_folder(masks, d.name, several), "--masks") if masks is not None
                        else (folder / "object_mask" if (folder / "object_mask").is_dir() else None))
            mask_files = None
            if mask_dir is not None:
                mask_files = natsorted_glob(mask_dir, ".png")
                _count_check(d.name, photos, photo_dir, mask_files, mask_dir, "object masks (*.png)")
            if splat:
                scene.methods.append(_splat_method(name, path, mask_files, mask_dir))
                continue
            render_dir = _need_dir(folder / "renders", f"method {name!r} renders/")
            renders = natsorted_glob(render_dir, "png")
            _count_check(d.name, photos, photo_dir, renders, render_dir, "renders (*png)")
            scene.methods.append(MethodFiles(name, folder, renders, mask_files, mask_dir))
        out.append(_with_cameras(scene, cameras, several, need_cameras))
    return out


def spinnerf_scenes(data: str | os.PathLike, methods: list[str], *, masks: str | None = None,
                    factor: int | None = None, n_test: int = SPINNERF_N_TEST, cameras: str | None = None,
                    need_cameras: bool = False) -> list[SceneFiles]:
    """The SPIn-NeRF scenes under ``data`` (a scene folder with ``images/``, or a folder of them).

    The test views are the first ``n_test`` photographs of ``images/`` (``images_<factor>/``) in
    natural order.  methods: ``NAME=FOLDER`` as for `usid_scenes`, FOLDER holding the renders
    of the test views in ``renders/`` (or directly), ``*.png`` / ``*.jpg``.  masks: a folder of
    ``<photo stem>.png`` masks; without it ``test_label/`` or ``label/`` beside the photographs.
    A method given as a splat scene is rendered at the test cameras as in `usid_scenes` (the
    scene's COLMAP model ``sparse/0`` by default).
    """
    if n_test < 1:
        raise InputError(f"--n-test must be at least 1, got {n_test}")
    sub = "images" if factor is None else f"images_{factor}"
    dirs = _scene_dirs(Path(data), sub, "SPIn-NeRF")
    several = len(dirs) > 1 or not (Path(data) / sub).is_dir()
    parsed = [parse_method(m) for m in methods]
    _unique([n for n, _ in parsed])
    out = []
    for d in dirs:
        photo_dir = d / sub
        every = sorted((p for p in photo_dir.iterdir() if p.is_file() and p.name.endswith(_SPINNERF_EXTENSIONS)
                        and not p.name.startswith(".")), key=lambda p: natural_key(p.name))
        if len(every) < n_test:
            raise InputError(f"{len(every)} photographs, fewer than the {n_test} test views (--n-test)", photo_dir)
        photos = every[:n_test]
        scene = SceneFiles(d.name, d, photos)
        if masks is not None:
            mask_dir = _need_dir(_scene_folder(masks, d.name, several), "--masks")
        else:
            mask_dir = next((photo_dir / s for s in ("test_label", "label") if (photo_dir / s).is_dir()), None)
        mask_files = None
        if mask_dir is not None:
            mask_files = [mask_dir / (p.stem + ".png") for p in photos]
            for f in mask_files:
                if not f.is_file():
                    raise InputError(f"no mask for test view {f.stem} (masks are <photo stem>.png)", f)
        for name, template in parsed:
            path = _method_path(template, name, d.name, several, len(dirs))
            if is_splat_method(path):
                scene.methods.append(_splat_method(name, path, mask_files, mask_dir))
                continue
            folder = _need_dir(path, f"method {name!r} output")
            render_dir = folder / "renders" if (folder / "renders").is_dir() else folder
            renders = sorted((p for p in render_dir.iterdir() if p.is_file() and p.suffix.lower() in (".png", ".jpg")
                              and not p.name.startswith(".")), key=lambda p: natural_key(p.name))
            _count_check(d.name, photos, photo_dir, renders, render_dir, "renders (*.png, *.jpg)")
            scene.methods.append(MethodFiles(name, folder, renders, mask_files, mask_dir))
        out.append(_with_cameras(scene, cameras, several, need_cameras))
    return out


def _unique(names: list[str]) -> None:
    seen = set()
    for n in names:
        if n in seen:
            raise InputError(f"method {n!r} is given twice")
        seen.add(n)
