"""Parity of r360gpu's SAM automatic mask generator with segment-anything's, without model weights.

Builds SAM ViT-B with random weights (fixed seed), exports its image encoder
and prompt decoder to ONNX as samexporter does (``ImageEncoderOnnxModel``
without ``--use-preprocess``; segment-anything's ``SamOnnxModel`` without
``--return-single-mask``, opset 17, dynamic point count), and compares:

1. the AMG's pure steps on the same inputs (point grids, crop boxes,
   stability scores, mask boxes, crop-edge filter, box NMS, small-region
   removal, RLE), r360gpu.probes.amg_utils / rle against segment_anything's;
2. pre- and post-processing: encoder input tensor, decoder coordinates,
   low-res logits -> image logits;
3. the ONNX encoder / decoder against the torch modules;
4. whole mask sets: ``SamAutomaticMaskGenerator.generate`` against
   r360gpu's ``generate_masks`` (a) driven by the official torch predictor
   (the algorithm alone) and (b) on the exported ONNX pair (what users run),
   with the same parameters on the same images: counts and the Hungarian
   matching of masks by IoU.

Needs torch, torchvision, onnx, onnxruntime, opencv, pycocotools, scipy and
the fetched sources (never committed):

    python bench/parity_sam.py --sam-src /tmp/sam-src --samexporter-src /tmp/samexporter-src \
        [--work /tmp/probes-parity] [--points-per-side 16]

Random weights give arbitrary but deterministic masks; the thresholds used
(printed) are chosen low enough that both generators keep non-trivial sets.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sam-src", required=True, help="folder holding the fetched segment_anything package")
    add_model_args(ap)
    ap.add_argument("--quick", action="store_true", help="only the step checks (no models)")
    ap.add_argument("--margins-only", action="store_true",
                    help="of the mask-set checks, only the ONNX-vs-torch logit margins (minutes, not half an hour)")
    return ap.parse_args()


def add_model_args(ap) -> None:
    """The arguments both parity benches take: the exporter's source, where exports go, seed, point grid."""
    ap.add_argument("--samexporter-src", required=True, help="folder holding the fetched samexporter package")
    ap.add_argument("--work", default="/tmp/probes-parity", help="where the ONNX exports are written")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--points-per-side", type=int, default=16)


def report(name: str, ok: bool, detail: str = "") -> bool:
    print(f"  [{'same' if ok else 'DIFF'}] {name}{(': ' + detail) if detail else ''}")
    return ok


