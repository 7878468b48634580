"""Inception pool3 features for FID / KID from an ONNX export of pytorch-fid's network.

The export contract (what ``bench/export_inpaint_models.py`` writes): pytorch-fid's
``InceptionV3([3])`` (``resize_input=True``, ``normalize_input=True``, the FID Inception
weights) exported whole, so the graph holds pytorch-fid's own preprocessing:

* one input ``(N, 3, H, W)`` float32, RGB in [0, 1], as ``torchvision``'s ``to_tensor``
  makes it from an 8-bit image (the value / 255);
* inside the graph: bilinear resize to 299 x 299 (``F.interpolate``,
  ``align_corners=False``, no antialiasing), ``2 x - 1``, the Inception blocks up to
  the pool3 average pool;
* one output ``(N, 2048)`` or ``(N, 2048, 1, 1)``: the pool3 features.

Exported with dynamic ``H, W`` (``dynamic_axes``), each image is fed at its own size and
the graph resizes it, as pytorch-fid does.  An export whose input is fixed at 299 x 299
(``torch.onnx.export`` without ``dynamic_axes``, traced on a 299 x 299 dummy) is fed
images that we resize first with the same bilinear rule
(`r360gpu.probes.preprocess.resize_logits`, equal to ``F.interpolate(...,
align_corners=False)``); the graph's own resize is then the identity.  Any other fixed
size, a second input or a wrong feature count is an InputError naming the file.  A
fixed batch size of 1 is run image by image; otherwise up to ``batch_size`` images of
one size go in one run (pytorch-fid: 50).

Features are returned as float64, as pytorch-fid stores its float32 activations.
"""
from __future__ import annotations

import os
from collections.abc import Iterable

import numpy as np

from ..errors import InputError
from .onnx_models import OnnxModel, TensorInfo
from .preprocess import resize_logits

#: Features per image: Inception's pool3 (pytorch-fid ``--dims 2048``, the 360-USID script's).
FID_DIMS = 2048
#: The side pytorch-fid's ``InceptionV3`` resizes every image to.
FID_INPUT_SIDE = 299
#: pytorch-fid's ``calculate_fid_given_paths`` batch size in the 360-USID script.
FID_BATCH = 50

_ROLE = "Inception feature model"


