"""Semantic probe: GroundingDINO boxes, SAM / SAM2 masks (Grounded-SAM), on ONNX models.

GroundingDINO export (e.g. hpc203/GroundingDINO-onnxrun ``export_onnx.py``):
inputs ``img (1, 3, H, W)`` float, ``input_ids``, ``attention_mask``,
``position_ids``, ``token_type_ids`` (1, L) and ``text_token_mask``
(1, L, L) -> ``logits`` (1, Q, 256) raw text-token logits (Q queries, 900
for the released models) and ``boxes`` (1, Q, 4) normalised (cx, cy, w, h).
Integer / boolean inputs are cast to the element types the model declares.
The image is resized (antialiased bilinear) so its shorter side is
``size`` = 800 with the longer side at most ``max_size`` = 1333
(GroundingDINO's ``RandomResize([800], max_size=1333)``), or to a fixed
W x H with ``resize=1200x800`` (the size common GroundingDINO ONNX runtimes
use; see :class:`GroundingParams`) -- or, when the graph has a fixed input
height and width, to exactly that -- and normalised with the ImageNet
mean / std.

Text: the BERT tokenizer is read from a Hugging Face ``tokenizer.json``
(bert-base-uncased's) or a WordPiece ``vocab.txt`` with the optional
``tokenizers`` package.  Caption
rule: the prompt lower-cased and stripped, with " ." appended unless it
already ends with "." (GroundingDINO appends "."; BERT splits the period off
either way, so the tokens are the same).  ``position_ids`` and
``text_token_mask`` are GroundingDINO's "sub-sentence" encoding
(``generate_masks_with_special_tokens_and_transfer_map``, see
:func:`sub_sentence_masks`); sequences longer than ``max_text_len`` = 256
tokens are truncated.

Detection (GroundingDINO's ``predict``): scores = sigmoid(logits) in float32; a query
is kept when its highest token score is > ``box_threshold`` (0.35, compared in
float32 as torch does); its
phrase is the WordPiece decoding of the caption tokens whose score is >
``text_threshold`` (0.25) -- [CLS] and positions >= 255 excluded -- with
periods removed.  No box NMS (as Grounded-SAM-2).

Instances: with ``phrase_match`` (default) only detections whose phrase
equals one of the prompt's '.'-separated phrases are kept -- the rule the
public Remove360 conversion of Grounded-SAM-2 dumps applies
(:func:`r360gpu.probes.prompt_rule.label_matches`).  Each kept box (scaled
to pixels, cxcywh -> xyxy) prompts the SAM decoder as its two corners
(labels 2 and 3); the mask is the single-mask output (token 0 of a SAM
decoder, ``multimask_output=False`` as Grounded-SAM) or, for decoders
without it (samexporter's SAM2 decoder returns only the three multimask
outputs), the output with the highest predicted IoU; logits > 0.  The
semantic prediction is the union of the instances.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError, R360Error
from r360gpu.probes.base import ProbeView, SemanticPrediction, SemanticProbe
from r360gpu.probes.onnx_models import OnnxModel, SamModels
from r360gpu.probes.prompt_rule import PROMPT_RULE, label_matches
from r360gpu.probes.preprocess import as_rgb01, dino_encoder_input, dino_input_shape
from r360gpu.util.filehash import file_sha256

__all__ = [
    "GroundingParams",
    "SPECIAL_TOKENS",
    "caption_for",
    "sub_sentence_masks",
    "decode_wordpiece",
    "phrase_from_posmap",
    "cxcywh_to_xyxy",
    "select_detections",
    "text_inputs",
    "DinoTokenizer",
    "Detections",
    "GroundingDino",
    "GroundedSamProbe",
]

#: Tokens that delimit GroundingDINO's sub-sentences.
SPECIAL_TOKENS = ("[CLS]", "[SEP]", ".", "?")
_DINO_INPUTS = frozenset({"img", "input_ids", "attention_mask", "position_ids", "token_type_ids", "text_token_mask"})
_MASK_CHUNK = 16


@dataclass(frozen=True)
class GroundingParams:
    """GroundingDINO settings (defaults of Grounded-SAM-2's demos).

    box_threshold / text_threshold: on sigmoid token scores (0..1).
    size / max_size: image resize target in pixels (ignored for models with a
    fixed input size).  max_text_len: token limit of the text encoder.
    phrase_match: keep only detections whose phrase equals a prompt phrase.
    resize: the resize policy as text, overriding size / max_size:
    ``"S/M"`` keeps the aspect ratio, shorter side S, longer side at most M
    (GroundingDINO's ``RandomResize([800], max_size=1333)`` is ``"800/1333"``,
    the default); ``"WxH"`` resizes to exactly W x H pixels, aspect not kept,
    as common GroundingDINO ONNX runtimes do (``"1200x800"``; boxes are
    normalised to the image either way).  A graph with a fixed input size
    uses that size, and a fixed ``resize`` must agree with it.
    """

    box_threshold: float = 0.35
    text_threshold: float = 0.25
    size: int = 800
    max_size: int = 1333
    max_text_len: int = 256
    phrase_match: bool = True
    resize: str | None = None

    def __post_init__(self) -> None:
        for name in ("box_threshold", "text_threshold"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and not isinstance(value, bool) and 0.0 <= value <= 1.0):
                raise InputError(f"grounded probe: {name} must be in [0, 1], got {value!r}")
        for name in ("size", "max_size", "max_text_len"):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
                raise InputError(f"grounded probe: {name} must be a positive integer, got {value!r}")
        if self.max_size < self.size:
            raise InputError(f"grounded probe: max_size {self.max_size} is below size {self.size}")
        if not isinstance(self.phrase_match, bool):
            raise InputError(f"grounded probe: phrase_match must be true or false, got {self.phrase_match!r}")
        if self.resize is not None:
            self.resize_policy()

    def resize_policy(self) -> tuple[str, int, int]:
        """("aspect", shorter side, longest allowed) or ("fixed", height, width)."""
        if self.resize is None:
            return "aspect", self.size, self.max_size
        text = str(self.resize).strip().lower()
        for sep, kind in (("/", "aspect"), ("x", "fixed")):
            a, found, b = text.partition(sep)
            if found and a.strip().isdigit() and b.strip().isdigit() and int(a) >= 1 and int(b) >= 1:
                a, b = int(a), int(b)
                if kind == "aspect":
                    if b < a:
                        raise InputError(f"grounded probe: resize={self.resize!r}: the longest side {b} is below {a}")
                    return kind, a, b
                return kind, b, a  # written W x H
        raise InputError(
            f"grounded probe: resize={self.resize!r} is neither SHORT/MAX (e.g. 800/1333: shorter side 800, "
            "longer at most 1333) nor WxH (e.g. 1200x800: exactly 1200 wide, 800 high)"
        )


def caption_for(prompt: str) -> str:
    """GroundingDINO caption of a category prompt: lower-cased, stripped, ending with " ."."""
    caption = str(prompt).lower().strip()
    if not caption.strip(" ."):
        raise InputError(f"the category prompt {prompt!r} has no words")
    return caption if caption.endswith(".") else caption + " ."


def sub_sentence_masks(input_ids: np.ndarray, special_ids: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """GroundingDINO's sub-sentence attention mask and position ids for one caption.

    input_ids: int (L,).  special_ids: ids of :data:`SPECIAL_TOKENS`.
    Returns (bool (L, L), int64 (L,)).  Each run of tokens after a special
    token, up to and including the next special token, attends only within
    itself and is numbered 0, 1, ... from its first token; a special token
    at the first or last position attends to itself only, position 0; every
    token attends to itself.
    """
    ids = np.asarray(input_ids).reshape(-1)
    n = len(ids)
    is_special = np.isin(ids, np.asarray(list(special_ids), dtype=ids.dtype if ids.size else np.int64))
    mask = np.eye(n, dtype=bool)
    positions = np.zeros(n, np.int64)
    previous = 0
    for col in np.flatnonzero(is_special):
        col = int(col)
        if col == 0 or col == n - 1:
            mask[col, col] = True
            positions[col] = 0
        else:
            mask[previous + 1 : col + 1, previous + 1 : col + 1] = True
            positions[previous + 1 : col + 1] = np.arange(col - previous)
        previous = col
    return mask, positions


_CLEANUP = (
    (" .", "."),
    (" ?", "?"),
    (" !", "!"),
    (" ,", ","),
    (" ' ", "'"),
    (" n't", "n't"),
    (" 'm", "'m"),
    (" 's", "'s"),
    (" 've", "'ve"),
    (" 're", "'re"),
)


def decode_wordpiece(tokens: Sequence[str]) -> str:
    """Text of WordPiece tokens as Hugging Face's BERT tokenizer decodes it.

    Tokens are joined with spaces, "##" continuations glued to the previous
    token, then spaces before punctuation and English contractions removed
    (``clean_up_tokenization``).  Special tokens are kept.
    """
    text = ""
    for i, token in enumerate(tokens):
        if i and token.startswith("##"):
            text += token[2:]
        else:
            text += (" " if i else "") + token
    for dirty, clean in _CLEANUP:
        text = text.replace(dirty, clean)
    return text


def phrase_from_posmap(
    posmap: np.ndarray, input_ids: np.ndarray, id_to_token, left_idx: int = 0, right_idx: int = 255
) -> str:
    """Decoded caption tokens selected by a bool token map (GroundingDINO's
    ``get_phrases_from_posmap``): positions <= left_idx and >= right_idx are
    excluded; id_to_token maps an id to its token string."""
    pos = np.asarray(posmap, bool).copy().reshape(-1)
    pos[: left_idx + 1] = False
    pos[right_idx:] = False
    ids = np.asarray(input_ids).reshape(-1)
    picked = [int(ids[i]) for i in np.flatnonzero(pos) if i < len(ids)]
    return decode_wordpiece([id_to_token(i) for i in picked])


def cxcywh_to_xyxy(boxes: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """float64 (N, 4) pixel XYXY boxes from normalised (cx, cy, w, h) (N, 4) on an (H, W) image.

    Computed in float32 as Grounded-SAM-2 does (``boxes * Tensor([w, h, w, h])``,
    then ``box_convert`` cxcywh -> xyxy: centre -/+ 0.5 * size), so the prompt
    corners are the same numbers; returned as float64.
    """
    h, w = image_size
    b = np.asarray(boxes, np.float32).reshape(-1, 4) * np.array([w, h, w, h], np.float32)
    half = b[:, 2:] * np.float32(0.5)
    return np.concatenate([b[:, :2] - half, b[:, :2] + half], axis=1).astype(np.float64)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """float32 sigmoid, correctly rounded from float64 (torch's float32 sigmoid is within 1 ulp)."""
    x = np.asarray(x, np.float64)
    with np.errstate(over="ignore"):
        return (1.0 / (1.0 + np.exp(-x))).astype(np.float32)


@dataclass(frozen=True, eq=False)
class Detections:
    """GroundingDINO detections on one image.

    boxes: float64 (N, 4) XYXY in image pixels (not clipped).
    scores: float32 (N,) highest token score of each box.
    phrases: N strings (periods removed, not stripped: as Grounded-SAM-2 labels
        them; the prompt rule strips when matching).
    """

    boxes: np.ndarray
    scores: np.ndarray
    phrases: list[str]

    @property
    def count(self) -> int:
        return len(self.phrases)

    def take(self, keep: Sequence[int]) -> "Detections":
        """The detections at indices ``keep``, in that order."""
        keep = [int(i) for i in keep]
        return Detections(self.boxes[keep].reshape(-1, 4), self.scores[keep], [self.phrases[i] for i in keep])


def select_detections(
    logits: np.ndarray,
    boxes: np.ndarray,
    input_ids: np.ndarray,
    id_to_token,
    image_size: tuple[int, int],
    box_threshold: float = 0.35,
    text_threshold: float = 0.25,
) -> Detections:
    """GroundingDINO's ``predict`` post-processing for one image.

    logits: raw (Q, T) token logits; boxes: normalised cxcywh (Q, 4);
    input_ids: int (L,) caption tokens; image_size: (H, W) of the original
    image.  See the module docstring for the rule.
    """
    probs = _sigmoid(logits)
    best = probs.max(axis=1) if probs.shape[1] else np.zeros(len(probs), np.float32)
    # torch compares a float32 tensor with a Python float in float32: 0.35 is 0.35f there.
    keep = np.flatnonzero(best > np.float32(box_threshold))
    text_t = np.float32(text_threshold)
    phrases = [phrase_from_posmap(probs[q] > text_t, input_ids, id_to_token).replace(".", "") for q in keep]
    return Detections(cxcywh_to_xyxy(np.asarray(boxes)[keep], image_size), best[keep], phrases)


def require_tokenizers():
    """The ``tokenizers`` module, or an R360Error saying how to install it."""
    try:
        import tokenizers
    except ImportError:
        raise R360Error(
            "the grounded probe needs the 'tokenizers' package to read tokenizer.json; "
            "install it with: pip install 'r360gpu[models]' (or: pip install tokenizers)"
        ) from None
    return tokenizers


class DinoTokenizer:
    """The BERT tokenizer GroundingDINO uses, from either file it is shipped as.

    path: a Hugging Face ``tokenizer.json`` (bert-base-uncased's), or a BERT
    WordPiece ``vocab.txt`` (one token per line, the id is the line number),
    which common GroundingDINO ONNX runtimes ship; it is read through
    ``tokenizers.BertWordPieceTokenizer`` with bert-base-uncased's settings
    (lower-casing and accent stripping, [CLS] ... [SEP]).  The two are told
    apart by content: a tokenizer.json is a JSON object.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        tokenizers = require_tokenizers()
        if not self.path.is_file():
            raise InputError("tokenizer file does not exist", self.path)
        try:
            with open(self.path, "rb") as f:
                head = f.read(64).lstrip()
            if head.startswith(b"{"):
                self.format = "tokenizer.json"
                self._tok = tokenizers.Tokenizer.from_file(str(self.path))
            else:
                self.format = "vocab.txt"
                # read_file gives token -> line number; handing the path itself to
                # BertWordPieceTokenizer does not read it in every tokenizers release.
                vocab = tokenizers.models.WordPiece.read_file(str(self.path))
                self._tok = tokenizers.BertWordPieceTokenizer(vocab, lowercase=True)
        except Exception as exc:  # noqa: BLE001 - the Rust side raises a bare Exception
            raise InputError(
                f"cannot read the tokenizer ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
                "give a tokenizer.json or a BERT vocab.txt",
                self.path,
            ) from None
        self.cls_id = self._tok.token_to_id("[CLS]")
        self.sep_id = self._tok.token_to_id("[SEP]")
        if self.cls_id is None or self.sep_id is None:
            raise InputError("not a BERT tokenizer: the vocabulary lacks [CLS] or [SEP]", self.path)
        self.special_ids = [i for i in (self._tok.token_to_id(t) for t in SPECIAL_TOKENS) if i is not None]
        self._digest: str | None = None

    def encode(self, caption: str) -> np.ndarray:
        """int64 (L,) token ids of a caption, starting with [CLS] and ending with [SEP]."""
        ids = list(self._tok.encode(caption).ids)
        if not ids or ids[0] != self.cls_id:
            ids = [self.cls_id] + ids
        if ids[-1] != self.sep_id:
            ids = ids + [self.sep_id]
        return np.asarray(ids, np.int64)

    def id_to_token(self, token_id: int) -> str:
        """The token string of an id ("[UNK]" for an id outside the vocabulary)."""
        token = self._tok.id_to_token(int(token_id))
        return "[UNK]" if token is None else token

    def digest(self) -> str:
        """Hex SHA-256 of the tokenizer file (memoised)."""
        if self._digest is None:
            self._digest = file_sha256(self.path)
        return self._digest


def text_inputs(input_ids: np.ndarray, special_ids: Sequence[int], max_text_len: int = 256) -> dict[str, np.ndarray]:
    """The five text inputs of the GroundingDINO graph for one caption (batch 1).

    input_ids (1, L) int64, attention_mask (1, L) all true, token_type_ids
    (1, L) zeros, position_ids (1, L) and text_token_mask (1, L, L) from
    :func:`sub_sentence_masks`; everything cut to ``max_text_len`` tokens.
    """
    ids = np.asarray(input_ids, np.int64).reshape(-1)
    mask, positions = sub_sentence_masks(ids, special_ids)
    n = min(len(ids), int(max_text_len))
    return {
        "input_ids": ids[None, :n],
        "attention_mask": np.ones((1, n), bool),
        "token_type_ids": np.zeros((1, n), np.int64),
        "position_ids": positions[None, :n],
        "text_token_mask": mask[None, :n, :n],
    }


class GroundingDino:
    """A GroundingDINO ONNX model with its tokenizer (module docstring)."""

    def __init__(
        self,
        model: str | os.PathLike,
        tokenizer: str | os.PathLike,
        device: str = "cpu",
        params: GroundingParams | None = None,
    ):
        self.params = params or GroundingParams()
        self.tokenizer = DinoTokenizer(tokenizer)
        self.model = OnnxModel(model, device, "GroundingDINO model")
        names = set(self.model.inputs)
        if names != _DINO_INPUTS or not {"logits", "boxes"} <= set(self.model.outputs):
            raise InputError(
                f"not a supported GroundingDINO export: expected inputs {sorted(_DINO_INPUTS)} and outputs "
                f"'logits', 'boxes'; found {self.model.signature()}",
                self.model.path,
            )
        img = self.model.inputs["img"]
        if len(img.shape) != 4 or img.fixed(1) not in (None, 3):
            raise InputError(f"GroundingDINO image input must be (1, 3, H, W); found {img}", self.model.path)
        fixed = (img.fixed(2), img.fixed(3))
        self.fixed_input = fixed if None not in fixed else None
        kind, h, w = self.params.resize_policy()
        if kind == "fixed" and self.fixed_input is not None and self.fixed_input != (h, w):
            raise InputError(
                f"resize={self.params.resize} asks for {w}x{h} but the GroundingDINO graph takes exactly "
                f"{self.fixed_input[1]}x{self.fixed_input[0]} (W x H)",
                self.model.path,
            )

    def input_shape(self, height: int, width: int) -> tuple[int, int]:
        """(H', W') the image is resized to before the model."""
        if self.fixed_input is not None:
            return self.fixed_input
        kind, a, b = self.params.resize_policy()
        if kind == "fixed":
            return a, b
        return dino_input_shape(height, width, a, b)

    def detect(self, image, prompt: str) -> Detections:
        """Detections of ``prompt`` in one RGB (H, W, 3) image, uint8 0..255 or float 0..1."""
        image01 = as_rgb01(image)
        h, w = image01.shape[:2]
        ids = self.tokenizer.encode(caption_for(prompt))
        feeds = text_inputs(ids, self.tokenizer.special_ids, self.params.max_text_len)
        feeds["img"] = dino_encoder_input(image01, self.input_shape(h, w))
        out = self.model.run(feeds, ["logits", "boxes"])
        logits, boxes = np.asarray(out["logits"]), np.asarray(out["boxes"])
        if (
            logits.ndim != 3
            or boxes.ndim != 3
            or logits.shape[0] != 1
            or boxes.shape[:2] != (1, logits.shape[1])
            or boxes.shape[2] != 4
        ):
            raise InputError(
                f"GroundingDINO returned logits {logits.shape} and boxes {boxes.shape}; "
                "expected (1, Q, T) and (1, Q, 4)",
                self.model.path,
            )
        return select_detections(
            logits[0],
            boxes[0],
            feeds["input_ids"][0],
            self.tokenizer.id_to_token,
            (h, w),
            self.params.box_threshold,
            self.params.text_threshold,
        )


class GroundedSamProbe(SemanticProbe):
    """Semantic probe: GroundingDINO boxes -> SAM / SAM2 box-prompted masks.

    dino, tokenizer: the GroundingDINO ``.onnx`` and its ``tokenizer.json``.
    sam_encoder, sam_decoder: a SAM-family pair (see
    :mod:`r360gpu.probes.onnx_models`).  params: :class:`GroundingParams`.
    device: onnxruntime device.  name: probe name (default "grounded-sam" /
    "grounded-sam2").

    ``predict`` returns per view the kept instances (bool masks at the view
    size), their GroundingDINO scores and phrases.  Images: uint8 0..255 or
    float 0..1 RGB.
    """

    def __init__(
        self,
        dino: str | os.PathLike,
        tokenizer: str | os.PathLike,
        sam_encoder: str | os.PathLike,
        sam_decoder: str | os.PathLike,
        params: GroundingParams | None = None,
        device: str = "cpu",
        name: str | None = None,
    ):
        self.dino = GroundingDino(dino, tokenizer, device, params)
        self.sam = SamModels(sam_encoder, sam_decoder, device)
        self._name = name or ("grounded-sam2" if self.sam.variant == "sam2" else "grounded-sam")

    @property
    def name(self) -> str:
        return self._name

    @property
    def grounding(self) -> GroundingParams:
        return self.dino.params

    def params(self) -> dict:
        return {
            "model": "grounded-sam",
            "grounding": dataclasses.asdict(self.grounding),
            "dino_input": list(self.dino.fixed_input) if self.dino.fixed_input is not None else
            "shorter side {1}, longer at most {2}".format(*self.grounding.resize_policy())
            if self.grounding.resize_policy()[0] == "aspect" else
            "exactly {2}x{1} (W x H)".format(*self.grounding.resize_policy()),
            "dino_image_resize": "PIL bilinear on the uint8 image (GroundingDINO transforms)",
            "caption_rule": "lower-case, strip, append ' .' unless ending with '.'",
            "prompt_rule": PROMPT_RULE if self.grounding.phrase_match else "every detection",
            "sam": self.sam.describe_models(),
            "mask_selection": "single-mask token, else highest predicted IoU; logits > 0",
            "provider": self.sam.provider,
            "dino_provider": self.dino.model.provider,
        }

    def model_hashes(self) -> dict[str, str]:
        out = {f"dino:{k}": v for k, v in self.dino.model.digests().items()}
        out[f"tokenizer:{self.dino.tokenizer.path.name}"] = self.dino.tokenizer.digest()
        out.update({f"sam-{k}": v for k, v in self.sam.digests().items()})
        return out

    def predict(self, views: Sequence[ProbeView], prompt: str) -> list[SemanticPrediction]:
        """One SemanticPrediction per view, at the view's size."""
        caption_for(prompt)  # reject an empty prompt before any model runs
        out = []
        for view in views:
            if view.image is None:
                raise InputError(
                    f"probe {self.name!r} needs the rendered image of view {view.name!r}, and none was given"
                )
            image01 = as_rgb01(view.image, f"view {view.name!r} image")
            out.append(self.predict_image(image01, prompt))
        return out

    def predict_image(self, image, prompt: str) -> SemanticPrediction:
        """Instances of ``prompt`` in one RGB (H, W, 3) image, uint8 0..255 or float 0..1."""
        image01 = as_rgb01(image)
        h, w = image01.shape[:2]
        found = self.dino.detect(image01, prompt)
        if self.grounding.phrase_match:
            found = found.take([i for i, p in enumerate(found.phrases) if label_matches(p, prompt)])
        if found.count == 0:
            return SemanticPrediction.empty(h, w, self.name)
        embedding = self.sam.embed(image01)
        decoded = self.sam.predict_boxes(embedding, found.boxes)
        logits, _ = decoded.single()
        masks = np.empty((found.count, h, w), bool)
        for start in range(0, found.count, _MASK_CHUNK):
            chunk = self.sam.logits_to_image(embedding, logits[start : start + _MASK_CHUNK], decoded.low_res)
            masks[start : start + _MASK_CHUNK] = chunk > 0.0
        return SemanticPrediction(masks, found.scores, found.phrases, self.name)