# --------------------------------------------------------------------------- 1. pure steps
def check_steps(rng) -> list[bool]:
    import torch
    from segment_anything.utils import amg as A
    from torchvision.ops.boxes import batched_nms

    from r360gpu.probes import amg_utils as au
    from r360gpu.probes import rle as R

    out = []
    print("1. AMG steps on identical inputs")
    ok = all(
        all(np.array_equal(a, b) for a, b in zip(A.build_all_layer_point_grids(n, l, s), au.build_all_layer_point_grids(n, l, s)))
        for n in (1, 2, 7, 16, 32, 64) for l in (0, 1, 2, 3) for s in (1, 2) if n // s**l >= 1
    )
    out.append(report("point grids (n 1..64, layers 0..3, downscale 1..2)", ok))
    bad = []
    for (h, w) in [(240, 320), (320, 240), (1, 1), (7, 1000), (1080, 1920), (333, 333), (1500, 2250)]:
        for layers in (0, 1, 2, 3):
            for ratio in (0.0, 512 / 1500, 0.5, 1.0):
                a = A.generate_crop_boxes((h, w), layers, ratio)
                b = au.generate_crop_boxes((h, w), layers, ratio)
                if a[0] != b[0] or a[1] != b[1]:
                    bad.append((h, w, layers, ratio))
    out.append(report("crop boxes (7 sizes x 4 layers x 4 overlaps)", not bad, f"differ for {bad[:3]}" if bad else ""))
    logits = rng.normal(0, 3, (40, 37, 53)).astype(np.float32)
    logits[3] = -10  # empty even at the low threshold: official 0/0 = NaN, r360gpu 0
    logits[4] = 10
    for offset, thr in ((1.0, 0.0), (0.5, 0.3), (2.0, -1.0)):
        s_off = A.calculate_stability_score(torch.from_numpy(logits), thr, offset).numpy()
        s_r = au.stability_score(logits, thr, offset)
        nan = np.isnan(s_off)
        same = np.array_equal(s_off[~nan].astype(np.float32), s_r[~nan]) and np.all(s_r[nan] == 0)
        keep_same = all(np.array_equal(s_off >= t, s_r >= t) for t in (0.0, 0.5, 0.95) if t > 0)
        out.append(report(f"stability score offset={offset} thr={thr}", same and keep_same,
                          f"{nan.sum()} NaN (empty) in official, 0 in r360gpu; keep sets equal" if nan.any() else ""))
    masks = rng.random((30, 41, 29)) > 0.97
    masks[0] = False
    masks[1, 5, 7] = True
    masks[1] = False
    masks[1, 5, 7] = True
    b_off = A.batched_mask_to_box(torch.from_numpy(masks)).numpy()
    out.append(report("mask boxes (incl. empty and one-pixel masks)", np.array_equal(b_off, au.masks_to_boxes(masks))))
    boxes = rng.integers(0, 300, (200, 4))
    boxes[:, 2:] = boxes[:, :2] + rng.integers(0, 200, (200, 2))
    crop, orig = [100, 50, 400, 300], [0, 0, 500, 400]
    near_off = A.is_box_near_crop_edge(torch.from_numpy(boxes), crop, orig).numpy()
    out.append(report("crop-edge filter", np.array_equal(near_off, au.is_box_near_crop_edge(boxes, crop, orig))))
    bad = 0
    for trial in range(200):
        n = int(rng.integers(1, 120))
        bx = rng.integers(0, 60, (n, 4)).astype(np.float64)
        bx[:, 2:] = bx[:, :2] + rng.integers(0, 40, (n, 2))
        if trial % 3 == 0:
            sc = rng.integers(0, 3, n).astype(np.float32)  # ties (the small-region NMS scores 0/1)
        else:
            sc = rng.random(n).astype(np.float32)
        thr = float(rng.choice([0.0, 0.3, 0.5, 0.7, 1.0]))
        k_off = batched_nms(torch.from_numpy(bx).float(), torch.from_numpy(sc), torch.zeros(n), thr).numpy()
        k_r = au.nms(bx, sc, thr)
        bad += not np.array_equal(k_off, k_r)
    out.append(report("box NMS keep lists, in order (200 random sets, ties included)", bad == 0, f"{bad} differ" if bad else ""))
    bad = 0
    for trial in range(60):
        m = rng.random((48, 64)) > rng.uniform(0.3, 0.8)
        for mode in ("holes", "islands"):
            for area in (0, 1, 5, 30, 10000):
                a, ca = A.remove_small_regions(m.copy(), area, mode)
                b, cb = au.remove_small_regions(m.copy(), area, mode)
                bad += not (np.array_equal(a, b) and ca == cb)
    out.append(report("small-region removal (holes / islands, 5 areas, 60 masks)", bad == 0, f"{bad} differ" if bad else ""))
    from pycocotools import mask as mask_utils

    bad = 0
    for trial in range(50):
        h, w = int(rng.integers(1, 40)), int(rng.integers(1, 40))
        m = rng.random((1, h, w)) > rng.uniform(0, 1)
        rle_off = A.mask_to_rle_pytorch(torch.from_numpy(m))[0]
        counts_r = [int(c) for c in R.mask_to_counts(m[0])]
        coco = A.coco_encode_rle(rle_off)
        enc_r = R.encode(m[0])
        bad += not (
            rle_off["counts"] == counts_r
            and coco["counts"] == enc_r["counts"]
            and np.array_equal(A.rle_to_mask(rle_off), R.decode(enc_r))
            and np.array_equal(mask_utils.decode(coco).astype(bool), m[0])
        )
    out.append(report("RLE counts / compressed string / decode (50 masks)", bad == 0, f"{bad} differ" if bad else ""))
    return out


