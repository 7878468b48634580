"""The decoder rewrite that computes prompt-independent work once per run
(r360gpu/probes/onnx_hoist.py), on tiny graphs built with the onnx helper API:
what it re-points, what it leaves, bit-identical outputs at several prompt
counts, the check that catches a batch-shaped tensor that is not a repeat,
and SamModels using the rewrite only when that check passes."""

from __future__ import annotations

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")
from onnx import helper  # noqa: E402

from r360gpu.probes.onnx_hoist import hoist_prompt_invariant, outputs_identical  # noqa: E402
from r360gpu.probes.onnx_models import SamEmbedding, SamModels  # noqa: E402

from onnx_graphs import F, I64, const, sam_decoder, sam_encoder_nchw, save_model, value_info  # noqa: E402

BATCHES = (1, 2, 7, 64)
RNG = np.random.default_rng(7)


def _session(model, optimize=True):
    options = ort.SessionOptions()
    options.log_severity_level = 3
    if not optimize:
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
    return ort.InferenceSession(model.SerializeToString(), options, providers=["CPUExecutionProvider"])


def _runner(model, outputs, optimize=True):
    session = _session(model, optimize)
    return lambda feeds: session.run(outputs, feeds)


def _attention_graph(tmp_path):
    """A two-way-attention-like block: the image (1, 4, 8) is tiled to one copy per prompt, then
    projected (hoistable) into two heads, attended to by the prompt tokens (broadcasting MatMuls),
    updated by the tokens (a broadcasting Add), concatenated with the tokens (Concat does not
    broadcast: the repeat stays for it), multiplied by the tokens in a MatMul whose right operand
    is 3-D (not re-pointed) and reshaped to the repeated image's shape (a Shape of a batch-shaped
    tensor).  ``mask`` has one row per prompt, the same in every row."""
    nodes = [
        helper.make_node("Shape", ["point_coords"], ["b"], start=0, end=1),
        helper.make_node("Concat", ["b", "ones2"], ["reps"], axis=0),
        helper.make_node("Tile", ["image", "reps"], ["img"]),
        helper.make_node("Add", ["img", "mask"], ["img_m"]),
        helper.make_node("Add", ["img_m", "pe"], ["img_pe"]),
        helper.make_node("MatMul", ["img_pe", "Wk"], ["k"]),
        helper.make_node("Reshape", ["k", "heads"], ["kh"]),
        helper.make_node("Transpose", ["kh"], ["kt"], perm=[0, 2, 3, 1]),
        helper.make_node("MatMul", ["img_m", "Wv"], ["v"]),
        helper.make_node("Reshape", ["v", "heads"], ["vh"]),
        helper.make_node("Transpose", ["vh"], ["vt"], perm=[0, 2, 1, 3]),
        helper.make_node("Unsqueeze", ["point_coords", "ax1"], ["pc3"]),
        helper.make_node("MatMul", ["pc3", "Wt"], ["tok"]),
        helper.make_node("Reshape", ["tok", "tok_heads"], ["th"]),
        helper.make_node("Transpose", ["th"], ["tt"], perm=[0, 2, 1, 3]),
        helper.make_node("MatMul", ["tt", "kt"], ["logits"]),
        helper.make_node("Softmax", ["logits"], ["attn"], axis=-1),
        helper.make_node("MatMul", ["attn", "vt"], ["out"]),
        helper.make_node("Reshape", ["out", "tok_flat"], ["out_flat"]),
        helper.make_node("Add", ["img_m", "out_flat"], ["img2"]),
        helper.make_node("Concat", ["img", "tok"], ["joined"], axis=1),
        helper.make_node("Transpose", ["img_m"], ["img_t"], perm=[0, 2, 1]),
        helper.make_node("MatMul", ["tok", "img_t"], ["plain"]),
        helper.make_node("Shape", ["img_m"], ["img_shape"]),
        helper.make_node("Reshape", ["img2", "img_shape"], ["img2_out"]),
    ]
    inits = [
        const("ones2", [1, 1], np.int64),
        const("ax1", [1], np.int64),
        const("heads", [0, 4, 2, 4], np.int64),
        const("tok_heads", [0, 1, 2, 4], np.int64),
        const("tok_flat", [0, 1, 8], np.int64),
        const("pe", RNG.standard_normal((1, 4, 8))),
        const("Wk", RNG.standard_normal((8, 8))),
        const("Wv", RNG.standard_normal((8, 8))),
        const("Wt", RNG.standard_normal((2, 8))),
    ]
    inputs = [
        value_info("image", F, [1, 4, 8]),
        value_info("point_coords", F, ["B", 2]),
        value_info("mask", F, ["B", 4, 8]),
    ]
    outputs = [
        value_info("out", F, ["B", 2, 1, 4]),
        value_info("img2_out", F, ["B", 4, 8]),
        value_info("joined", F, ["B", 5, 8]),
        value_info("plain", F, ["B", 1, 4]),
    ]
    return onnx.load(str(save_model(tmp_path / "attention.onnx", nodes, inputs, outputs, inits)))