def image_tensor(image, what: str = "image") -> np.ndarray:
    """float32 (3, H, W) in [0, 1] from an RGB (H, W, 3) image, as ``to_tensor`` makes it.

    uint8 is divided by 255 in float32 (``to_tensor``'s ``div(255)``); float input must
    already lie in [0, 1].  Other shapes, integer types or values: InputError naming ``what``.
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"{what} must be an RGB (H, W, 3) array, got shape {arr.shape}")
    if arr.dtype == np.uint8:
        x = arr.astype(np.float32) / np.float32(255.0)
    elif arr.dtype.kind == "f":
        x = arr.astype(np.float32)
        if not np.isfinite(x).all():
            raise InputError(f"{what} has NaN or infinite values")
        if x.min() < 0.0 or x.max() > 1.0:
            raise InputError(f"{what} has values in [{x.min():.6g}, {x.max():.6g}], outside [0, 1]")
    else:
        raise InputError(f"{what} must be uint8 (0..255) or float (0..1), got {arr.dtype}")
    return np.ascontiguousarray(x.transpose(2, 0, 1))


class InceptionModel:
    """pytorch-fid's Inception network in ONNX form (see the module docstring for the contract).

    path: the ``.onnx`` file; device: the execution provider, as the learned probes'
    (``--probe-device``, `r360gpu.probes.providers`).
    """

    def __init__(self, path: str | os.PathLike, device: str = "cpu"):
        self.model = OnnxModel(path, device, role=_ROLE)
        self.path = self.model.path
        if len(self.model.inputs) != 1:
            self._refuse(f"needs one image input, this model has {len(self.model.inputs)}")
        inp: TensorInfo = next(iter(self.model.inputs.values()))
        if len(inp.shape) != 4 or inp.fixed(1) not in (None, 3):
            self._refuse(f"input {inp} is not (N, 3, H, W)")
        if "float" not in inp.type or "16" in inp.type:
            self._refuse(f"input {inp} is not float32 (the images in [0, 1])")
        h, w = inp.fixed(2), inp.fixed(3)
        if (h is None) != (w is None) or (h is not None and (h, w) != (FID_INPUT_SIDE, FID_INPUT_SIDE)):
            self._refuse(
                f"input {inp} has a fixed size other than {FID_INPUT_SIDE} x {FID_INPUT_SIDE}: export with "
                f"dynamic H and W so the graph resizes as pytorch-fid does"
            )
        self.input_name = inp.name
        #: True when the graph takes any size (and resizes itself), False for a fixed 299 x 299 input.
        self.any_size = h is None
        if inp.fixed(0) not in (None, 1):
            self._refuse(f"input {inp} fixes the batch at {inp.fixed(0)}: export with a dynamic batch or a batch of 1")
        self.batch_limit = inp.fixed(0)
        out = next(iter(self.model.outputs.values()))
        if len(out.shape) not in (2, 4) or out.fixed(1) not in (None, FID_DIMS) or any(
            out.fixed(a) not in (None, 1) for a in range(2, len(out.shape))
        ):
            self._refuse(f"output {out} is not (N, {FID_DIMS}) or (N, {FID_DIMS}, 1, 1) pool3 features")
        self.output_name = out.name

    def _refuse(self, problem: str):
        raise InputError(f"not a pytorch-fid Inception export: {problem} ({self.model.signature()})", self.path)

    @property
    def file_name(self) -> str:
        return self.path.name

    @property
    def provider(self) -> str:
        return self.model.provider

    def describe(self) -> dict:
        """{"file", "sha256", "input", "output", "resize", "provider"} for the results."""
        return {
            "file": self.file_name,
            "sha256": self.model.digests()[self.file_name],
            "input": str(self.model.inputs[self.input_name]),
            "output": str(self.model.outputs[self.output_name]),
            "resize": "in the model" if self.any_size else "bilinear to 299 x 299 before the model",
            "provider": self.provider,
        }

    def features(self, images: Iterable, batch_size: int = FID_BATCH, what: str = "image") -> np.ndarray:
        """(N, 2048) float64 pool3 features of RGB (H, W, 3) images (uint8, or float in [0, 1]).

        Consecutive images of one size share a run of up to ``batch_size`` images (1 when
        the model fixes its batch to 1); images may differ in size.  what: names the
        images in errors (``what[i]`` is given as ``f"{what} {i}"``).
        """
        if batch_size < 1:
            raise InputError(f"batch_size must be at least 1, got {batch_size}")
        limit = batch_size if self.batch_limit is None else min(batch_size, self.batch_limit)
        rows: list[np.ndarray] = []
        batch: list[np.ndarray] = []
        for i, image in enumerate(images):
            x = image_tensor(image, f"{what} {i}")
            if not self.any_size and x.shape[1:] != (FID_INPUT_SIDE, FID_INPUT_SIDE):
                x = resize_logits(x, (FID_INPUT_SIDE, FID_INPUT_SIDE))
            if batch and (x.shape != batch[0].shape or len(batch) == limit):
                rows.append(self._run(batch))
                batch = []
            batch.append(x)
        if batch:
            rows.append(self._run(batch))
        if not rows:
            return np.empty((0, FID_DIMS), np.float64)
        return np.concatenate(rows, axis=0)

    def _run(self, batch: list[np.ndarray]) -> np.ndarray:
        x = np.stack(batch)
        out = np.asarray(self.model.run({self.input_name: x}, [self.output_name])[self.output_name])
        if out.shape[0] != x.shape[0] or out[0].size != FID_DIMS:
            raise InputError(
                f"the {_ROLE} returned {out.shape} for {x.shape[0]} image(s); expected ({x.shape[0]}, {FID_DIMS})",
                self.path,
            )
        feats = out.reshape(x.shape[0], FID_DIMS).astype(np.float64)
        if not np.isfinite(feats).all():
            raise InputError(f"the {_ROLE} returned non-finite features", self.path)
        return feats