# --------------------------------------------------------------------------- models
def build_sam(seed: int):
    import torch
    from segment_anything import sam_model_registry

    torch.manual_seed(seed)
    sam = sam_model_registry["vit_b"](checkpoint=None)
    sam.eval()
    return sam


def export_onnx(sam, work: Path, batched_decoder: bool = False, reuse: bool = False) -> tuple[Path, Path]:
    """Encoder and decoder exported as samexporter's export_encoder.py / export_decoder.py do.

    batched_decoder: the decoder's prompt-batch axis (point_coords / point_labels
    axis 0) exported dynamic too, so one run decodes many prompts; samexporter
    fixes it at 1.  reuse: keep files already in ``work`` (the caller vouches
    they come from the same seed; the export of the encoder takes minutes).
    """
    import torch
    from samexporter.onnx_utils import ImageEncoderOnnxModel
    from segment_anything.utils.onnx import SamOnnxModel

    work.mkdir(parents=True, exist_ok=True)
    enc_path = work / "sam_vit_b_random.encoder.onnx"
    dec_path = work / ("sam_vit_b_random.decoder_batched.onnx" if batched_decoder else "sam_vit_b_random.decoder.onnx")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if not (reuse and enc_path.is_file()):
            enc = ImageEncoderOnnxModel(sam, use_preprocess=False,
                                        pixel_mean=[123.675, 116.28, 103.53], pixel_std=[58.395, 57.12, 57.375])
            size = sam.image_encoder.img_size
            torch.onnx.export(enc, (torch.randn(1, 3, size, size),), str(enc_path), export_params=True,
                              opset_version=17, do_constant_folding=True, input_names=["input_image"],
                              output_names=["image_embeddings"], dynamo=False)
        if reuse and dec_path.is_file():
            return enc_path, dec_path
        dec = SamOnnxModel(sam, return_single_mask=False)
        embed = sam.prompt_encoder.image_embedding_size
        batch = 3 if batched_decoder else 1
        dummy = {
            "image_embeddings": torch.randn(1, sam.prompt_encoder.embed_dim, *embed),
            "point_coords": torch.randint(0, 1024, (batch, 5, 2)).float(),
            "point_labels": torch.randint(0, 4, (batch, 5)).float(),
            "mask_input": torch.randn(1, 1, 4 * embed[0], 4 * embed[1]),
            "has_mask_input": torch.tensor([1.0]),
            "orig_im_size": torch.tensor([1500.0, 2250.0]),
        }
        points_axes = {0: "prompts", 1: "num_points"} if batched_decoder else {1: "num_points"}
        torch.onnx.export(dec, tuple(dummy.values()), str(dec_path), export_params=True, opset_version=17,
                          do_constant_folding=True, input_names=list(dummy),
                          output_names=["masks", "iou_predictions", "low_res_masks"],
                          dynamic_axes={"point_coords": points_axes, "point_labels": points_axes},
                          dynamo=False)
    return enc_path, dec_path


