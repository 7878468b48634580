"""Parity of r360gpu's automatic mask generator on SAM 2 exports with SAM 2's own, without model weights.

Builds SAM 2.1 Hiera-Tiny (the ``sam2`` package of Grounded-SAM-2, config
``configs/sam2.1/sam2.1_hiera_t.yaml``) with random weights (fixed seed),
exports encoder and decoder to ONNX as samexporter's ``export_sam2.py`` does
(its ``SAM2ImageEncoder`` / ``SAM2ImageDecoder`` with multimask output), and
compares:

1. pre- and post-processing: encoder input tensor (``SAM2Transforms``),
   decoder point coordinates (``transform_coords``), low-res logits -> image
   (``postprocess_masks``);
2. the ONNX encoder / decoder against the torch model;
3. whole mask sets: ``SAM2AutomaticMaskGenerator.generate`` against
   r360gpu's ``generate_masks`` (a) driven by the official
   ``SAM2ImagePredictor`` (the algorithm alone) and (b) on the exported ONNX
   pair, with the same parameters on the same images (made by
   bench/parity_sam.py's generator, here drawn first from the seed): counts
   and the Hungarian matching of masks by IoU.

Needs torch, hydra-core, iopath, onnx, onnxruntime, opencv, scipy and the
fetched sources (never committed); torchvision is replaced by
bench/torchvision_standin when it does not load:

    git --git-dir=<mirror of IDEA-Research/Grounded-SAM-2> archive HEAD sam2 | tar -x -C /tmp/gsam2-src
    nice -n 19 python bench/parity_sam2.py --gsam2-src /tmp/gsam2-src \
        --samexporter-src /tmp/samexporter-src [--work /tmp/probes-parity] [--images shapes240x320]

(the sam2 folder must include sam2/configs).  On CPU the hole / sprinkle
filling of SAM 2's predictor is skipped (its CUDA extension does not load),
as it is in r360gpu.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import parity_sam as P  # noqa: E402  (shared helpers: report, match, images, the torchvision fallback)

CONFIG = "configs/sam2.1/sam2.1_hiera_t.yaml"
# Chosen from --explore (see generator_configs).
MASK_THRESHOLD = 0.25
STABILITY_OFFSET = 0.005
PRED_IOU_THRESH = 0.5


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gsam2-src", required=True, help="folder holding Grounded-SAM-2's sam2 package (with configs)")
    P.add_model_args(ap)
    ap.add_argument("--images", default="shapes240x320,noise210x280",
                    help="comma-separated names of parity_sam.py's images (default: one structured, one noise)")
    ap.add_argument("--explore", action="store_true", help="print logit / score distributions and stop")
    return ap.parse_args()


def build_sam2(seed: int):
    import torch
    from sam2.build_sam import build_sam2 as build

    torch.manual_seed(seed)
    return build(CONFIG, ckpt_path=None, device="cpu", mode="eval")


def export_onnx(model, work: Path) -> tuple[Path, Path]:
    """samexporter export_sam2.py: encoder input 'image' (1, 3, 1024, 1024), outputs
    high_res_feats_0/1 + image_embed; decoder multimask, low-res masks, dynamic prompt counts."""
    import torch
    from samexporter.export_sam2 import SAM2ImageDecoder, SAM2ImageEncoder

    work.mkdir(parents=True, exist_ok=True)
    enc_path, dec_path = work / "sam2.1_hiera_t_random.encoder.onnx", work / "sam2.1_hiera_t_random.decoder.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        img = torch.randn(1, 3, 1024, 1024)
        enc = SAM2ImageEncoder(model).cpu()
        f0, f1, emb = enc(img)
        torch.onnx.export(enc, img, str(enc_path), export_params=True, opset_version=18, do_constant_folding=True,
                          input_names=["image"], output_names=["high_res_feats_0", "high_res_feats_1", "image_embed"],
                          dynamo=False)
        dec = SAM2ImageDecoder(model, multimask_output=True).cpu()
        embed = model.image_size // model.backbone_stride
        args = (emb, f0, f1, torch.randint(0, 1024, (1, 5, 2), dtype=torch.float),
                torch.randint(0, 1, (1, 5), dtype=torch.float), torch.randn(1, 1, 4 * embed, 4 * embed),
                torch.tensor([1], dtype=torch.float))
        torch.onnx.export(dec, args, str(dec_path), export_params=True, opset_version=18, do_constant_folding=True,
                          input_names=["image_embed", "high_res_feats_0", "high_res_feats_1", "point_coords",
                                       "point_labels", "mask_input", "has_mask_input"],
                          output_names=["masks", "iou_predictions"],
                          dynamic_axes={"point_coords": {0: "num_labels", 1: "num_points"},
                                        "point_labels": {0: "num_labels", 1: "num_points"},
                                        "mask_input": {0: "num_labels"}, "has_mask_input": {0: "num_labels"}},
                          dynamo=False)
    return enc_path, dec_path


class TorchSam2Models:
    """SAM 2's torch predictor behind r360gpu's SamModels interface (variant "sam2"), so that
    r360gpu's generate_masks runs the algorithm on the official model outputs."""

    variant = "sam2"

    def __init__(self, model, cache=None):
        from sam2.sam2_image_predictor import SAM2ImagePredictor

        self.predictor = SAM2ImagePredictor(model)
        self.cache = cache

        class _P:
            path = "torch-sam2"

        self.decoder = _P()

    def embed(self, image01):
        from r360gpu.probes.onnx_models import SamEmbedding
        from r360gpu.probes.preprocess import as_rgb01, to_uint8

        u8 = to_uint8(as_rgb01(image01))  # uint8 or float 0..1, as SamModels.embed; exact for uint8 sources
        set_image(self.predictor, u8, self.cache)
        return SamEmbedding({}, tuple(u8.shape[:2]), (1024, 1024))

    def predict_points(self, embedding, points_xy):
        import torch

        from r360gpu.probes.onnx_models import Decoded

        # As SAM2AutomaticMaskGenerator._process_batch: float32 points, normalised by the crop size.
        pts = torch.as_tensor(np.asarray(points_xy), dtype=torch.float32)
        coords = self.predictor._transforms.transform_coords(pts, normalize=True, orig_hw=embedding.image_size)
        labels = torch.ones(len(pts), dtype=torch.int)
        with torch.no_grad():
            low, iou = self._decode(coords[:, None, :], labels[:, None])
        return Decoded(low.numpy(), iou.numpy(), True)

    def _decode(self, coords, labels):
        """SAM2ImagePredictor._predict up to the decoder: low-res logits (unclamped: _predict
        upsamples those and clamps only the low-res copy it returns) and predicted IoUs."""
        m = self.predictor.model
        sparse, dense = m.sam_prompt_encoder(points=(coords, labels), boxes=None, masks=None)
        feats = self.predictor._features
        low, iou, _, _ = m.sam_mask_decoder(
            image_embeddings=feats["image_embed"][0].unsqueeze(0),
            image_pe=m.sam_prompt_encoder.get_dense_pe(),
            sparse_prompt_embeddings=sparse,
            dense_prompt_embeddings=dense,
            multimask_output=True,
            repeat_image=coords.shape[0] > 1,
            high_res_features=[f[0].unsqueeze(0) for f in feats["high_res_feats"]],
        )
        return low, iou

    def logits_to_image(self, embedding, logits, low_res):
        import torch

        with torch.no_grad():
            up = self.predictor._transforms.postprocess_masks(
                torch.from_numpy(np.asarray(logits, np.float32))[:, None], embedding.image_size
            )
        return up[:, 0].numpy()


