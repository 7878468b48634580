"""onnxruntime sessions for the model probes, and the SAM / SAM2 encoder-decoder pair.

Execution providers (``device``): ``"cpu"`` (default), ``"cuda"``,
``"tensorrt"``, ``"webgpu"``, ``"directml"``, ``"coreml"`` or ``"auto"``
(:mod:`r360gpu.probes.providers`: what auto takes, what happens when a
provider is missing or cannot start).  The CPU provider always backs the
chosen one for operators it lacks.

Supported SAM exports (detected from the models' input / output names and
shapes; anything else is an InputError listing what was found):

``sam`` -- SAM ViT-B/L/H and MobileSAM:

* encoder: one input, either ``(N, 3, S, S)`` float (segment-anything's
  ``export_onnx_model.py`` encoder ``x``, samexporter without
  ``--use-preprocess``, ...: we resize the longest side to S, normalise with
  SAM's pixel mean / std on 0..255 and zero-pad bottom / right), or
  ``(H, W, 3)`` float (samexporter ``--use-preprocess``, input
  ``input_image``: the graph normalises and pads; we feed the resized image
  on the 0..255 scale); output ``image_embeddings`` ``(1, 256, 64, 64)``.
* decoder (segment-anything ``SamOnnxModel``): inputs ``image_embeddings,
  point_coords (1, N, 2), point_labels (1, N), mask_input (1, 1, 256, 256),
  has_mask_input (1,), orig_im_size (2,)`` -> ``masks, iou_predictions,
  low_res_masks``.  Points are in the frame of the resized (longest side S)
  image.  Without ``--return-single-mask`` the decoder returns all four mask
  tokens (token 0 is the single-mask output, 1..3 the multimask outputs).
  We upscale ``low_res_masks`` ourselves (to S x S, drop the padding, resize
  to the image): the traced ``masks`` output can have the crop of the
  export's dummy image size baked in.  A decoder without ``low_res_masks``
  must return ``masks`` at ``orig_im_size``.  The point batch dimension is
  fixed to 1 in these exports, so prompts run one at a time unless the
  model declares it dynamic (export with ``dynamic_axes`` ``{0: "prompts",
  1: "num_points"}`` on ``point_coords`` and ``point_labels``, as
  bench/parity_sam.py's ``export_onnx(batched_decoder=True)``: the automatic
  mask generator then decodes ``points_per_batch`` prompts per run).  With
  the ``onnx`` package installed the decoder's ``masks`` branch is cut from
  the graph when ``low_res_masks`` exists (:func:`pruned_model_bytes`), and a
  batched decoder's prompt-independent work runs once per run
  (:class:`SamModels`, :mod:`r360gpu.probes.onnx_hoist`).

``sam2`` -- SAM 2 / 2.1 (samexporter ``export_sam2.py``, the
ONNX-SAM2-Segment-Anything notebook):

* encoder: input ``(1, 3, S, S)`` (plain resize to S x S, ImageNet mean /
  std on 0..1) -> ``high_res_feats_0, high_res_feats_1, image_embed``.
* decoder: inputs ``image_embed, high_res_feats_0, high_res_feats_1,
  point_coords (B, N, 2), point_labels (B, N), mask_input (B, 1, 256, 256),
  has_mask_input`` and optionally ``orig_im_size`` -> ``masks,
  iou_predictions``.  Points are in the S x S frame (x / W * S, y / H * S);
  the graph appends SAM2's padding point itself.  ``masks`` are 256 x 256
  logits (upsampled bilinearly to the image here) or, with
  ``orig_im_size``, already at the image size.  samexporter's decoder
  returns the three multimask outputs.

Model hashes (``describe()``) cover the ``.onnx`` file and any external-data
files it names (large encoders keep their weights beside the graph).
"""

from __future__ import annotations

import hashlib
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np

from r360gpu.errors import InputError
from r360gpu.util.filehash import file_sha256
from r360gpu.probes.preprocess import (
    as_rgb01,
    resize_logits,
    sam2_encoder_input,
    sam_encoder_input,
    sam_logits_to_image,
    sam_resized_image,
)
from r360gpu.probes.providers import DEVICES, available_providers, open_session, plan, providers_for, started

__all__ = [
    "DEVICES",
    "available_providers",
    "providers_for",
    "TensorInfo",
    "OnnxModel",
    "external_data_files",
    "pruned_model_bytes",
    "SamEmbedding",
    "Decoded",
    "SamModels",
    "EMBEDDINGS",
]