class TorchSamModels:
    """The official torch predictor behind r360gpu's SamModels interface, so that
    r360gpu's generate_masks runs the algorithm on the official model outputs."""

    variant = "sam"

    def __init__(self, sam):
        from segment_anything import SamPredictor

        self.predictor = SamPredictor(sam)

        class _P:
            path = "torch-sam"

        self.decoder = _P()

    def embed(self, image01):
        from r360gpu.probes.onnx_models import SamEmbedding
        from r360gpu.probes.preprocess import as_rgb01, to_uint8

        u8 = to_uint8(as_rgb01(image01))  # uint8 or float 0..1, as SamModels.embed; exact for uint8 sources
        self.predictor.set_image(u8)
        return SamEmbedding({}, tuple(u8.shape[:2]), tuple(self.predictor.input_size))

    def predict_points(self, embedding, points_xy):
        import torch

        from r360gpu.probes.onnx_models import Decoded

        pts = self.predictor.transform.apply_coords(np.asarray(points_xy, np.float64), embedding.image_size)
        coords = torch.as_tensor(pts)[:, None, :]  # float64, as the official generator passes them
        labels = torch.ones(len(pts), 1, dtype=torch.int)
        model = self.predictor.model
        # SamPredictor.predict_torch without its final upsampling (done by logits_to_image).
        with torch.no_grad():
            sparse, dense = model.prompt_encoder(points=(coords, labels), boxes=None, masks=None)
            low, iou = model.mask_decoder(
                image_embeddings=self.predictor.features,
                image_pe=model.prompt_encoder.get_dense_pe(),
                sparse_prompt_embeddings=sparse,
                dense_prompt_embeddings=dense,
                multimask_output=True,
            )
        return Decoded(low.numpy(), iou.numpy(), True)

    def logits_to_image(self, embedding, logits, low_res):
        import torch

        with torch.no_grad():
            up = self.predictor.model.postprocess_masks(
                torch.from_numpy(np.asarray(logits, np.float32))[:, None], embedding.model_size, embedding.image_size
            )
        return up[:, 0].numpy()


class EmbeddingCache:
    """Image encodings memoised by the exact pixels encoded.

    The encoder is a pure function of its input, and on CPU one ViT-B pass
    takes ~20 s; every crop of every image is encoded once per side (torch,
    ONNX) and shared between the runs that need it.  Nothing downstream of
    the encoder is cached.
    """

    def __init__(self):
        self.store = {}
        self.hits = self.misses = 0

    @staticmethod
    def key(image) -> tuple:
        arr = np.ascontiguousarray(image)
        return arr.shape, str(arr.dtype), hashlib.sha256(arr.tobytes()).hexdigest()

    def wrap_predictor(self, predictor) -> None:
        """segment-anything's SamPredictor.set_image, memoised (features, sizes)."""
        original = predictor.set_image

        def set_image(image, image_format="RGB"):
            k = ("torch", image_format) + self.key(image)
            if k in self.store:
                self.hits += 1
                predictor.reset_image()
                predictor.features, predictor.original_size, predictor.input_size = self.store[k]
                predictor.is_image_set = True
                return
            self.misses += 1
            original(image, image_format)
            self.store[k] = (predictor.features, predictor.original_size, predictor.input_size)

        predictor.set_image = set_image

    def wrap_models(self, models) -> None:
        """r360gpu's SamModels.embed, memoised."""
        original = models.embed

        def embed(image):
            k = ("onnx",) + self.key(image)
            if k not in self.store:
                self.misses += 1
                self.store[k] = original(image)
            else:
                self.hits += 1
            return self.store[k]

        models.embed = embed


def generator_kwargs(params) -> dict:
    """The keyword arguments SAM's and SAM 2's automatic mask generators share, from ``params``."""
    keys = ("points_per_side", "points_per_batch", "pred_iou_thresh", "stability_score_thresh",
            "stability_score_offset", "box_nms_thresh", "crop_n_layers", "crop_nms_thresh", "crop_overlap_ratio",
            "crop_n_points_downscale_factor", "min_mask_region_area")
    return {k: getattr(params, k) for k in keys} | {"output_mode": "binary_mask"}


