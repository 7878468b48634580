"""A public Remove360 folder scored the way the public scripts score it (``--compat`` modes).

The public evaluation (github.com/simonakocour/anything_left, commit dd0aad8:
``remove360/evaluation/{semantic,depth,sam}.py``, their ``summarize_*``
functions and ``scripts/evaluate_sam.py``) reads its inputs from the scene
folder itself, so this module does too, with the same decoders:

* semantic: views = ``masks/*.png`` (sorted); ``masks/V.png``,
  ``gsam2/before/mask/V.png`` and ``gsam2/after/mask/V.png`` read with
  ``cv2.imread(IMREAD_GRAYSCALE)`` (a missing GSAM2 file is an all-zero
  mask), all three resized to the largest height and width among them with
  torch ``"nearest"`` and binarised ``> 0``.  ``IoU = |A∩B| / |A∪B|``, 0 when
  the union is empty, so a view with an empty target has IoU_pre = IoU_post = 0:
  counted as "not detected" in acc_seg and as IoU_drop 0 in the mean.
  Scene: ``acc_seg@xi`` = fraction of ALL views with ``IoU_post < xi``,
  ``iou_drop`` = mean over all views (and mean IoU_pre, IoU_post).
* geometric: views = ``depth/before/*.png`` (suffix compared lower-case)
  that have a same-named file in ``depth/after/``, sorted, whether or not a
  target mask exists.  The changed mask is :func:`~r360gpu.metrics.compat.public_changed`
  on :func:`~r360gpu.metrics.compat.read_depth_public` depths; a size
  different from the target's is resized with torch ``"nearest-exact"``.
  ``acc_depth = |changed ∩ M| / |M|`` with ``M = masks/V.png > 0``
  (IMREAD_GRAYSCALE), 0 when M is empty or missing.  Scene: the mean.
* structural: SAM records of ``masks/`` (``merged.json`` or ``*.json``,
  the scripts' "GT": SAM on the captured ``images/before``) against
  ``sam/after/``; per GT view that also has SAM output and a ``masks/V``
  or ``masks/V.png``: the target read with PIL ``convert("L") > 128``, each
  record's ``"mask"`` (else ``"segmentation"``) resized with
  ``cv2.INTER_NEAREST`` and kept when its IoU with the target is >= 0.1;
  a view where either side keeps nothing is not reported; else Hungarian
  matching (scipy) and ``sim = sum of matched IoU > 0 / max(N, M)``.
  Scene: the mean over reported views (None when there is none, as when
  either folder has no SAM JSON: the script then prints an error).

Everything is a pure function of the files; nothing is written.
"""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError, R360Warning
from ..protocol import RETAIN_IOU, XI_PUBLIC
from .compat import check_compat, public_changed, public_delta, read_depth_public
from .geometric import GhtParams

SEMANTIC_DIRS = {"pre": "gsam2/before/mask", "post": "gsam2/after/mask"}
SAM_DIRS = {"gt": "masks", "post": "sam/after"}
DEPTH_DIRS = {"pre": "depth/before", "post": "depth/after"}


# --- readers, as the scripts read ------------------------------------------------------------

def read_gray(path: str | os.PathLike) -> np.ndarray | None:
    """``cv2.imread(path, IMREAD_GRAYSCALE)``: uint8 (H, W), None when the file
    does not exist (the scripts' "missing"); an undecodable file is an InputError."""
    path = os.fspath(path)
    if not os.path.exists(path):
        return None
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError("cannot decode image (cv2.imread with IMREAD_GRAYSCALE, as the public scripts read masks)", path)
    return img