def _attention_feeds(b):
    mask_row = RNG.standard_normal((1, 4, 8)).astype(np.float32)
    return {
        "image": RNG.standard_normal((1, 4, 8)).astype(np.float32),
        "point_coords": RNG.standard_normal((b, 2)).astype(np.float32),
        "mask": np.repeat(mask_row, b, axis=0),
    }


def test_repeat_followed_by_hoistable_and_other_ops(tmp_path):
    model = _attention_graph(tmp_path)
    rewritten = hoist_prompt_invariant(model, ["point_coords"], ["mask"])
    assert rewritten is not None
    onnx.checker.check_model(rewritten)
    nodes = {n.output[0]: n for n in rewritten.graph.node}
    # The projections of the image run on the batch-1 twin only; the originals are gone.
    assert "k" not in nodes and "v" not in nodes and "k__batch1" in nodes and "v__batch1" in nodes
    assert nodes["logits"].input[1] == "kt__batch1" and nodes["out"].input[1] == "vt__batch1"
    assert nodes["img2"].input[0] == "img_m__batch1"
    # A 3-D right operand of MatMul keeps its prompt axis (see hoist_prompt_invariant).
    assert nodes["plain"].input[1] == "img_t"
    # Concat does not broadcast: the repeated image stays for it.
    assert nodes["joined"].input[0] == "img" and nodes["img"].op_type == "Tile"
    # The Shape of the repeated image is rebuilt from the prompt count and the twin's shape.
    assert nodes["img_shape"].op_type == "Concat"
    assert nodes["mask__batch1"].op_type == "Slice"

    wanted = ["out", "img2_out", "joined", "plain"]
    before, after = _runner(model, wanted), _runner(rewritten, wanted)
    for b in BATCHES:
        feeds = _attention_feeds(b)
        want, got = before(feeds), after(feeds)
        for w, g in zip(want, got):
            assert w.shape == g.shape and w.shape[0] == b
            assert w.tobytes() == g.tobytes()
    assert outputs_identical(before, after, [_attention_feeds(b) for b in BATCHES])


def test_shapes_kept_from_the_repeat_when_asked(tmp_path):
    model = _attention_graph(tmp_path)
    rewritten = hoist_prompt_invariant(model, ["point_coords"], ["mask"], shapes_from_twins=False)
    nodes = {n.output[0]: n for n in rewritten.graph.node}
    assert nodes["img_shape"].op_type == "Shape" and nodes["img_shape"].input[0] == "img_m"
    wanted = ["out", "img2_out", "joined", "plain"]
    assert outputs_identical(_runner(model, wanted), _runner(rewritten, wanted), [_attention_feeds(b) for b in (1, 7)])


def test_nothing_to_hoist_leaves_the_graph(tmp_path):
    # The SAM stand-in decoder: every tensor that depends on the prompts depends on their values.
    model = onnx.load(str(sam_decoder(tmp_path / "d.onnx", iou=[0.9], radius=[50], slope=[1.0])))
    assert hoist_prompt_invariant(model, ["point_coords", "point_labels"]) is None
    # No per-prompt input in the graph: nothing to do.
    assert hoist_prompt_invariant(_attention_graph(tmp_path), ["no_such_input"]) is None


def _range_graph(tmp_path):
    """A batch-shaped tensor that is not a repeat: arange(B) added to the prompts."""
    nodes = [
        helper.make_node("Shape", ["point_coords"], ["b"], start=0, end=1),
        helper.make_node("Squeeze", ["b"], ["b0"]),
        helper.make_node("Range", ["zero", "b0", "one"], ["idx"]),
        helper.make_node("Cast", ["idx"], ["idx_f"], to=F),
        helper.make_node("Unsqueeze", ["idx_f", "ax1"], ["col"]),
        helper.make_node("Add", ["col", "point_coords"], ["y"]),
    ]
    inits = [const("zero", 0, np.int64), const("one", 1, np.int64), const("ax1", [1], np.int64)]
    path = save_model(
        tmp_path / "range.onnx",
        nodes,
        [value_info("point_coords", F, ["B", 2])],
        [value_info("y", F, ["B", 2])],
        inits,
    )
    return onnx.load(str(path))