def official_generate(sam, image, params, cache: EmbeddingCache | None = None):
    from segment_anything import SamAutomaticMaskGenerator

    # The official generator reads the mask threshold from the model.
    sam.mask_threshold = params.mask_threshold
    gen = SamAutomaticMaskGenerator(sam, **generator_kwargs(params))
    if cache is not None:
        cache.wrap_predictor(gen.predictor)
    anns = gen.generate(image)
    if not anns:
        return np.zeros((0,) + image.shape[:2], bool), np.zeros(0)
    return np.stack([a["segmentation"] for a in anns]), np.array([a["predicted_iou"] for a in anns])


def match(a: np.ndarray, b: np.ndarray) -> dict:
    """Hungarian matching of two mask sets by IoU."""
    from scipy.optimize import linear_sum_assignment

    if len(a) == 0 or len(b) == 0:
        return {"n_off": len(a), "n_r360": len(b), "matched": 0, "mean_iou": float("nan"), "min_iou": float("nan"),
                "identical": 0}
    fa = a.reshape(len(a), -1).astype(np.float32)
    fb = b.reshape(len(b), -1).astype(np.float32)
    inter = fa @ fb.T
    union = fa.sum(1)[:, None] + fb.sum(1)[None, :] - inter
    iou = np.where(union > 0, inter / np.maximum(union, 1), 1.0)
    ri, ci = linear_sum_assignment(-iou)
    m = iou[ri, ci]
    return {"n_off": len(a), "n_r360": len(b), "matched": int((m > 0.5).sum()), "mean_iou": float(m.mean()),
            "min_iou": float(m.min()), "identical": int(sum(np.array_equal(a[i], b[j]) for i, j in zip(ri, ci)))}


def images(rng):
    """Deterministic synthetic RGB scenes, (name, uint8 image): shapes on a gradient with
    noise (landscape and portrait) and uniform noise."""
    import cv2

    out = []
    for h, w in ((240, 320), (300, 200)):
        yy, xx = np.mgrid[0:h, 0:w]
        img = np.stack([xx * 200 / w, yy * 200 / h, np.full((h, w), 90.0)], -1)
        img = img.astype(np.uint8).copy()
        for _ in range(6):
            c = tuple(int(v) for v in rng.integers(0, 256, 3))
            if rng.random() < 0.5:
                cv2.circle(img, (int(rng.integers(0, w)), int(rng.integers(0, h))), int(rng.integers(10, 60)), c, -1)
            else:
                x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
                cv2.rectangle(img, (x, y), (x + int(rng.integers(10, 90)), y + int(rng.integers(10, 90))), c, -1)
        img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
        out.append((f"shapes{h}x{w}", img))
    out.append(("noise210x280", rng.integers(0, 256, (210, 280, 3), dtype=np.uint8)))
    return out


