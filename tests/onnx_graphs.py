"""Tiny stand-ins for the SAM / SAM2 / GroundingDINO ONNX exports, built with the onnx helper API.

The graphs have the real exports' input / output names and shapes and
produce known outputs: encoders that pool the preprocessed image (so the
preprocessing can be checked from the embedding), decoders whose mask logits
are disks around the prompt point or rectangles on the prompt box (so prompt
coordinates, token selection, upsampling and the AMG filters can be checked
from the masks), and a GroundingDINO graph with fixed logits / boxes.
Opset 17, IR version 8 (loadable by onnxruntime >= 1.14).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from r360gpu.probes.onnx_models import OnnxModel

F = TensorProto.FLOAT
I64 = TensorProto.INT64
B = TensorProto.BOOL

#: Vocabulary of the test tokenizer (ids are the positions).
VOCAB = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", ".", "?", "red", "sofa", "chair", "the", "##s"]


def write_tokenizer_json(path: Path) -> Path:
    """A BERT-style WordPiece tokenizer.json over :data:`VOCAB` (needs ``tokenizers``)."""
    from tokenizers import Tokenizer, decoders, models, normalizers, pre_tokenizers, processors

    vocab = {t: i for i, t in enumerate(VOCAB)}
    tok = Tokenizer(models.WordPiece(vocab, unk_token="[UNK]"))
    tok.normalizer = normalizers.BertNormalizer(lowercase=True)
    tok.pre_tokenizer = pre_tokenizers.BertPreTokenizer()
    tok.post_processor = processors.TemplateProcessing(
        single="[CLS] $A [SEP]", special_tokens=[("[CLS]", vocab["[CLS]"]), ("[SEP]", vocab["[SEP]"])]
    )
    tok.decoder = decoders.WordPiece()
    tok.save(str(path))
    return path


def save_model(path: Path, nodes, inputs, outputs, inits=()) -> Path:
    graph = helper.make_graph(nodes, path.stem, inputs, outputs, initializer=list(inits))
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8)
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def const(name, array, dtype=np.float32):
    return numpy_helper.from_array(np.asarray(array, dtype=dtype), name)


def value_info(name, elem, shape):
    return helper.make_tensor_value_info(name, elem, shape)


def sam_encoder_nchw(path: Path, input_name="x") -> Path:
    """(1,3,1024,1024) -> image_embeddings (1,256,64,64): channels 0..2 the 16x16 block means."""
    nodes = [
        helper.make_node("AveragePool", [input_name], ["pooled"], kernel_shape=[16, 16], strides=[16, 16]),
        helper.make_node("Concat", ["pooled", "zeros"], ["image_embeddings"], axis=1),
    ]
    return save_model(
        path,
        nodes,
        [value_info(input_name, F, [1, 3, 1024, 1024])],
        [value_info("image_embeddings", F, [1, 256, 64, 64])],
        [const("zeros", np.zeros((1, 253, 64, 64)))],
    )


def sam_encoder_hwc(path: Path) -> Path:
    """input_image (H,W,3) -> image_embeddings whose channels 0..2 are the per-channel means (0..255)."""
    nodes = [
        helper.make_node("ReduceMean", ["input_image"], ["mean"], axes=[0, 1], keepdims=0),
        helper.make_node("Reshape", ["mean", "shape4"], ["mean4"]),
        helper.make_node("Expand", ["mean4", "grid"], ["means"]),
        helper.make_node("Concat", ["means", "zeros"], ["image_embeddings"], axis=1),
    ]
    return save_model(
        path,
        nodes,
        [value_info("input_image", F, ["image_height", "image_width", 3])],
        [value_info("image_embeddings", F, [1, 256, 64, 64])],
        [
            const("shape4", [1, 3, 1, 1], np.int64),
            const("grid", [1, 3, 64, 64], np.int64),
            const("zeros", np.zeros((1, 253, 64, 64))),
        ],
    )


def sam2_encoder(path: Path) -> Path:
    """image (1,3,1024,1024) -> high_res_feats_0/1 and image_embed, all block means."""
    nodes = [
        helper.make_node("AveragePool", ["image"], ["high_res_feats_0"], kernel_shape=[4, 4], strides=[4, 4]),
        helper.make_node("AveragePool", ["image"], ["high_res_feats_1"], kernel_shape=[8, 8], strides=[8, 8]),
        helper.make_node("AveragePool", ["image"], ["image_embed"], kernel_shape=[16, 16], strides=[16, 16]),
    ]
    return save_model(
        path,
        nodes,
        [value_info("image", F, [1, 3, 1024, 1024])],
        [
            value_info("high_res_feats_0", F, [1, 3, 256, 256]),
            value_info("high_res_feats_1", F, [1, 3, 128, 128]),
            value_info("image_embed", F, [1, 3, 64, 64]),
        ],
    )


# Low-resolution pixel centres in the 1024 frame (a 4 x 4 block of frame pixels each).
_CENTRES = (4 * np.arange(256) + 1.5).astype(np.float32)
_X = np.broadcast_to(_CENTRES[None, :], (256, 256))[None, None]
_Y = np.broadcast_to(_CENTRES[:, None], (256, 256))[None, None]


def _first_point_nodes(batched: bool):
    """Nodes giving px, py of point 0 of each prompt, shaped (B,1,1,1)."""
    return [
        helper.make_node("Gather", ["point_coords", "i0"], ["p0"], axis=1),  # (B, 2)
        helper.make_node("Gather", ["p0", "i0"], ["px"], axis=1),  # (B,)
        helper.make_node("Gather", ["p0", "i1"], ["py"], axis=1),
        helper.make_node("Reshape", ["px", "col4"], ["px4"]),
        helper.make_node("Reshape", ["py", "col4"], ["py4"]),
    ]


def _point_consts():
    return [
        const("i0", 0, np.int64),
        const("i1", 1, np.int64),
        const("col4", [-1, 1, 1, 1], np.int64),
        const("X", _X),
        const("Y", _Y),
    ]


def _disk_nodes():
    """logits = A * (R^2 - (X - px)^2 - (Y - py)^2), per token."""
    return [
        helper.make_node("Sub", ["X", "px4"], ["dx"]),
        helper.make_node("Sub", ["Y", "py4"], ["dy"]),
        helper.make_node("Mul", ["dx", "dx"], ["dx2"]),
        helper.make_node("Mul", ["dy", "dy"], ["dy2"]),
        helper.make_node("Add", ["dx2", "dy2"], ["d2"]),
        helper.make_node("Sub", ["R2", "d2"], ["r2md2"]),
        helper.make_node("Mul", ["A", "r2md2"], ["logits"]),
    ]


def _box_nodes():
    """logits = A * min(X - x0, x1 - X, Y - y0, y1 - Y) + Bk, per token (points 0 and 1 are the corners)."""
    return [
        helper.make_node("Gather", ["point_coords", "i1"], ["p1"], axis=1),
        helper.make_node("Gather", ["p1", "i0"], ["qx"], axis=1),
        helper.make_node("Gather", ["p1", "i1"], ["qy"], axis=1),
        helper.make_node("Reshape", ["qx", "col4"], ["qx4"]),
        helper.make_node("Reshape", ["qy", "col4"], ["qy4"]),
        helper.make_node("Sub", ["X", "px4"], ["l"]),
        helper.make_node("Sub", ["qx4", "X"], ["r"]),
        helper.make_node("Sub", ["Y", "py4"], ["t"]),
        helper.make_node("Sub", ["qy4", "Y"], ["b"]),
        helper.make_node("Min", ["l", "r", "t", "b"], ["inside"]),
        helper.make_node("Mul", ["A", "inside"], ["scaled"]),
        helper.make_node("Add", ["scaled", "Bk"], ["logits"]),
    ]


def _token_consts(radius_px=None, slope=None, offset=None):
    m = len(slope)
    out = [const("A", np.asarray(slope).reshape(1, m, 1, 1))]
    if radius_px is not None:
        out.append(const("R2", (np.asarray(radius_px, np.float64) ** 2).reshape(1, m, 1, 1)))
    if offset is not None:
        out.append(const("Bk", np.asarray(offset).reshape(1, m, 1, 1)))
    return out


def sam_decoder(path: Path, iou, shape="disk", radius=None, slope=None, offset=None, low_res_output=True) -> Path:
    """A segment-anything SamOnnxModel stand-in: batch 1, four tokens, masks at orig_im_size."""
    m = len(iou)
    nodes = _first_point_nodes(False) + (_disk_nodes() if shape == "disk" else _box_nodes())
    nodes += [
        helper.make_node("Identity", ["logits"], ["low_res_masks"] if low_res_output else ["low"]),
        helper.make_node("Cast", ["orig_im_size"], ["hw"], to=I64),
        helper.make_node("Concat", ["lead", "hw"], ["out_size"], axis=0),
        helper.make_node(
            "Resize",
            ["low_res_masks" if low_res_output else "low", "", "", "out_size"],
            ["masks"],
            mode="linear",
            coordinate_transformation_mode="half_pixel",
        ),
        helper.make_node("Identity", ["iou_const"], ["iou_predictions"]),
    ]
    inits = (
        _point_consts()
        + _token_consts(radius, slope, offset)
        + [
            const("lead", [1, m], np.int64),
            const("iou_const", np.asarray(iou).reshape(1, m)),
        ]
    )
    outputs = [value_info("masks", F, [1, m, None, None]), value_info("iou_predictions", F, [1, m])]
    if low_res_output:
        outputs.append(value_info("low_res_masks", F, [1, m, 256, 256]))
    inputs = [
        value_info("image_embeddings", F, [1, 256, 64, 64]),
        value_info("point_coords", F, [1, "num_points", 2]),
        value_info("point_labels", F, [1, "num_points"]),
        value_info("mask_input", F, [1, 1, 256, 256]),
        value_info("has_mask_input", F, [1]),
        value_info("orig_im_size", F, [2]),
    ]
    return save_model(path, nodes, inputs, outputs, inits)


def sam2_decoder(path: Path, iou, shape="disk", radius=None, slope=None, offset=None) -> Path:
    """A samexporter SAM2 decoder stand-in: dynamic prompt batch, three tokens, 256x256 logits."""
    m = len(iou)
    nodes = _first_point_nodes(True) + (_disk_nodes() if shape == "disk" else _box_nodes())
    nodes += [
        helper.make_node("Identity", ["logits"], ["masks"]),
        helper.make_node("ReduceSum", ["point_coords", "axes12"], ["psum"], keepdims=0),  # (B,)
        helper.make_node("Reshape", ["psum", "col2"], ["psum2"]),
        helper.make_node("Mul", ["psum2", "zero"], ["zeros_b"]),
        helper.make_node("Add", ["zeros_b", "iou_const"], ["iou_predictions"]),
    ]
    inits = (
        _point_consts()
        + _token_consts(radius, slope, offset)
        + [
            const("axes12", [1, 2], np.int64),
            const("col2", [-1, 1], np.int64),
            const("zero", 0.0),
            const("iou_const", np.asarray(iou).reshape(1, m)),
        ]
    )
    inputs = [
        value_info("image_embed", F, [1, None, 64, 64]),
        value_info("high_res_feats_0", F, [1, None, 256, 256]),
        value_info("high_res_feats_1", F, [1, None, 128, 128]),
        value_info("point_coords", F, ["num_labels", "num_points", 2]),
        value_info("point_labels", F, ["num_labels", "num_points"]),
        value_info("mask_input", F, ["num_labels", 1, 256, 256]),
        value_info("has_mask_input", F, ["num_labels"]),
    ]
    outputs = [value_info("masks", F, ["num_labels", m, 256, 256]), value_info("iou_predictions", F, ["num_labels", m])]
    return save_model(path, nodes, inputs, outputs, inits)


def dino_model(path: Path, logits, boxes, image_shape=(1, 3, "height", "width")) -> Path:
    """GroundingDINO stand-in: fixed logits (1,Q,256) and boxes (1,Q,4)."""
    q = logits.shape[0]
    nodes = [
        helper.make_node("Identity", ["logits_const"], ["logits"]),
        helper.make_node("Identity", ["boxes_const"], ["boxes"]),
    ]
    inputs = [
        value_info("img", F, list(image_shape)),
        value_info("input_ids", I64, [1, "seq_len"]),
        value_info("attention_mask", B, [1, "seq_len"]),
        value_info("position_ids", I64, [1, "seq_len"]),
        value_info("token_type_ids", I64, [1, "seq_len"]),
        value_info("text_token_mask", B, [1, "seq_len", "seq_len"]),
    ]
    outputs = [value_info("logits", F, [1, q, 256]), value_info("boxes", F, [1, q, 4])]
    inits = [const("logits_const", logits[None]), const("boxes_const", boxes[None])]
    return save_model(path, nodes, inputs, outputs, inits)


def record(model: OnnxModel) -> list:
    """Wrap a model's run() so every feed dict is kept."""
    calls = []
    original = model.run

    def run(feeds, outputs=None):
        calls.append({k: np.array(v) for k, v in feeds.items()})
        return original(feeds, outputs)

    model.run = run
    return calls