def set_image(predictor, image, cache):
    """SAM2ImagePredictor.set_image, memoised by the exact pixels (see parity_sam.EmbeddingCache).
    Calls the class's method, so a predictor whose set_image is wrapped (wrap_generator) does not recurse."""
    from sam2.sam2_image_predictor import SAM2ImagePredictor

    if cache is None:
        SAM2ImagePredictor.set_image(predictor, image)
        return
    k = ("sam2-torch",) + cache.key(image)
    if k in cache.store:
        cache.hits += 1
        predictor.reset_predictor()
        predictor._features, predictor._orig_hw = cache.store[k]
        predictor._is_image_set = True
        return
    cache.misses += 1
    SAM2ImagePredictor.set_image(predictor, image)
    cache.store[k] = (predictor._features, list(predictor._orig_hw))


def wrap_generator(gen, cache) -> None:
    gen.predictor.set_image = lambda image: set_image(gen.predictor, image, cache)


def official_generate(model, image, params, cache):
    from sam2.automatic_mask_generator import SAM2AutomaticMaskGenerator

    gen = SAM2AutomaticMaskGenerator(model, mask_threshold=params.mask_threshold, **P.generator_kwargs(params))
    wrap_generator(gen, cache)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the CUDA hole-filling extension is absent on CPU
        anns = gen.generate(image)
    if not anns:
        return np.zeros((0,) + image.shape[:2], bool)
    return np.stack([a["segmentation"] for a in anns])