def check_models(sam, enc_path, dec_path, imgs, rng) -> list[bool]:
    import torch

    from r360gpu.probes.onnx_models import SamModels
    from r360gpu.probes.preprocess import as_rgb01, sam_encoder_input, sam_logits_to_image

    out = []
    print("2. pre- and post-processing")
    models = SamModels(enc_path, dec_path)
    pred = TorchSamModels(sam).predictor
    for _, img in imgs:
        pred.set_image(img)
        t_in = pred.model.preprocess(
            torch.as_tensor(pred.transform.apply_image(img)).permute(2, 0, 1)[None].float()
        ).numpy()
        r_in, size = sam_encoder_input(as_rgb01(img), 1024)
        d = np.abs(t_in - r_in)
        out.append(report(f"encoder input {img.shape[:2]}", size == tuple(pred.input_size) and d.max() == 0,
                          f"resized size {size} vs {tuple(pred.input_size)}; max |diff| {d.max():.3g}"))
        pts = rng.uniform(0, 1, (50, 2)) * np.array([img.shape[1], img.shape[0]])
        c_off = pred.transform.apply_coords(pts, img.shape[:2])
        from r360gpu.probes.onnx_models import SamEmbedding

        emb = SamEmbedding({}, img.shape[:2], size)
        c_r = models.to_model_coords(emb, pts)
        out.append(report(f"decoder point coordinates {img.shape[:2]}", np.abs(c_off - c_r).max() < 1e-4,
                          f"max |diff| {np.abs(c_off - c_r).max():.2g} px (float32 feed)"))
        low = rng.normal(0, 4, (5, 256, 256)).astype(np.float32)
        up_off = pred.model.postprocess_masks(torch.from_numpy(low)[:, None], size, img.shape[:2])[:, 0].numpy()
        up_r = sam_logits_to_image(low, 1024, size, img.shape[:2])
        d = np.abs(up_off - up_r)
        flips = (up_off > 0) != (up_r > 0)
        # cv2's bilinear and torch's round differently (float32): masks may only
        # differ where the logit is within that rounding of the threshold.
        out.append(report(f"low-res logits -> image {img.shape[:2]}",
                          d.max() < 1e-3 and not (flips & (np.abs(up_off) > d.max())).any(),
                          f"max |diff| {d.max():.2g}; {int(flips.sum())} of {flips.size} thresholded pixels differ, "
                          f"each with |logit| <= that"))

    print("3. ONNX export vs torch modules")
    img = imgs[0][1]
    pred.set_image(img)
    emb_r = models.embed(img)
    t_emb = pred.features.numpy()
    o_emb = emb_r.features["image_embeddings"]
    d = np.abs(t_emb - o_emb).max() / np.abs(t_emb).max()
    out.append(report("image embedding (same image through each side's preprocessing)", d < 1e-2, f"max rel diff {d:.2g}"))
    pts = np.array([[50.0, 60.0], [200.0, 100.0], [10.0, 230.0]])
    t = TorchSamModels(sam)
    t.embed(as_rgb01(img))
    d_t = t.predict_points(SamEmbedding({}, img.shape[:2], tuple(pred.input_size)), pts)
    d_o = models.predict_points(emb_r, pts)
    lo, io = d_o.multimask()
    dl = np.abs(d_t.logits - lo).max()
    di = np.abs(d_t.iou - io).max()
    out.append(report("decoder multimask logits / IoU (3 points)", dl < 0.05 * np.abs(d_t.logits).max() and di < 1e-2,
                      f"max |logit diff| {dl:.3g} of range {np.abs(d_t.logits).max():.3g}; max |iou diff| {di:.2g}"))
    return out


def generator_configs(pps: int):
    """The parameter sets both generators get.

    Random weights give mask logits within about +-0.3 whose 0-level sets
    cover 40-90 % of the image with full-image boxes, so at SAM's defaults
    (threshold 0, offset 1, thresholds 0.88 / 0.95) nothing is kept and at 0
    box NMS keeps one mask.  At a mask threshold of 0.2 (the official
    generator reads it from ``Sam.mask_threshold``) masks are localised
    (median box 17 % of the image) and with a stability offset of 0.003 --
    the logits' scale -- tens of masks survive every filter; the IoU and
    stability thresholds still remove a large share (printed as counts).
    """
    from r360gpu.probes.sam_amg import AmgParams

    common = dict(points_per_side=pps, mask_threshold=0.2, stability_score_offset=0.003, pred_iou_thresh=0.02)
    return [
        AmgParams(**common, stability_score_thresh=0.5, box_nms_thresh=0.7),
        AmgParams(**common, stability_score_thresh=0.4, box_nms_thresh=0.6, crop_n_layers=1,
                  crop_n_points_downscale_factor=2, min_mask_region_area=12),
    ]


