"""The Inception feature wrapper (r360gpu/probes/inception.py) on tiny ONNX graphs built with
the onnx helper API.

Each graph does what the export contract puts in pytorch-fid's network before the Inception
blocks (bilinear resize to 299 x 299, ``2 x - 1``) and then, instead of the blocks, reads
2048 pixels of the result at a fixed stride, so a feature row shows the exact tensor the
network saw: the feed's scale and channel order, the resize rule, and which image went to
which row.  The reference re-computes that in numpy (cv2's bilinear resize, half-pixel
centres, as ``F.interpolate(align_corners=False)``).
"""
from __future__ import annotations

import hashlib

import cv2
import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
from onnx import helper  # noqa: E402

from r360gpu.errors import InputError  # noqa: E402
from r360gpu.probes.inception import FID_DIMS, FID_INPUT_SIDE, InceptionModel, image_tensor  # noqa: E402

from onnx_graphs import F, const, save_model, value_info  # noqa: E402

SIDE = FID_INPUT_SIDE
STRIDE = 131  # 2048 samples spread over the 3 x 299 x 299 values


def inception_like(path, *, in_shape=("N", 3, "H", "W"), resize=True, dims=FID_DIMS, out_rank=2,
                   n_inputs=1):
    """(N, 3, H, W) in [0, 1] -> resize to 299 (half-pixel bilinear) -> 2x-1 -> strided samples (N, dims)."""
    nodes, inits = [], [const("two", 2.0), const("one", 1.0), const("flat", [0, -1], np.int64),
                        const("starts", [0], np.int64), const("ends", [STRIDE * dims], np.int64),
                        const("axes", [1], np.int64), const("steps", [STRIDE], np.int64)]
    src = "x"
    if resize:
        nodes += [
            helper.make_node("Shape", ["x"], ["xs"]),
            helper.make_node("Slice", ["xs", "s0", "s2", "s_ax"], ["nc"]),
            helper.make_node("Concat", ["nc", "hw"], ["size4"], axis=0),
            helper.make_node("Resize", ["x", "", "", "size4"], ["xr"], mode="linear",
                             coordinate_transformation_mode="half_pixel"),
        ]
        inits += [const("s0", [0], np.int64), const("s2", [2], np.int64), const("s_ax", [0], np.int64),
                  const("hw", [SIDE, SIDE], np.int64)]
        src = "xr"
    nodes += [
        helper.make_node("Mul", [src, "two"], ["x2"]),
        helper.make_node("Sub", ["x2", "one"], ["xn"]),
        helper.make_node("Reshape", ["xn", "flat"], ["xf"]),
        helper.make_node("Slice", ["xf", "starts", "ends", "axes", "steps"], ["feat"]),
    ]
    out_name = "feat"
    if out_rank == 4:
        inits.append(const("shape4", [0, dims, 1, 1], np.int64))
        nodes.append(helper.make_node("Reshape", ["feat", "shape4"], ["pool3"]))
        out_name = "pool3"
    inputs = [value_info("x", F, list(in_shape))] + [value_info(f"extra{i}", F, list(in_shape)) for i in range(1, n_inputs)]
    out_shape = [in_shape[0], dims] + [1, 1] * (out_rank == 4)
    return save_model(path, nodes, inputs, [value_info(out_name, F, out_shape)], inits)


def reference(image_u8: np.ndarray) -> np.ndarray:
    x = image_u8.astype(np.float32) / np.float32(255.0)
    if x.shape[:2] != (SIDE, SIDE):
        x = cv2.resize(x, (SIDE, SIDE), interpolation=cv2.INTER_LINEAR)
    x = (x * 2 - 1).transpose(2, 0, 1).ravel()
    return x[: STRIDE * FID_DIMS : STRIDE].astype(np.float64)


@pytest.fixture(scope="module")
def dynamic_model(tmp_path_factory):
    return InceptionModel(inception_like(tmp_path_factory.mktemp("inc") / "inception_fid.onnx"))


def _images(sizes, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for h, w in sizes]


