"""segment-anything's ``scripts/amg.py`` output (format ``sam-amg``): one folder per view holding
``metadata.csv`` and ``<id>.png`` per mask (its default, binary-mask mode)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError
from r360gpu.probes.base import MaskSet
from r360gpu.probes.mask_dirs import mask_dir, read_mask_png
from r360gpu.util.filehash import input_stamp

AMG_METADATA = "metadata.csv"
# Header of segment-anything's scripts/amg.py write_masks_to_folder (one row per mask <id>.png).
AMG_HEADER = ("id,area,bbox_x0,bbox_y0,bbox_w,bbox_h,point_input_x,point_input_y,predicted_iou,"
              "stability_score,crop_box_x0,crop_box_y0,crop_box_w,crop_box_h")


def is_amg_view_folder(folder: Path) -> bool:
    """A folder as segment-anything's ``scripts/amg.py`` writes per image: ``metadata.csv`` + ``<i>.png``."""
    return (folder / AMG_METADATA).is_file()


def is_amg_dir(directory: str | os.PathLike) -> bool:
    """A directory of amg.py output (one sub-folder per image holding ``metadata.csv``), without JSON files."""
    d = Path(directory)
    if not d.is_dir() or any(d.glob("*.json")):
        return False
    return any(p.is_dir() and is_amg_view_folder(p) for p in d.iterdir())


def read_amg_folder(folder: str | os.PathLike, probe: str = "") -> MaskSet:
    """The masks of one image as ``scripts/amg.py`` writes them (binary-mask mode): ``metadata.csv``
    (header :data:`AMG_HEADER`, one row per mask) and ``<id>.png`` per row; scores = predicted_iou."""
    folder = Path(folder)
    meta = folder / AMG_METADATA
    try:
        lines = [ln.strip() for ln in meta.read_text(encoding="utf-8").splitlines() if ln.strip()]
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", meta) from None
    except UnicodeDecodeError:
        raise InputError("not a text file (expected SAM amg.py metadata.csv)", meta) from None
    if not lines or lines[0] != AMG_HEADER:
        raise InputError(f"not SAM amg.py metadata (the first line must be {AMG_HEADER!r})", meta)
    cols = AMG_HEADER.split(",")
    i_id, i_iou = cols.index("id"), cols.index("predicted_iou")
    masks, scores = [], []
    for n, line in enumerate(lines[1:], start=2):
        row = line.split(",")
        if len(row) != len(cols):
            raise InputError(f"line {n} has {len(row)} fields, the header {len(cols)}", meta)
        try:
            mid, iou = int(row[i_id]), float(row[i_iou])
        except ValueError:
            raise InputError(f"line {n}: id must be an integer and predicted_iou a number", meta) from None
        png = folder / f"{mid}.png"
        if not png.is_file():
            raise InputError(f"mask {png.name} listed on line {n} of {AMG_METADATA} is missing", png)
        m = read_mask_png(png)
        if masks and m.shape != masks[0].shape:
            raise InputError(f"mask is {m.shape[1]}x{m.shape[0]}, {masks[0].shape[1]}x{masks[0].shape[0]} "
                             f"for the first mask of the folder", png)
        masks.append(m)
        scores.append(iou)
    if not masks:
        return MaskSet(np.zeros((0, 0, 0), bool), None, probe)
    return MaskSet(np.stack(masks), np.asarray(scores, np.float32), probe)


class SamAmgDir:
    """Directory of segment-anything ``scripts/amg.py`` output: ``<name>/metadata.csv`` and
    ``<name>/<i>.png`` per view (its default, binary-mask mode)."""

    format = "sam-amg"

    def __init__(self, directory: str | os.PathLike):
        self.directory = mask_dir(directory)

    def names(self) -> list[str]:
        return sorted(p.name for p in self.directory.iterdir() if p.is_dir() and is_amg_view_folder(p))

    def path_for(self, name: str) -> Path:
        return self.directory / name / AMG_METADATA

    def stamps(self, name: str) -> dict:
        """{path: :func:`~r360gpu.util.filehash.input_stamp`} of the view's folder and every file in it
        (what :meth:`read` may read)."""
        folder = self.directory / name
        out = {str(folder): input_stamp(folder)}
        if folder.is_dir():
            out.update({str(p): input_stamp(p) for p in sorted(folder.iterdir())})
        return out

    def read(self, name: str, probe: str = "") -> MaskSet | None:
        folder = self.directory / name
        if not folder.is_dir():
            return None
        if not is_amg_view_folder(folder):
            raise InputError(f"SAM amg.py folder of view {name!r} has no {AMG_METADATA}", folder)
        return read_amg_folder(folder, probe)