def logit_margin(sam, onnx_models, torch_models, img, p) -> str:
    """Where the ONNX masks may differ from torch's: the same grid decoded by both
    on the whole image; D = max |logit diff| after upsampling; every mask pixel
    that differs must have a torch logit within D of the mask threshold, and
    every keep decision that differs must be within the score differences of
    its threshold."""
    from r360gpu.probes import amg_utils as au

    h, w = img.shape[:2]
    pts = au.build_all_layer_point_grids(p.points_per_side, 0, 1)[0] * np.array([w, h], np.float64)
    from r360gpu.probes.preprocess import as_rgb01

    e_t = torch_models.embed(as_rgb01(img))  # as generate_masks passes it (float 0..1)
    e_o = onnx_models.embed(as_rgb01(img))
    d_t = torch_models.predict_points(e_t, pts)
    d_o = onnx_models.predict_points(e_o, pts)
    lo_o, iou_o = d_o.multimask()
    lo_t, iou_t = d_t.multimask()
    lo_t = lo_t.reshape((-1,) + lo_t.shape[2:])
    lo_o = lo_o.reshape((-1,) + lo_o.shape[2:])
    # In chunks: SAM's postprocess_masks goes through a 1024 x 1024 frame (3 GB for 768 masks at once).
    d, n_diff, n_far, n_px, s_t, s_o = 0.0, 0, 0, 0, [], []
    chunks = []
    for start in range(0, len(lo_t), 64):
        up_t = torch_models.logits_to_image(e_t, lo_t[start : start + 64], True)
        up_o = onnx_models.logits_to_image(e_o, lo_o[start : start + 64], True)
        d = max(d, float(np.abs(up_t - up_o).max()))
        s_t.append(au.stability_score(up_t, p.mask_threshold, p.stability_score_offset))
        s_o.append(au.stability_score(up_o, p.mask_threshold, p.stability_score_offset))
        chunks.append(((up_t > p.mask_threshold) != (up_o > p.mask_threshold), np.abs(up_t - p.mask_threshold)))
    for diff_c, dist_c in chunks:  # D is known only after the last chunk
        n_diff += int(diff_c.sum())
        n_far += int((diff_c & (dist_c > d)).sum())
        n_px += diff_c.size
    s_t, s_o = np.concatenate(s_t), np.concatenate(s_o)
    di = float(np.abs(iou_t - iou_o).max())
    keep_t = (iou_t.reshape(-1) > p.pred_iou_thresh) & (s_t >= p.stability_score_thresh)
    keep_o = (iou_o.reshape(-1) > p.pred_iou_thresh) & (s_o >= p.stability_score_thresh)
    ds = float(np.abs(s_t - s_o).max())
    flip = np.flatnonzero(keep_t != keep_o)
    flip_explained = all(
        abs(float(iou_t.reshape(-1)[i]) - p.pred_iou_thresh) <= di or abs(float(s_t[i]) - p.stability_score_thresh) <= ds
        for i in flip
    )
    ok = n_far == 0 and flip_explained
    return ok, (f"logits max |diff| D={d:.2g}; {n_diff} of {n_px} mask pixels differ, "
            f"{'all' if n_far == 0 else 'NOT all'} with |logit - thr| <= D; "
            f"iou max |diff| {di:.2g}, stability max |diff| {ds:.2g}; keep decisions differ for {len(flip)} of "
            f"{len(keep_t)} masks{' (each within those diffs of its threshold)' if flip_explained else ' (NOT explained)'}")


def print_configs(configs) -> None:
    """One line per generator configuration, then the header of the mask-set table."""
    for k, p in enumerate(configs):
        print(f"   config {k}: points {p.points_per_side}, mask_threshold {p.mask_threshold}, pred_iou_thresh "
              f"{p.pred_iou_thresh}, stability >= {p.stability_score_thresh} (offset {p.stability_score_offset}), "
              f"box_nms {p.box_nms_thresh}, crop_n_layers {p.crop_n_layers} (points / "
              f"{p.crop_n_points_downscale_factor}), min_mask_region_area {p.min_mask_region_area}")
    print("   image        cfg | official | r360 on torch model: n, IoU==1 pairs, min IoU | "
          "r360 on ONNX: n, IoU==1 pairs, IoU>0.5, mean / min IoU")