_NP_TYPES = {
    "tensor(float)": np.float32,
    "tensor(float16)": np.float16,
    "tensor(double)": np.float64,
    "tensor(int64)": np.int64,
    "tensor(int32)": np.int32,
    "tensor(bool)": np.bool_,
}

_SAM_DECODER_INPUTS = frozenset(
    {"image_embeddings", "point_coords", "point_labels", "mask_input", "has_mask_input", "orig_im_size"}
)
_SAM2_DECODER_INPUTS = frozenset(
    {
        "image_embed",
        "high_res_feats_0",
        "high_res_feats_1",
        "point_coords",
        "point_labels",
        "mask_input",
        "has_mask_input",
    }
)
_SAM2_FEATURES = ("image_embed", "high_res_feats_0", "high_res_feats_1")
# What SamModels reads from a SAM decoder that has low-resolution logits.
_SAM_DECODER_READS = ("iou_predictions", "low_res_masks")


@dataclass(frozen=True)
class TensorInfo:
    """One model input or output: name, shape (ints; str or None for dynamic axes), element type."""

    name: str
    shape: tuple
    type: str

    def __str__(self) -> str:
        dims = ", ".join("?" if d is None else str(d) for d in self.shape)
        return f"{self.name} {self.type.replace('tensor(', '').rstrip(')')}[{dims}]"

    def fixed(self, axis: int) -> int | None:
        """The size of ``axis`` when the model fixes it, else None."""
        if axis >= len(self.shape):
            return None
        dim = self.shape[axis]
        return int(dim) if isinstance(dim, (int, np.integer)) and int(dim) > 0 else None


_LOCATION_KEY = b"\x0a\x08location\x12"
_MAX_VARINT = 5  # bytes of a 32-bit length
_MAX_NAME = 4096  # longest external-data file name taken as one
_SCAN_BLOCK = 1 << 22  # bytes read at a time when scanning a model file


def external_data_files(path: str | os.PathLike) -> list[Path]:
    """External-data files an ONNX model names, resolved beside it, sorted, existing ones only.

    Scans the protobuf bytes for the ``location`` entries of external tensors
    (``key: "location"`` followed by the length-prefixed relative file name)
    without parsing the whole model.
    """
    path = Path(path)
    found: set[str] = set()
    tail = b""
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(_SCAN_BLOCK), b""):
            data = tail + block
            # A key cut by the block end is searched again, whole, with the next block.
            keep_from = max(len(data) - len(_LOCATION_KEY) - _MAX_VARINT, 0)
            start = 0
            while True:
                i = data.find(_LOCATION_KEY, start)
                if i < 0:
                    break
                j = i + len(_LOCATION_KEY)
                length, shift, complete = 0, 0, False
                while j < len(data) and shift < 7 * _MAX_VARINT:
                    byte = data[j]
                    length |= (byte & 0x7F) << shift
                    j += 1
                    shift += 7
                    if not byte & 0x80:
                        complete = True
                        break
                if complete and length > _MAX_NAME:
                    start = i + 1  # not a file name: some other bytes that happen to match
                    continue
                if not complete or j + length > len(data):
                    keep_from = min(keep_from, i)
                    break
                try:
                    found.add(data[j : j + length].decode("utf-8"))
                except UnicodeDecodeError:
                    pass
                start = j + length
            tail = data[keep_from:]
    out = []
    for name in sorted(found):
        candidate = path.parent / name
        if candidate.is_file():
            out.append(candidate)
    return out