def test_check_rejects_a_batch_shaped_tensor_that_is_not_a_repeat(tmp_path):
    model = _range_graph(tmp_path)
    rewritten = hoist_prompt_invariant(model, ["point_coords"])
    assert rewritten is not None  # the graph alone cannot tell arange(B) from a repeat
    feeds = [{"point_coords": RNG.standard_normal((b, 2)).astype(np.float32)} for b in (1, 3)]
    before, after = _runner(model, ["y"]), _runner(rewritten, ["y"])
    assert outputs_identical(before, after, feeds[:1])  # one prompt cannot show it
    assert not outputs_identical(before, after, feeds)


def _axis1_repeat_graph(tmp_path):
    """The image tiled along axis 1 (its prompt axis is not axis 0), then moved to axis 0 and added
    to the prompts (hoistable); the Shape of the tiled tensor also sizes a reshape of the prompts."""
    nodes = [
        helper.make_node("Shape", ["point_coords"], ["b"], start=0, end=1),
        helper.make_node("Concat", ["one1", "b", "one1"], ["reps"], axis=0),
        helper.make_node("Tile", ["image", "reps"], ["t"]),  # (1, B, 8)
        helper.make_node("Shape", ["t"], ["t_shape"]),
        helper.make_node("Gather", ["t_shape", "one1"], ["nb"], axis=0),
        helper.make_node("Concat", ["nb", "one1", "eight"], ["r_shape"], axis=0),
        helper.make_node("Reshape", ["t", "r_shape"], ["r"]),  # (B, 1, 8)
        helper.make_node("MatMul", ["point_coords", "W"], ["p"]),  # (B, 8)
        helper.make_node("Unsqueeze", ["p", "one1"], ["p3"]),
        helper.make_node("Add", ["r", "p3"], ["y"]),
        helper.make_node("Concat", ["nb", "eight"], ["flat"], axis=0),
        helper.make_node("Reshape", ["y", "flat"], ["z"]),
    ]
    inits = [const("one1", [1], np.int64), const("eight", [8], np.int64), const("W", RNG.standard_normal((2, 8)))]
    path = save_model(
        tmp_path / "axis1.onnx",
        nodes,
        [value_info("image", F, [1, 1, 8]), value_info("point_coords", F, ["B", 2])],
        [value_info("z", F, ["B", 8])],
        inits,
    )
    model = onnx.load(str(path))
    model.graph.value_info.append(value_info("t", F, [1, "B", 8]))  # as exporters record it
    return model


def test_shapes_from_twins_refused_when_the_prompt_axis_is_not_leading(tmp_path):
    model = _axis1_repeat_graph(tmp_path)
    feeds = [
        {"image": RNG.standard_normal((1, 1, 8)).astype(np.float32),
         "point_coords": RNG.standard_normal((b, 2)).astype(np.float32)}
        for b in BATCHES
    ]
    # onnxruntime's graph optimisations may derive the size from the recorded shape of "t" instead
    # of computing it: without them the graphs compute what they say.
    before = _runner(model, ["z"], optimize=False)
    with_shapes = hoist_prompt_invariant(model, ["point_coords"])
    assert not outputs_identical(before, _runner(with_shapes, ["z"], optimize=False), feeds)
    keeping = hoist_prompt_invariant(model, ["point_coords"], shapes_from_twins=False)
    assert {n.output[0]: n for n in keeping.graph.node}["y"].input[0] == "r__batch1"
    assert outputs_identical(before, _runner(keeping, ["z"], optimize=False), feeds)
    assert outputs_identical(_runner(model, ["z"]), _runner(keeping, ["z"]), feeds)


def test_outputs_identical_compares_bits():
    a = np.array([0.0, np.nan], np.float32)
    assert outputs_identical(lambda f: [a], lambda f: [a.copy()], [{}])
    assert not outputs_identical(lambda f: [a], lambda f: [np.array([-0.0, np.nan], np.float32)], [{}])
    assert not outputs_identical(lambda f: [a], lambda f: [a.astype(np.float64)], [{}])
    assert not outputs_identical(lambda f: [a], lambda f: [a[:1]], [{}])

    def broken(feeds):
        raise RuntimeError("shape mismatch")

    assert not outputs_identical(lambda f: [a], broken, [{}])


def test_subgraphs_are_not_analysed(tmp_path):
    branch = helper.make_graph(
        [helper.make_node("Identity", ["point_coords"], ["z"])], "b", [], [value_info("z", F, ["B", 2])]
    )
    nodes = [helper.make_node("If", ["cond"], ["y"], then_branch=branch, else_branch=branch)]
    path = save_model(
        tmp_path / "if.onnx",
        nodes,
        [value_info("point_coords", F, ["B", 2]), value_info("cond", onnx.TensorProto.BOOL, [])],
        [value_info("y", F, ["B", 2])],
    )
    assert hoist_prompt_invariant(onnx.load(str(path)), ["point_coords"]) is None