def check_generators(sam, enc_path, dec_path, imgs, pps, margins_only=False) -> list[bool]:
    from r360gpu.probes.onnx_models import SamModels
    from r360gpu.probes.sam_amg import generate_masks

    out = []
    print("4. whole mask sets: SamAutomaticMaskGenerator vs r360gpu generate_masks")
    cache = EmbeddingCache()
    onnx_models = SamModels(enc_path, dec_path)
    cache.wrap_models(onnx_models)
    torch_models = TorchSamModels(sam)
    cache.wrap_predictor(torch_models.predictor)
    configs = generator_configs(pps)
    print_configs(configs)
    for name, img in imgs:
        for k, p in enumerate([] if margins_only else configs):
            t0 = time.perf_counter()
            m_off, _ = official_generate(sam, img, p, cache)
            t1 = time.perf_counter()
            r_t = generate_masks(torch_models, img, p)
            t2 = time.perf_counter()
            r_o = generate_masks(onnx_models, img, p)
            t3 = time.perf_counter()
            a = match(m_off, r_t.masks)
            b = match(m_off, r_o.masks)
            print(f"   {name:12s} {k:3d} | {a['n_off']:8d} | {a['n_r360']:3d}, {a['identical']:3d}, "
                  f"{a['min_iou']:.4f} | {b['n_r360']:3d}, {b['identical']:3d}, {b['matched']:3d}, "
                  f"{b['mean_iou']:.4f} / {b['min_iou']:.4f}   ({t1 - t0:.0f} s / {t2 - t1:.0f} s / {t3 - t2:.0f} s)")
            out.append(report(f"{name} config {k}: r360gpu's algorithm on the torch model gives the official mask set",
                              a["n_off"] > 0 and a["n_off"] == a["n_r360"] == a["identical"],
                              f"{a['n_off']} masks, {a['identical']} identical pairs"))
        ok, text = logit_margin(sam, onnx_models, torch_models, img, configs[0])
        out.append(report(f"{name}: ONNX masks differ from torch's only within float32 margins (config 0 grid)", ok, text))
    print(f"   (encoder cache: {cache.misses} encodes, {cache.hits} reuses)")
    return out


def use_torchvision_or_standin() -> str:
    """The installed torchvision, or bench/torchvision_standin when its compiled ops do not load."""
    try:
        import torchvision.ops  # noqa: F401

        return "torchvision " + __import__("torchvision").__version__
    except Exception as exc:  # noqa: BLE001 - a CUDA wheel beside a CPU torch raises RuntimeError
        for name in [m for m in sys.modules if m == "torchvision" or m.startswith("torchvision.")]:
            del sys.modules[name]
        sys.path.insert(0, str(HERE / "torchvision_standin"))
        import torchvision.ops  # noqa: F401

        return f"bench/torchvision_standin (installed torchvision failed: {str(exc).splitlines()[0][:80]})"


def main() -> int:
    args = parse_args()
    tv = use_torchvision_or_standin()
    sys.path.insert(0, str(Path(args.sam_src).resolve()))
    sys.path.insert(0, str(Path(args.samexporter_src).resolve()))
    import torch

    torch.set_num_threads(max(1, (os.cpu_count() or 2)))
    rng = np.random.default_rng(args.seed)
    print(f"torch {torch.__version__}; {tv}; segment_anything from {args.sam_src}; seed {args.seed}")
    results = check_steps(rng)
    if not args.quick:
        sam = build_sam(args.seed)
        t0 = time.perf_counter()
        enc, dec = export_onnx(sam, Path(args.work))
        print(f"   (ONNX export {time.perf_counter() - t0:.0f} s: {enc.name}, {dec.name})")
        imgs = images(rng)
        results += check_models(sam, enc, dec, imgs, rng)
        results += check_generators(sam, enc, dec, imgs, args.points_per_side, args.margins_only)
    print(f"summary: {sum(results)} of {len(results)} checks agree")
    return 0 if all(results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