def pruned_model_bytes(path: str | os.PathLike, outputs: tuple[str, ...]) -> bytes | None:
    """The model at ``path`` cut down to the nodes that ``outputs`` depend on, serialised; None
    when nothing would be cut, when a named output is missing, when the model keeps weights in
    external-data files, or when the ``onnx`` package is not installed.

    onnxruntime runs every node of a graph whatever outputs are asked for, so an output nobody
    reads still costs its full computation: segment-anything's SAM decoder upsamples every mask
    to 1024 x 1024 and then to the image size for its ``masks`` output, which the automatic mask
    generator never reads (it upsamples ``low_res_masks`` itself, for the masks it keeps).  Graph
    inputs are all kept (feeds stay the same); a node is kept when one of its outputs is needed,
    including names its subgraphs (If / Loop bodies) read from the enclosing graph.
    """
    try:
        import onnx
    except ImportError:
        return None
    try:
        model = onnx.load(str(path), load_external_data=False)
    except Exception:  # noqa: BLE001 - the session that follows reports an unloadable file
        return None
    graph = model.graph
    names = {o.name for o in graph.output}
    if not set(outputs) <= names or set(outputs) == names:
        return None
    if any(t.data_location == onnx.TensorProto.EXTERNAL for t in graph.initializer):
        return None
    needed = set(outputs)
    kept = []
    for node in reversed(graph.node):
        if any(o in needed for o in node.output):
            kept.append(node)
            needed.update(i for i in node.input if i)
            needed.update(_subgraph_reads(node))
    kept.reverse()
    del graph.node[:]
    graph.node.extend(kept)
    for field, keep in (
        (graph.output, lambda v: v.name in outputs),
        (graph.initializer, lambda t: t.name in needed),
        (graph.value_info, lambda v: v.name in needed),
    ):
        survivors = [v for v in field if keep(v)]
        del field[:]
        field.extend(survivors)
    return model.SerializeToString()


def _subgraph_reads(node) -> set[str]:
    """Names read by the subgraphs in ``node``'s attributes (at any depth)."""
    out: set[str] = set()
    for attr in node.attribute:
        for sub in list(attr.g.node if attr.HasField("g") else []) + [n for g in attr.graphs for n in g.node]:
            out.update(i for i in sub.input if i)
            out.update(_subgraph_reads(sub))
    return out