def _sam_decoder_with_repeat(path, batched=True):
    """The SAM stand-in decoder plus a repeated image embedding projected and added to each prompt's
    x coordinate: a term that changes the logits, so a wrong rewrite would show."""
    base = onnx.load(str(sam_decoder(path, iou=[0.99, 0.95, 0.92], radius=[80, 160, 240], slope=[1.0] * 3)))
    g = base.graph
    extra = [
        helper.make_node("Shape", ["point_coords"], ["nb"], start=0, end=1),
        helper.make_node("Concat", ["nb", "ones3"], ["reps"], axis=0),
        helper.make_node("Tile", ["image_embeddings", "reps"], ["rep"]),
        helper.make_node("Reshape", ["rep", "flat"], ["rep3"]),
        helper.make_node("Transpose", ["rep3"], ["rep_t"], perm=[0, 2, 1]),
        helper.make_node("MatMul", ["rep_t", "W"], ["proj"]),
        helper.make_node("Reshape", ["px", "col3"], ["px3"]),
        helper.make_node("Add", ["proj", "px3"], ["mixed"]),
        helper.make_node("ReduceMean", ["mixed"], ["score"], axes=[1, 2], keepdims=0),
        helper.make_node("Reshape", ["score", "col4"], ["score4"]),
        helper.make_node("Mul", ["score4", "eps"], ["nudge"]),
    ]
    for k, node in enumerate(g.node):
        if "logits" in node.output:
            node.output[0] = "logits_disk"
            g.node.insert(k + 1, helper.make_node("Add", ["logits_disk", "nudge"], ["logits"]))
            break
    # One row of predicted IoUs per prompt (the stand-in's constant row, broadcast).
    iou = next(n for n in g.node if n.output[0] == "iou_predictions")
    iou.CopyFrom(helper.make_node("Add", ["iou_zeros", "iou_const"], ["iou_predictions"]))
    extra += [
        helper.make_node("Reshape", ["px", "col2"], ["px2"]),
        helper.make_node("Mul", ["px2", "zero"], ["iou_zeros"]),
    ]
    g.node.extend(extra)
    g.initializer.extend(
        [
            const("ones3", [1, 1, 1], np.int64),
            const("flat", [0, 256, -1], np.int64),
            const("W", RNG.standard_normal((256, 1))),
            const("col3", [-1, 1, 1], np.int64),
            const("eps", 1e-3),
            const("col2", [-1, 1], np.int64),
            const("zero", 0.0),
        ]
    )
    if batched:
        for name in ("point_coords", "point_labels"):
            dim = next(i for i in g.input if i.name == name).type.tensor_type.shape.dim[0]
            dim.Clear()
            dim.dim_param = "prompts"
    from r360gpu.probes.onnx_hoist import _toposort

    _toposort(g)
    onnx.checker.check_model(base)
    onnx.save(base, str(path))
    return path


def test_sam_models_use_the_rewrite_only_when_checked(tmp_path, monkeypatch):
    enc = sam_encoder_nchw(tmp_path / "enc.onnx")
    dec = _sam_decoder_with_repeat(tmp_path / "dec.onnx")
    hoisted, plain = SamModels(enc, dec), SamModels(enc, dec, hoist=False)
    assert plain.batched and hoisted.hoisted and not plain.hoisted
    features = {"image_embeddings": RNG.standard_normal((1, 256, 64, 64)).astype(np.float32)}
    emb = SamEmbedding(features, (480, 640), (768, 1024))
    for b in BATCHES:
        points = RNG.uniform(0, 480, (b, 2))
        a, c = plain.predict_points(emb, points), hoisted.predict_points(emb, points)
        assert a.logits.tobytes() == c.logits.tobytes() and a.iou.tobytes() == c.iou.tobytes()

    # A decoder with the prompt batch fixed at 1 is not rewritten.
    assert not SamModels(enc, _sam_decoder_with_repeat(tmp_path / "dec1.onnx", batched=False)).hoisted

    # A rewrite whose outputs differ from the original's at the check is not used.
    import r360gpu.probes.onnx_hoist as hoist_module

    monkeypatch.setattr(hoist_module, "outputs_identical", lambda *a, **k: False)
    assert not SamModels(enc, dec).hoisted


def test_sam_models_pickle_keeps_the_choice(tmp_path):
    import pickle

    enc = sam_encoder_nchw(tmp_path / "enc.onnx")
    dec = _sam_decoder_with_repeat(tmp_path / "dec.onnx")
    assert pickle.loads(pickle.dumps(SamModels(enc, dec))).hoisted
    assert not pickle.loads(pickle.dumps(SamModels(enc, dec, hoist=False))).hoisted