def read_binary_pil(path: str | os.PathLike, threshold: int = 128) -> np.ndarray:
    """``Image.open(path).convert("L") > threshold`` as uint8 0/1 (the SAM evaluation's target)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return (np.array(im.convert("L")) > threshold).astype(np.uint8)
    except (OSError, UnidentifiedImageError, ValueError) as e:
        raise InputError(f"cannot read mask: {e}", path) from None


def _load_json(path: Path):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise InputError(f"cannot read SAM JSON: {e}", path) from None


def load_sam_dir(directory: str | os.PathLike) -> dict:
    """``merged.json`` when present, else ``{stem: records}`` of every ``*.json``
    (the scripts' ``load_sam_data``); {} for a missing folder."""
    d = Path(directory)
    if not d.is_dir():
        return {}
    merged = d / "merged.json"
    if merged.exists():
        data = _load_json(merged)
        if not isinstance(data, dict):
            raise InputError("merged.json must map image names to SAM record lists", merged)
        return data
    return {p.stem: _load_json(p) for p in sorted(d.glob("*.json"))}


# --- torch's nearest-neighbour index rules (CPU upsample_nearest2d) --------------------------

def _nearest_index(out_size: int, in_size: int, exact: bool) -> np.ndarray:
    dst = np.arange(out_size)
    if out_size == in_size:
        return dst
    if not exact and out_size == 2 * in_size:
        return dst >> 1
    scale = np.float32(np.float32(in_size) / np.float32(out_size))
    if exact:
        src = np.floor(((dst + 0.5) * np.float64(scale)).astype(np.float32))
    else:
        src = np.floor(dst.astype(np.float32) * scale)
    return np.minimum(src.astype(np.int64), in_size - 1)


def resize_torch_nearest(img: np.ndarray, size: tuple[int, int], *, exact: bool = False) -> np.ndarray:
    """``F.interpolate(t[None, None].float(), size, mode="nearest"|"nearest-exact")`` on a 2-D array."""
    h, w = size
    if img.shape == (h, w):
        return img
    rows = _nearest_index(h, img.shape[0], exact)
    cols = _nearest_index(w, img.shape[1], exact)
    return img[rows[:, None], cols[None, :]]


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a > 0, b > 0
    union = int(np.logical_or(a, b).sum())
    return int(np.logical_and(a, b).sum()) / union if union > 0 else 0.0


# --- per view ---------------------------------------------------------------------------------

def semantic_view_public(ref: np.ndarray, before: np.ndarray | None, after: np.ndarray | None) -> dict:
    """IoU_pre, IoU_post, IoU_drop of one view from grey masks (None = missing file)."""
    before = np.zeros_like(ref) if before is None else before
    after = np.zeros_like(ref) if after is None else after
    h = max(m.shape[0] for m in (ref, before, after))
    w = max(m.shape[1] for m in (ref, before, after))
    r, b, a = (resize_torch_nearest(m, (h, w)) > 0 for m in (ref, before, after))
    iou_pre, iou_post = _iou(r, b), _iou(r, a)
    return {"iou_pre": iou_pre, "iou_post": iou_post, "iou_drop": float(iou_pre - iou_post),
            "empty_target": not bool(r.any())}


def depth_view_public(d_pre: np.ndarray, d_post: np.ndarray, ref: np.ndarray | None, mode: str,
                      ght: GhtParams = GhtParams()) -> dict:
    """acc_depth (and IoU, GHT gray threshold) of one view from uint8 depths and a grey target
    (None = no mask file: scored against an empty target, i.e. 0)."""
    res = public_changed(public_delta(d_pre, d_post), mode, **ght.as_dict())
    # The evaluation reads the saved mask (0 = changed, 255 = unchanged) and resizes it.
    saved = np.where(res.changed, np.uint8(0), np.uint8(255))
    if ref is None:
        ref = np.zeros_like(saved)
    changed = resize_torch_nearest(saved, ref.shape, exact=True) != 255
    m = ref > 0
    n_mask = int(m.sum())
    n_in = int((changed & m).sum())
    return {"acc_depth": n_in / n_mask if n_mask > 0 else 0.0, "iou": _iou(m, changed),
            "threshold": float(res.threshold), "n_mask": n_mask, "n_changed_in_mask": n_in,
            "empty_target": n_mask == 0}


def _kept(records, target: np.ndarray, where: str) -> list[np.ndarray]:
    h, w = target.shape
    t = target.astype(bool)
    out = []
    if not isinstance(records, list):
        raise InputError(f"{where}: SAM output must be a list of records")
    for seg in records:
        if not isinstance(seg, dict):
            raise InputError(f"{where}: SAM record is not an object")
        raw = seg.get("mask") if "mask" in seg else seg.get("segmentation")
        if raw is None:
            continue
        arr = np.array(raw)
        if arr.ndim != 2 or arr.dtype == object or arr.size == 0:
            raise InputError(f"{where}: the public scripts read SAM masks as nested 0/1 lists; got "
                             f"{'an RLE or other object' if arr.dtype == object or arr.ndim != 2 else 'an empty list'}")
        m = cv2.resize(arr.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
        union = int((m | t).sum())
        iou = int((m & t).sum()) / union if union > 0 else 0.0
        if iou >= RETAIN_IOU:
            out.append(m)
    return out


def sam_view_public(gt_records, post_records, target: np.ndarray, where: str = "") -> dict:
    """sim_SAM of one view, or ``{"reported": False}`` when either side keeps no mask."""
    from scipy.optimize import linear_sum_assignment

    a = _kept(gt_records, target, where)
    b = _kept(post_records, target, where)
    if not a or not b:
        return {"reported": False, "n_gt": len(a), "n_sam": len(b), "sim_sam": None}
    iou = np.zeros((len(a), len(b)))
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            union = (x | y).sum()
            iou[i, j] = float((x & y).sum() / union) if union != 0 else 0.0
    rows, cols = linear_sum_assignment(-iou)
    total = 0.0
    for i, j in zip(rows, cols):
        if iou[i, j] > 0:
            total += iou[i, j]
    return {"reported": True, "n_gt": len(a), "n_sam": len(b), "sim_sam": float(total / max(len(a), len(b)))}


# --- a folder ---------------------------------------------------------------------------------

def evaluate_public_folder(root: str | os.PathLike, compat="public", *, xis=XI_PUBLIC,
                           ght: GhtParams = GhtParams()) -> dict:
    """Per-view and scene values of one public-layout scene folder, as the scripts compute them.

    Returns ``{"mode", "views": {axis: {view: {...}}}, "scene": {...}, "notes": [...]}`` where
    ``scene`` has ``acc_seg`` ({xi: value}), ``s_sem`` (acc_seg@0.3), ``iou_pre``, ``iou_post``,
    ``iou_drop``, ``s_geo`` (mean acc_depth), ``sim_sam`` and ``s_str`` (mean sim_SAM over the
    reported views) and the view counts per axis; a value is None when its script prints nothing.
    """
    mode = check_compat(compat)
    if mode is None:
        raise InputError("evaluate_public_folder needs a compat mode ('public' or 'public-default')")
    root = Path(root)
    masks = root / "masks"
    notes: list[str] = []
    views: dict = {"semantic": {}, "geometric": {}, "structural": {}}

    if not masks.is_dir():
        raise InputError("the public scripts need a masks/ folder", masks)
    for d in SEMANTIC_DIRS.values():
        if not (root / d).is_dir():
            notes.append(f"{d}/ is missing: the public semantic script scores every view's mask there as empty")
    for p in sorted(x for x in os.listdir(masks) if x.endswith(".png")):
        ref = read_gray(masks / p)
        if ref is None:
            continue
        name = p[: -len(".png")]
        views["semantic"][name] = semantic_view_public(
            ref, read_gray(root / SEMANTIC_DIRS["pre"] / p), read_gray(root / SEMANTIC_DIRS["post"] / p))

    before, after = root / DEPTH_DIRS["pre"], root / DEPTH_DIRS["post"]
    if before.is_dir() and after.is_dir():
        after_names = {f.name for f in after.iterdir() if f.suffix.lower() == ".png"}
        for f in sorted(f for f in before.iterdir() if f.suffix.lower() == ".png"):
            if f.name not in after_names:
                continue
            d_pre, d_post = read_depth_public(f), read_depth_public(after / f.name)
            if d_pre.shape != d_post.shape:
                raise InputError(f"depth/before is {d_pre.shape[1]}x{d_pre.shape[0]} but depth/after is "
                                 f"{d_post.shape[1]}x{d_post.shape[0]}: the public depth script cannot subtract them",
                                 after / f.name)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", R360Warning)
                views["geometric"][f.stem] = depth_view_public(d_pre, d_post, read_gray(masks / f"{f.stem}.png"), mode, ght)
    else:
        notes.append("depth/before/ or depth/after/ is missing: the public depth script scores nothing")

    gt, post = load_sam_dir(root / SAM_DIRS["gt"]), load_sam_dir(root / SAM_DIRS["post"])
    if not gt or not post:
        notes.append("no SAM JSON in masks/ or sam/after/: the public SAM script stops with an error, no sim_SAM")
    else:
        for name, records in gt.items():
            if name not in post:
                continue
            target = masks / name
            if not target.exists():
                target = masks / f"{name}.png"
            if not target.exists():
                continue
            views["structural"][name] = sam_view_public(records, post[name], read_binary_pil(target), str(target))

    sem = list(views["semantic"].values())
    geo = [v["acc_depth"] for v in views["geometric"].values()]
    sims = [v["sim_sam"] for v in views["structural"].values() if v["reported"]]
    mean = lambda xs: float(np.mean(xs)) if xs else None  # noqa: E731
    acc_seg = {f"{x:g}": (sum(1 for v in sem if v["iou_post"] < x) / len(sem) if sem else None) for x in xis}
    scene = {
        "acc_seg": acc_seg,
        "s_sem": sum(1 for v in sem if v["iou_post"] < 0.30) / len(sem) if sem else None,
        "iou_pre": mean([v["iou_pre"] for v in sem]),
        "iou_post": mean([v["iou_post"] for v in sem]),
        "iou_drop": mean([v["iou_drop"] for v in sem]),
        "s_geo": mean(geo),
        "sim_sam": mean(sims),
        "s_str": mean(sims),
        "n_views": {"semantic": len(sem), "geometric": len(geo), "structural": len(sims),
                    "structural_not_reported": len(views["structural"]) - len(sims)},
    }
    return {"mode": mode, "views": views, "scene": scene, "notes": notes}