class OnnxModel:
    """One ONNX model file opened in an onnxruntime session.

    path: the ``.onnx`` file; device: see :func:`providers_for`; role: what
    the model is, for messages (e.g. "SAM image encoder").  A file that does
    not exist or that onnxruntime cannot load raises InputError naming it.
    outputs_read: the outputs the caller will ask for, when it never reads
    the others: the session then runs only the nodes those need (see
    :func:`pruned_model_bytes`; the whole graph where that returns None).
    ``outputs`` lists the outputs the session has.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        device: str = "cpu",
        role: str = "model",
        outputs_read: tuple[str, ...] | None = None,
    ):
        self.path = Path(path)
        self.role = role
        self.device = device
        self.outputs_read = None if outputs_read is None else tuple(outputs_read)
        if not self.path.is_file():
            raise InputError(f"{role} model file does not exist", self.path)
        self._plan = plan(device)
        #: The serialised graph the session runs when it is not the file's (a pruned copy), else None.
        self.model_bytes = None if self.outputs_read is None else pruned_model_bytes(self.path, self.outputs_read)
        try:
            self.session = self.open_session(self.model_bytes or str(self.path))
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises several unrelated types
            raise InputError(f"cannot load the {role} as an ONNX model ({_first_line(exc)})", self.path) from None
        self.provider = started(self.session, self._plan, self.path, role)
        self.inputs = {i.name: TensorInfo(i.name, tuple(i.shape), i.type) for i in self.session.get_inputs()}
        self.outputs = {o.name: TensorInfo(o.name, tuple(o.shape), o.type) for o in self.session.get_outputs()}
        self._digests: dict[str, str] | None = None

    def open_session(self, source: str | bytes):
        """An onnxruntime session on ``source`` (a path or a serialised model) with this model's
        providers and options."""
        import onnxruntime

        options = onnxruntime.SessionOptions()
        options.log_severity_level = 3
        return open_session(source, options, self._plan)

    def __reduce__(self):
        # A session cannot be pickled: another process (a Ray worker) opens the
        # same file again, so every node must see the model at this path.
        return (OnnxModel, (self.path, self.device, self.role, self.outputs_read))

    def signature(self) -> str:
        """ "inputs: ...; outputs: ..." with names, types and shapes (for error messages)."""
        ins = ", ".join(str(t) for t in self.inputs.values())
        outs = ", ".join(str(t) for t in self.outputs.values())
        return f"inputs: {ins}; outputs: {outs}"

    def cast(self, name: str, value) -> np.ndarray:
        """``value`` as a contiguous array of the element type the model declares for input ``name``."""
        dtype = _NP_TYPES.get(self.inputs[name].type)
        return np.ascontiguousarray(value if dtype is None else np.asarray(value).astype(dtype, copy=False))

    def run(self, feeds: dict[str, np.ndarray], outputs: list[str] | None = None) -> dict[str, np.ndarray]:
        """Run the model; returns output name -> array.

        Each feed is cast to the element type the model declares.  A failure
        inside onnxruntime (e.g. a shape the model does not accept) raises
        InputError naming the model file.
        """
        cast = {name: self.cast(name, value) for name, value in feeds.items()}
        names = list(self.outputs) if outputs is None else outputs
        try:
            values = self.session.run(names, cast)
        except Exception as exc:  # noqa: BLE001
            shapes = ", ".join(f"{k}{tuple(v.shape)}" for k, v in cast.items())
            raise InputError(
                f"the {self.role} failed to run on inputs {shapes} ({_first_line(exc)})", self.path
            ) from None
        return dict(zip(names, values))

    def digests(self) -> dict[str, str]:
        """File name -> SHA-256 of the model file and its external-data files (memoised)."""
        if self._digests is None:
            digests = {self.path.name: file_sha256(self.path)}
            for extra in external_data_files(self.path):
                digests[extra.name] = file_sha256(extra)
            self._digests = digests
        return dict(self._digests)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0][:500]


@dataclass(frozen=True, eq=False)
class SamEmbedding:
    """Encoder output for one image (or crop).

    features: decoder input name -> array (``image_embeddings`` for SAM;
    ``image_embed``, ``high_res_feats_0/1`` for SAM2).
    image_size: (H, W) of the encoded image, pixels.
    model_size: (H', W') of the image inside the model frame -- the resized,
    unpadded size for SAM, the full input size for SAM2.
    """

    features: dict
    image_size: tuple[int, int]
    model_size: tuple[int, int]


@dataclass(frozen=True, eq=False)
class Decoded:
    """Decoder output for B prompts.

    logits: float32 (B, M, h, w) mask logits; low-resolution (to be passed
    through :meth:`SamModels.logits_to_image`) when ``low_res`` is True, else
    already at the image size.  iou: float32 (B, M) predicted IoU.
    M is 4 (SAM decoders: single-mask token then the three multimask
    tokens), 3 (multimask tokens only) or 1 (a single-mask export).
    """

    logits: np.ndarray
    iou: np.ndarray
    low_res: bool

    @property
    def masks_per_prompt(self) -> int:
        return int(self.logits.shape[1])

    def multimask(self) -> tuple[np.ndarray, np.ndarray]:
        """(logits (B, M', h, w), iou (B, M')) of the multimask outputs
        (``multimask_output=True``): tokens 1..3 of a 4-token decoder, every
        output otherwise."""
        if self.masks_per_prompt == 4:
            return self.logits[:, 1:], self.iou[:, 1:]
        return self.logits, self.iou

    def single(self) -> tuple[np.ndarray, np.ndarray]:
        """(logits (B, h, w), iou (B,)) of one mask per prompt
        (``multimask_output=False``): token 0 of a 4-token decoder; with
        multimask-only decoders, the output with the highest predicted IoU."""
        if self.masks_per_prompt == 4:
            return self.logits[:, 0], self.iou[:, 0]
        best = np.argmax(self.iou, axis=1)
        rows = np.arange(self.logits.shape[0])
        return self.logits[rows, best], self.iou[rows, best]


class _EmbeddingMemo:
    """Encoder outputs of the last few images, shared by every SamModels in the process.

    A view's rendering goes through the structural probe (SAM automatic masks)
    and the semantic one (GroundingDINO boxes -> SAM); when both name the same
    SAM encoder file the second encode (seconds on a CPU) would recompute what
    the first returned.  Keyed by the encoder's identity (resolved path, size,
    modification time, execution provider) and the exact tensor fed to it
    (shape, dtype, BLAKE2b of its bytes), plus the image size the embedding
    describes: an entry is returned only for an input the encoder has already
    mapped to it.  Least recently used entries go first.
    """

    def __init__(self, capacity: int = 8):
        self.capacity = capacity
        self._store: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0

    @staticmethod
    def key(model: "OnnxModel", tensor: np.ndarray, image_size) -> tuple:
        st = model.path.stat()
        arr = np.ascontiguousarray(tensor)
        digest = hashlib.blake2b(arr.view(np.uint8).reshape(-1), digest_size=20).hexdigest()
        identity = (str(model.path.resolve()), st.st_size, st.st_mtime_ns, model.provider)
        return identity + (arr.shape, str(arr.dtype), digest, tuple(image_size))

    def get(self, key):
        with self._lock:
            found = self._store.get(key)
            if found is not None:
                self._store.move_to_end(key)
                self.hits += 1
            return found

    def put(self, key, value) -> None:
        with self._lock:
            self._store[key] = value
            self._store.move_to_end(key)
            while len(self._store) > self.capacity:
                self._store.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._store.clear()
            self.hits = 0


#: The process-wide memo of :meth:`SamModels.embed`.
EMBEDDINGS = _EmbeddingMemo()


class SamModels:
    """A SAM-family image encoder + prompt decoder pair (see module docstring).

    Attributes after loading: ``variant`` ("sam" or "sam2"),
    ``encoder_layout`` ("nchw": we preprocess; "hwc": preprocessing inside
    the encoder), ``input_size`` (H, W) of the model frame, ``batched``
    (whether the decoder takes several prompts per run), ``hoisted``
    (whether the decoder session runs the graph rewritten by
    :func:`r360gpu.probes.onnx_hoist.hoist_prompt_invariant`).

    The decoder session runs a rewrite of the file's graph, with the same
    outputs bit for bit: the ``masks`` branch cut when ``low_res_masks``
    exists (:func:`pruned_model_bytes`), and, for a decoder that takes a batch
    of prompts, the work that does not depend on the prompts (the first
    attention layer's projections of the repeated image embedding) done once
    per run instead of once per prompt.  The second is used only when the
    original and the rewritten graph give bit-identical outputs on random
    inputs of 1 and 3 prompts, checked when the models are opened
    (``hoist=False`` skips it).  Both need the ``onnx`` package.
    """

    def __init__(
        self, encoder: str | os.PathLike, decoder: str | os.PathLike, device: str = "cpu", hoist: bool = True
    ):
        self.encoder = OnnxModel(encoder, device, "SAM image encoder")
        # A SAM decoder's 'masks' output (every mask upsampled to the image, about half of a
        # one-point decoder run) is never read when it has 'low_res_masks': cut it out of the graph.
        reads = None if set(_SAM2_FEATURES) <= set(self.encoder.outputs) else _SAM_DECODER_READS
        self.decoder = OnnxModel(decoder, device, "SAM prompt decoder", outputs_read=reads)
        self.device = device
        self._detect()
        self.hoisted = hoist and self.batched and self._hoist()

    def __reduce__(self):
        # Another process (a Ray worker) opens the files again and redoes the checks.
        return (SamModels, (self.encoder.path, self.decoder.path, self.device, self.hoisted))

    def _hoist(self) -> bool:
        """Swap the decoder's session for one on the graph whose prompt-independent work runs once
        per run; True when done (the rewrite exists and its outputs are bit-identical to the
        original's at 1 and 3 prompts on random inputs), False when the original stays."""
        try:
            import onnx

            from r360gpu.probes.onnx_hoist import hoist_prompt_invariant, outputs_identical
        except ImportError:
            return False
        dec = self.decoder
        try:
            if dec.model_bytes is not None:
                model = onnx.load_from_string(dec.model_bytes)
            else:
                model = onnx.load(str(dec.path), load_external_data=False)
        except Exception:  # noqa: BLE001 - the session already opened it; nothing to rewrite
            return False
        if any(t.data_location == onnx.TensorProto.EXTERNAL for t in model.graph.initializer):
            return False
        rng = np.random.default_rng(0)
        checks = [self._check_feeds(rng, b) for b in (1, 3)]
        if checks[0] is None:
            return False
        wanted = self._decoder_outputs()
        # mask_input is fed zeros, the same in every row, when it takes one row per prompt.
        same_rows = ("mask_input",) if self._mask_input_batched else ()
        # Shapes from the batch-1 twins save the repeats themselves; when the check refuses
        # that, the rewrite that keeps the repeats for their Shape readers may still pass.
        for shapes_from_twins in (True, False):
            rewritten = hoist_prompt_invariant(model, ("point_coords", "point_labels"), same_rows, shapes_from_twins)
            if rewritten is None:
                return False
            data = rewritten.SerializeToString()
            try:
                session = dec.open_session(data)
            except Exception:  # noqa: BLE001 - onnxruntime raises several unrelated types
                continue
            if outputs_identical(lambda f: dec.session.run(wanted, f), lambda f: session.run(wanted, f), checks):
                dec.session, dec.model_bytes = session, data
                return True
        return False

    def _check_feeds(self, rng, b: int) -> dict | None:
        """Decoder feeds for ``b`` random point prompts on a random embedding, as :meth:`_decode`
        builds them; None when the decoder leaves a feature's size open."""
        features = {}
        for name in _SAM2_FEATURES if self.variant == "sam2" else ("image_embeddings",):
            info = self.decoder.inputs[name]
            shape = [info.fixed(axis) for axis in range(len(info.shape))]
            if None in shape:
                return None
            features[name] = rng.standard_normal(shape).astype(np.float32)
        h, w = self.input_size
        embedding = SamEmbedding(features, (h, w), (h, w))
        points = rng.uniform(0, 1, (b, 2)) * np.array([w, h])
        coords, labels = self._point_prompts(embedding, points)
        return {k: self.decoder.cast(k, v) for k, v in self._feeds(embedding, coords, labels).items()}

    # -- signature detection -------------------------------------------------
    def _reject(self, model: OnnxModel, why: str) -> NoReturn:
        raise InputError(
            f"not a supported SAM {model.role.split()[-1]} export: {why}; found {model.signature()}", model.path
        )

    def _detect(self) -> None:
        enc, dec = self.encoder, self.decoder
        enc_out = set(enc.outputs)
        if set(_SAM2_FEATURES) <= enc_out:
            variant = "sam2"
        elif "image_embeddings" in enc_out:
            variant = "sam"
        else:
            self._reject(
                enc,
                "expected outputs 'image_embeddings' (SAM, MobileSAM) or 'high_res_feats_0', "
                "'high_res_feats_1', 'image_embed' (SAM2)",
            )
        if len(enc.inputs) != 1:
            self._reject(enc, f"expected one image input, got {len(enc.inputs)}")
        image_in = next(iter(enc.inputs.values()))
        rank = len(image_in.shape)
        if rank == 4 and image_in.fixed(1) in (None, 3):
            layout = "nchw"
            size = (image_in.fixed(2) or 1024, image_in.fixed(3) or 1024)
        elif rank == 3 and variant == "sam" and image_in.fixed(2) in (None, 3):
            layout = "hwc"
            size = (1024, 1024)
        else:
            self._reject(enc, f"image input {image_in} is neither (N, 3, H, W) nor (for SAM) (H, W, 3)")
        if variant == "sam" and size[0] != size[1]:
            self._reject(enc, f"SAM encoders take a square input, got {size[0]}x{size[1]}")

        names = set(dec.inputs)
        if variant == "sam":
            if names != _SAM_DECODER_INPUTS:
                self._reject(dec, f"a SAM encoder needs a SAM decoder with inputs {sorted(_SAM_DECODER_INPUTS)}")
        else:
            if not (_SAM2_DECODER_INPUTS <= names <= _SAM2_DECODER_INPUTS | {"orig_im_size"}):
                self._reject(
                    dec,
                    f"a SAM2 encoder needs a SAM2 decoder with inputs {sorted(_SAM2_DECODER_INPUTS)} "
                    "(and optionally 'orig_im_size')",
                )
        for needed in ("masks" if "low_res_masks" not in dec.outputs else "low_res_masks", "iou_predictions"):
            if needed not in dec.outputs:
                self._reject(dec, f"the decoder has no output {needed!r}")
        self.variant = variant
        self.encoder_layout = layout
        self.input_size = (int(size[0]), int(size[1]))
        self.batched = dec.inputs["point_coords"].fixed(0) is None
        mask_in = dec.inputs["mask_input"]
        self._mask_input_size = (
            mask_in.fixed(2) or self.input_size[0] // 4,
            mask_in.fixed(3) or self.input_size[1] // 4,
        )
        self._mask_input_batched = mask_in.fixed(0) is None

    # -- public API ----------------------------------------------------------
    @property
    def provider(self) -> str:
        """The execution provider the encoder and decoder run on ("encoder: A, decoder: B" when
        one of them could not start the provider asked for and the other could)."""
        enc, dec = self.encoder.provider, self.decoder.provider
        return enc if enc == dec else f"encoder: {enc}, decoder: {dec}"

    def digests(self) -> dict[str, str]:
        """ "encoder:<file>" / "decoder:<file>" -> SHA-256 of every model file."""
        out = {f"encoder:{k}": v for k, v in self.encoder.digests().items()}
        out.update({f"decoder:{k}": v for k, v in self.decoder.digests().items()})
        return out

    def describe_models(self) -> dict:
        """Variant, layout and preprocessing facts for ``describe()`` (and so for probe-cache keys:
        a change of preprocessing must not reuse masks cached under the old one)."""
        resize = (
            "PIL bilinear on the uint8 image (segment-anything)"
            if self.variant == "sam"
            else "float32 antialiased bilinear (SAM2Transforms)"
        )
        return {
            "variant": self.variant,
            "encoder_layout": self.encoder_layout,
            "input_size": list(self.input_size),
            "image_resize": resize,
        }

    def embed(self, image) -> SamEmbedding:
        """Encode one RGB (H, W, 3) image, uint8 0..255 or float 0..1.

        The encoding is shared with every SamModels of this process on the same
        encoder file (:data:`EMBEDDINGS`): the same input is encoded once."""
        image01 = as_rgb01(image)
        h, w = image01.shape[:2]
        image_name = next(iter(self.encoder.inputs))
        if self.variant == "sam":
            if self.encoder_layout == "hwc":
                tensor = sam_resized_image(image01, self.input_size[0])
                model_size = tensor.shape[:2]
            else:
                tensor, model_size = sam_encoder_input(image01, self.input_size[0])
            wanted = ["image_embeddings"]
        else:
            tensor = sam2_encoder_input(image01, self.input_size)
            model_size = self.input_size
            wanted = list(_SAM2_FEATURES)
        key = EMBEDDINGS.key(self.encoder, tensor, (h, w))
        found = EMBEDDINGS.get(key)
        if found is not None:
            return found
        out = self.encoder.run({image_name: tensor}, wanted)
        embedding = SamEmbedding(out, (int(h), int(w)), (int(model_size[0]), int(model_size[1])))
        EMBEDDINGS.put(key, embedding)
        return embedding

    def to_model_coords(self, embedding: SamEmbedding, xy: np.ndarray) -> np.ndarray:
        """float32 (..., 2): image pixel (x, y) -> the decoder's coordinate frame.

        SAM: scaled by (W'/W, H'/H) in float64 into the resized image
        (``ResizeLongestSide.apply_coords``), rounded once to float32 (the
        decoder's input type).  SAM2: ``SAM2Transforms.transform_coords``
        (normalize=True) on its float32 tensor: x / W * S_w, y / H * S_h, each
        step rounded to float32.
        """
        h, w = embedding.image_size
        mh, mw = embedding.model_size
        if self.variant == "sam2":
            xy32 = np.asarray(xy, np.float64).astype(np.float32)
            return (xy32 / np.array([w, h], np.float32)) * np.array([mw, mh], np.float32)
        scale = np.array([mw / w, mh / h], np.float64)
        return (np.asarray(xy, np.float64) * scale).astype(np.float32)

    def predict_points(self, embedding: SamEmbedding, points_xy: np.ndarray) -> Decoded:
        """One positive point prompt per row of ``points_xy`` (B, 2) (image pixels)."""
        return self._decode(embedding, *self._point_prompts(embedding, points_xy))

    def _point_prompts(self, embedding: SamEmbedding, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(point_coords, point_labels) of one positive point per row of ``points_xy``."""
        pts = np.asarray(points_xy, np.float64).reshape(-1, 2)
        coords = self.to_model_coords(embedding, pts)[:, None, :]
        labels = np.ones((len(pts), 1), np.float32)
        if self.variant == "sam":
            # SAM's prompt encoder appends a "not a point" when no box is given;
            # SamOnnxModel leaves that to the caller.  SAM2 exports append it themselves.
            coords = np.concatenate([coords, np.zeros((len(pts), 1, 2), np.float32)], axis=1)
            labels = np.concatenate([labels, -np.ones((len(pts), 1), np.float32)], axis=1)
        return coords, labels

    def predict_boxes(self, embedding: SamEmbedding, boxes_xyxy: np.ndarray) -> Decoded:
        """One box prompt per row of ``boxes_xyxy`` (B, 4) (image pixels): the two
        corners with labels 2 (top-left) and 3 (bottom-right), no padding point."""
        boxes = np.asarray(boxes_xyxy, np.float64).reshape(-1, 2, 2)
        coords = self.to_model_coords(embedding, boxes)
        labels = np.tile(np.array([[2.0, 3.0]], np.float32), (len(boxes), 1))
        return self._decode(embedding, coords, labels)

    def logits_to_image(self, embedding: SamEmbedding, logits: np.ndarray, low_res: bool) -> np.ndarray:
        """float32 (K, H, W) mask logits at the image size from decoder logits (K, h, w)."""
        logits = np.asarray(logits, np.float32)
        if not low_res:
            return logits
        if self.variant == "sam":
            return sam_logits_to_image(logits, self.input_size[0], embedding.model_size, embedding.image_size)
        return resize_logits(logits, embedding.image_size)

    # -- decoding ------------------------------------------------------------
    def _decode(self, embedding: SamEmbedding, coords: np.ndarray, labels: np.ndarray) -> Decoded:
        b = coords.shape[0]
        if b == 0:
            raise ValueError("no prompts to decode")
        if self.batched:
            return self._decode_batch(embedding, coords, labels)
        parts = [self._decode_batch(embedding, coords[i : i + 1], labels[i : i + 1]) for i in range(b)]
        return Decoded(
            np.concatenate([p.logits for p in parts]), np.concatenate([p.iou for p in parts]), parts[0].low_res
        )

    def _feeds(self, embedding: SamEmbedding, coords: np.ndarray, labels: np.ndarray) -> dict:
        """Decoder inputs for the prompts (B, N, 2) / (B, N) on ``embedding``."""
        b = coords.shape[0]
        h, w = embedding.image_size
        feeds = dict(embedding.features)
        feeds["point_coords"] = coords
        feeds["point_labels"] = labels
        mh, mw = self._mask_input_size
        feeds["mask_input"] = np.zeros((b if self._mask_input_batched else 1, 1, mh, mw), np.float32)
        # Shape (1,): it broadcasts over any prompt batch in both export families.
        feeds["has_mask_input"] = np.zeros(1, np.float32)
        if "orig_im_size" in self.decoder.inputs:
            feeds["orig_im_size"] = np.array([h, w])
        return feeds

    def _decoder_outputs(self) -> list[str]:
        """The decoder outputs :meth:`_decode` reads."""
        if self.variant == "sam" and "low_res_masks" in self.decoder.outputs:
            return ["iou_predictions", "low_res_masks"]
        return ["masks", "iou_predictions"]

    def _decode_batch(self, embedding: SamEmbedding, coords: np.ndarray, labels: np.ndarray) -> Decoded:
        b = coords.shape[0]
        h, w = embedding.image_size
        out = self.decoder.run(self._feeds(embedding, coords, labels), self._decoder_outputs())
        iou = np.asarray(out["iou_predictions"], np.float32)
        low = out.get("low_res_masks")
        if low is not None:
            if low.ndim != 4:
                self._bad_output(f"'low_res_masks' of shape {low.shape} is not (B, M, h, w)")
            logits, low_res = low, True
        else:
            logits = out["masks"]
            if logits.ndim != 4:
                self._bad_output(f"'masks' of shape {logits.shape} is not (B, M, H, W)")
            full = logits.shape[2:] == (h, w)
            if self.variant == "sam" and not full:
                self._bad_output(
                    f"without 'low_res_masks', 'masks' must come at orig_im_size {h}x{w}, got "
                    f"{logits.shape[2]}x{logits.shape[3]}"
                )
            low_res = not full
        # Not clamped to +-32: SAM2ImagePredictor._predict upsamples the unclamped
        # logits and clamps only the low-res copy it returns for reuse as a mask input
        # (samexporter's SAM2 decoder clamps inside the graph; r360gpu takes what it gets).
        logits = np.asarray(logits, np.float32)
        if logits.shape[0] != b or iou.reshape(-1).size != logits.shape[0] * logits.shape[1]:
            self._bad_output(f"{b} prompts gave masks of shape {logits.shape} and iou_predictions of shape {iou.shape}")
        return Decoded(logits, iou.reshape(logits.shape[:2]), low_res)

    def _bad_output(self, why: str) -> NoReturn:
        raise InputError(
            f"unexpected SAM decoder output: {why}; the decoder is {self.decoder.signature()}", self.decoder.path
        )