def explore(model, imgs, pps):
    """Distributions that the thresholds of generator_configs were chosen from."""
    import torch

    from r360gpu.probes import amg_utils as au

    t = TorchSam2Models(model)
    for name, img in imgs[:1]:
        emb = t.embed(img)
        pts = au.build_all_layer_point_grids(pps, 0, 1)[0] * np.array([img.shape[1], img.shape[0]])
        d = t.predict_points(emb, pts)
        up = t.logits_to_image(emb, d.logits.reshape((-1,) + d.logits.shape[2:]), True)
        iou = d.iou.reshape(-1)
        print(name, "iou pct", np.percentile(iou, [0, 10, 50, 90, 100]).round(3),
              "|logit| pct", np.percentile(np.abs(up[::5]), [50, 90, 99, 100]).round(3))
        for thr in (0.0, 0.15, 0.2, 0.25):
            m = torch.from_numpy(up > thr)
            boxes = au.masks_to_boxes(m.numpy())
            area = ((boxes[:, 2] - boxes[:, 0] + 1) * (boxes[:, 3] - boxes[:, 1] + 1)) / (img.shape[0] * img.shape[1])
            print(f"   thr {thr:.3f}: pixel frac {np.percentile(m.float().mean((1, 2)).numpy(), [10, 50, 90]).round(3)}"
                  f" box frac {np.percentile(area, [10, 50, 90]).round(3)}")
            for off in (0.003, 0.005, 0.01, 0.05):
                s = au.stability_score(up, float(thr), off)
                keep = s >= 0.5
                k = au.nms(boxes[keep], iou[keep], 0.7) if keep.any() else []
                print(f"      offset {off}: stability pct {np.percentile(s, [10, 50, 90]).round(3)}, "
                      f">=0.5: {int(keep.sum())}, after NMS 0.7: {len(k)}")


def generator_configs(pps: int):
    """Both generators get these.  Random weights give logits within about
    +-0.45 and predicted IoUs of 0.47-0.55 (``--explore`` prints them); at a
    mask threshold of 0 every mask has a full-image box and box NMS keeps
    one.  At 0.25 (offset 0.005) masks are localised and tens survive NMS;
    the IoU threshold 0.5 removes about 40 % of them."""
    from r360gpu.probes.sam_amg import AmgParams

    common = dict(points_per_side=pps, mask_threshold=MASK_THRESHOLD, stability_score_offset=STABILITY_OFFSET,
                  pred_iou_thresh=PRED_IOU_THRESH)
    return [
        AmgParams(**common, stability_score_thresh=0.5, box_nms_thresh=0.7),
        AmgParams(**common, stability_score_thresh=0.4, box_nms_thresh=0.6, crop_n_layers=1,
                  crop_n_points_downscale_factor=2, min_mask_region_area=12),
    ]


def check_models(model, enc_path, dec_path, imgs, rng) -> list[bool]:
    import torch

    from r360gpu.probes.onnx_models import SamEmbedding, SamModels
    from r360gpu.probes.preprocess import as_rgb01, resize_logits, sam2_encoder_input

    out = []
    print("1. pre- and post-processing")
    models = SamModels(enc_path, dec_path)
    t = TorchSam2Models(model)
    tr = t.predictor._transforms
    for _, img in imgs:
        ref = tr(img)[None].numpy()
        r = sam2_encoder_input(as_rgb01(img), (1024, 1024))
        d = float(np.abs(ref - r).max())
        out.append(P.report(f"encoder input {img.shape[:2]}", d < 1e-5,
                            f"max |diff| {d:.2g} (float32 antialiased resize, summed in another order than torch's)"))
        pts = rng.uniform(0, 1, (50, 2)) * np.array([img.shape[1], img.shape[0]])
        c_off = tr.transform_coords(torch.as_tensor(pts, dtype=torch.float32), normalize=True,
                                    orig_hw=img.shape[:2]).numpy()
        c_r = models.to_model_coords(SamEmbedding({}, img.shape[:2], (1024, 1024)), pts)
        dc = float(np.abs(c_off - c_r).max())
        out.append(P.report(f"decoder point coordinates {img.shape[:2]}", dc == 0,
                            f"max |diff| {dc:.2g} px (float32 x / w * 1024 on both sides)"))
        low = rng.normal(0, 4, (5, 256, 256)).astype(np.float32)
        up_off = tr.postprocess_masks(torch.from_numpy(low)[:, None], img.shape[:2])[:, 0].numpy()
        up_r = resize_logits(low, img.shape[:2])
        d = np.abs(up_off - up_r)
        flips = (up_off > 0) != (up_r > 0)
        out.append(P.report(f"low-res logits -> image {img.shape[:2]}",
                            d.max() < 1e-3 and not (flips & (np.abs(up_off) > d.max())).any(),
                            f"max |diff| {d.max():.2g}; {int(flips.sum())} thresholded pixels differ, each with "
                            f"|logit| <= that"))
    print("2. ONNX export vs torch model")
    img = imgs[0][1]
    emb_o = models.embed(img)
    emb_t = t.embed(as_rgb01(img))
    feats = t.predictor._features
    for name, ref in (("image_embed", feats["image_embed"]), ("high_res_feats_0", feats["high_res_feats"][0]),
                      ("high_res_feats_1", feats["high_res_feats"][1])):
        ref = ref.numpy()
        d = float(np.abs(ref - emb_o.features[name]).max() / np.abs(ref).max())
        out.append(P.report(f"{name} (same image through each side's preprocessing)", d < 1e-3, f"max rel diff {d:.2g}"))
    pts = np.array([[50.0, 60.0], [200.0, 100.0], [10.0, 230.0]])
    d_t = t.predict_points(emb_t, pts)
    d_o = models.predict_points(emb_o, pts)
    lo, io = d_o.multimask()
    dl = float(np.abs(np.clip(d_t.logits, -32, 32) - lo).max())
    di = float(np.abs(d_t.iou - io).max())
    out.append(P.report("decoder multimask logits / IoU (3 points)", dl < 1e-2 * np.abs(d_t.logits).max() and di < 1e-3,
                        f"max |logit diff| {dl:.3g} of range {np.abs(d_t.logits).max():.3g}; max |iou diff| {di:.2g}"))
    return out