def test_features_follow_the_export_contract_in_batches_of_one_size(dynamic_model):
    # Two runs of one size, an odd size in between, a batch limit that splits the first run.
    imgs = _images([(40, 64), (40, 64), (40, 64), (23, 17), (299, 299), (40, 64)])
    feats = dynamic_model.features(imgs, batch_size=2)
    assert feats.shape == (6, FID_DIMS) and feats.dtype == np.float64
    for row, img in zip(feats, imgs):
        # onnxruntime's and cv2's bilinear weights round differently in float32 (a wrong
        # resize rule, scale or channel order differs by 1e-2 and more).
        np.testing.assert_allclose(row, reference(img), atol=1e-5)
    assert dynamic_model.any_size and dynamic_model.batch_limit is None
    one_by_one = np.concatenate([dynamic_model.features([im]) for im in imgs])
    np.testing.assert_allclose(feats, one_by_one, atol=1e-6)


def test_float_images_in_unit_range_equal_their_uint8(dynamic_model):
    img = _images([(31, 45)], seed=1)[0]
    f8 = dynamic_model.features([img])
    ff = dynamic_model.features([img.astype(np.float64) / 255.0])
    np.testing.assert_allclose(f8, ff, atol=1e-6)
    assert dynamic_model.features([]).shape == (0, FID_DIMS)


def test_fixed_299_export_is_fed_images_we_resize(tmp_path):
    # A fixed 299 x 299 batch-1 input (a trace without dynamic axes): we resize, the graph's resize is the identity.
    m = InceptionModel(inception_like(tmp_path / "fixed.onnx", in_shape=(1, 3, SIDE, SIDE), out_rank=4))
    assert not m.any_size and m.batch_limit == 1
    imgs = _images([(120, 80), (301, 299), (299, 299)], seed=2)
    feats = m.features(imgs, batch_size=50)
    for row, img in zip(feats, imgs):
        np.testing.assert_allclose(row, reference(img), atol=1e-6)
    assert m.describe()["resize"].startswith("bilinear to 299")


def test_describe_names_the_file_and_its_hash(tmp_path):
    path = inception_like(tmp_path / "pt_inception.onnx")
    d = InceptionModel(path).describe()
    assert d["file"] == "pt_inception.onnx"
    assert d["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert d["resize"] == "in the model" and d["provider"] == "CPUExecutionProvider"


@pytest.mark.parametrize("kwargs,match", [
    ({"n_inputs": 2}, "one image input"),
    ({"in_shape": ("N", 3, 224, 224), "resize": False}, "fixed size other than 299"),
    ({"in_shape": ("N", 3, 299, "W")}, "fixed size other than 299"),
    ({"in_shape": ("N", 4, "H", "W")}, r"not \(N, 3, H, W\)"),
    ({"in_shape": (4, 3, "H", "W")}, "fixes the batch at 4"),
    ({"dims": 1000}, "pool3 features"),
])
def test_models_that_break_the_contract_are_refused_naming_the_file(tmp_path, kwargs, match):
    path = inception_like(tmp_path / "other.onnx", **kwargs)
    with pytest.raises(InputError, match=match) as e:
        InceptionModel(path)
    assert "other.onnx" in str(e.value)


def test_a_graph_that_returns_the_wrong_count_at_run_time(tmp_path):
    # Declared (N, dims) with symbolic dims, but it returns 100 values per image.
    path = inception_like(tmp_path / "short.onnx", dims=100)
    g = onnx.load(str(path))
    g.graph.output[0].type.tensor_type.shape.dim[1].dim_param = "D"
    onnx.save(g, str(path))
    with pytest.raises(InputError, match=r"short.onnx.*expected \(1, 2048\)"):
        InceptionModel(path).features(_images([(20, 20)]))


def test_bad_images_are_refused(dynamic_model):
    for bad, match in [
        (np.zeros((8, 8), np.uint8), r"\(H, W, 3\)"),
        (np.full((8, 8, 3), 1.5), "outside"),
        (np.full((8, 8, 3), np.nan), "NaN"),
        (np.zeros((8, 8, 3), np.int16), "uint8"),
    ]:
        with pytest.raises(InputError, match=match):
            dynamic_model.features([bad])
    with pytest.raises(InputError, match="image 0"):
        image_tensor(np.zeros((3, 3)), "image 0")
    with pytest.raises(InputError, match="batch_size"):
        dynamic_model.features([], batch_size=0)