def check_generators(model, enc_path, dec_path, imgs, pps) -> list[bool]:
    from r360gpu.probes.onnx_models import SamModels
    from r360gpu.probes.sam_amg import generate_masks

    out = []
    print("3. whole mask sets: SAM2AutomaticMaskGenerator vs r360gpu generate_masks")
    cache = P.EmbeddingCache()
    onnx_models = SamModels(enc_path, dec_path)
    cache.wrap_models(onnx_models)
    torch_models = TorchSam2Models(model, cache)
    configs = generator_configs(pps)
    P.print_configs(configs)
    for name, img in imgs:
        for k, p in enumerate(configs):
            t0 = time.perf_counter()
            m_off = official_generate(model, img, p, cache)
            t1 = time.perf_counter()
            r_t = generate_masks(torch_models, img, p)
            t2 = time.perf_counter()
            r_o = generate_masks(onnx_models, img, p)
            t3 = time.perf_counter()
            a = P.match(m_off, r_t.masks)
            b = P.match(m_off, r_o.masks)
            print(f"   {name:12s} {k:3d} | {a['n_off']:8d} | {a['n_r360']:3d}, {a['identical']:3d}, "
                  f"{a['min_iou']:.4f} | {b['n_r360']:3d}, {b['identical']:3d}, {b['matched']:3d}, "
                  f"{b['mean_iou']:.4f} / {b['min_iou']:.4f}   ({t1 - t0:.0f} s / {t2 - t1:.0f} s / {t3 - t2:.0f} s)")
            out.append(P.report(f"{name} config {k}: r360gpu's algorithm on the torch model gives the official mask set",
                                a["n_off"] > 0 and a["n_off"] == a["n_r360"] == a["identical"],
                                f"{a['n_off']} masks, {a['identical']} identical pairs"))
        ok, text = P.logit_margin(model, onnx_models, torch_models, img, configs[0])
        out.append(P.report(f"{name}: ONNX masks differ from torch's only within float32 margins (config 0 grid)",
                            ok, text))
    print(f"   (encoder cache: {cache.misses} encodes, {cache.hits} reuses)")
    return out


def main() -> int:
    args = parse_args()
    tv = P.use_torchvision_or_standin()
    sys.path.insert(0, str(Path(args.gsam2_src).resolve()))
    sys.path.insert(0, str(Path(args.samexporter_src).resolve()))
    import torch

    torch.set_num_threads(max(1, (os.cpu_count() or 2)))
    rng = np.random.default_rng(args.seed)
    print(f"torch {torch.__version__}; {tv}; sam2 from {args.gsam2_src} ({CONFIG}); seed {args.seed}")
    model = build_sam2(args.seed)
    wanted = args.images.split(",")
    imgs = [(n, im) for n, im in P.images(rng) if n in wanted]  # a CPU run takes ~15 min per image
    if len(imgs) != len(wanted):
        raise SystemExit(f"--images: choose from {[n for n, _ in P.images(np.random.default_rng(args.seed))]}")
    if args.explore:
        explore(model, imgs, args.points_per_side)
        return 0
    t0 = time.perf_counter()
    enc, dec = export_onnx(model, Path(args.work))
    print(f"   (ONNX export {time.perf_counter() - t0:.0f} s: {enc.name}, {dec.name})")
    results = check_models(model, enc, dec, imgs, rng)
    results += check_generators(model, enc, dec, imgs, args.points_per_side)
    print(f"summary: {sum(results)} of {len(results)} checks agree")
    return 0 if all(results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
