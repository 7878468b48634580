"""r360gpu's model-based inpainting metrics against the libraries the 360-USID script runs.

On random images (several sizes, odd ones included) and random masks with fractional values,
in one run and one process:

1. LPIPS VGG, plain and spatial, both input conventions (``normalize`` True / False; the
   360-USID script feeds [0, 1] images without it): r360gpu's ``LpipsModel`` on the ONNX
   exports against ``lpips.LPIPS`` in torch, and ``masked_lpips`` against the script's
   ``sum(map * mask) / sum(mask)`` on ``to_tensor`` masks with values above 0.5 set to 1;
2. Inception pool3 features: ``InceptionModel`` on the export against pytorch-fid's
   ``get_activations`` on the same PNG files (images of two sizes, neither 299), beside the
   floor set by rounding: torch against itself with its inputs moved by ~1 float32 ulp;
3. FID: r360gpu (``fid_image_files`` + ``InceptionModel`` + ``fid_from_features``) against
   ``pytorch_fid.fid_score.calculate_fid_given_paths([ref, out], 50, "cpu", 2048, 0)``, the
   360-USID script's call, end to end; and ``fid_from_features`` against
   ``calculate_frechet_distance`` on the same (torch) features;
4. KID: ``kid_from_features`` against torchmetrics' ``poly_mmd`` on the same subsets, and
   against ``KernelInceptionDistance`` where every subset is the whole set.

The networks have random weights (``bench/export_inpaint_models.py --random-weights``,
exported here unless ``--models`` holds them); pytorch-fid is given the same Inception weights
through its loader.  Prints the largest differences (absolute, and relative to the values'
scale) and the time ratios (torch / r360gpu; both on the CPU, torch with its default threads,
onnxruntime with its own).

Needs a throwaway environment with CPU torch, lpips, pytorch-fid, torchmetrics, onnx and
r360gpu's own dependencies (opencv, onnxruntime, scipy, wgpu):

    /tmp/torch-env/bin/python bench/inpaint_models_vs_peers.py --work /tmp/inpaint-peers
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import export_inpaint_models as ex  # noqa: E402

from r360gpu.metrics.fid import fid_from_features, fid_image_files, kid_from_features  # noqa: E402
from r360gpu.metrics.fidelity import LpipsModel, masked_lpips  # noqa: E402
from r360gpu.probes.inception import InceptionModel  # noqa: E402

LPIPS_SIZES = [(64, 64), (97, 131), (131, 97), (256, 192), (37, 301), (480, 270)]
REF_SIZE, OUT_SIZE = (90, 120), (67, 101)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, default=Path("/tmp/inpaint-peers"), help="exports and image folders")
    ap.add_argument("--models", type=Path, help="a folder with the random-weight exports (default: export into --work)")
    ap.add_argument("--n-ref", type=int, default=12, help="reference images for FID / KID")
    ap.add_argument("--n-out", type=int, default=10, help="method images for FID / KID")
    ap.add_argument("--seed", type=int, default=0)
    return ap.parse_args()


def row(name: str, diff: float, scale: float, t_ours: float | None = None, t_peer: float | None = None) -> None:
    rel = diff / scale if scale else float("nan")
    timing = ""
    if t_ours is not None and t_peer is not None:
        timing = f"   r360gpu {t_ours:8.3f} s  peer {t_peer:8.3f} s  peer/r360gpu {t_peer / t_ours:6.2f}x"
    print(f"  {name:<44} max |diff| {diff:.3e}  relative {rel:.3e}{timing}")


def to_tensor(img):
    import torchvision.transforms.functional as tf

    return tf.to_tensor(img).unsqueeze(0)


def pair(rng, h, w):
    x = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    noise = rng.normal(0, 40, (h, w, 3))
    y = np.clip(x + noise, 0, 255).astype(np.uint8)
    return x, y


def random_mask(rng, h, w):
    """Blobs of 0, fractional values at and around 0.5, and 255."""
    levels = np.array([0, 0, 40, 127, 128, 200, 255, 255], np.uint8)
    coarse = rng.integers(0, len(levels), (-(-h // 8), -(-w // 8)))
    return levels[np.kron(coarse, np.ones((8, 8), int))[:h, :w]]


def check_lpips(models: dict, rng, seed: int) -> None:
    import lpips  # noqa: F401  (the peer's classes come through the export module)
    import torch

    print("1. LPIPS VGG (random weights)")
    plain_t = ex.lpips_network(False, True, seed=seed)
    spatial_t = ex.lpips_network(True, True, seed=seed)
    plain = LpipsModel(models["lpips"])
    spatial = LpipsModel(models["lpips_spatial"])
    pairs = [pair(rng, h, w) for h, w in LPIPS_SIZES]
    masks = [random_mask(rng, h, w) for h, w in LPIPS_SIZES]
    for normalize in (True, False):
        d_plain = d_map = d_masked = 0.0
        s_plain = s_map = s_masked = 0.0
        t_ours = t_peer = ts_ours = ts_peer = 0.0
        for (x, y), m in zip(pairs, masks):
            t0 = time.perf_counter()
            ours = plain.distance(x, y, normalize=normalize)
            t1 = time.perf_counter()
            with torch.no_grad():
                theirs = float(plain_t(to_tensor(x), to_tensor(y), normalize=normalize))
            t2 = time.perf_counter()
            t_ours += t1 - t0
            t_peer += t2 - t1
            d_plain, s_plain = max(d_plain, abs(ours - theirs)), max(s_plain, abs(theirs))
            t0 = time.perf_counter()
            omap = spatial.distance_map(x, y, normalize=normalize)
            t1 = time.perf_counter()
            with torch.no_grad():
                tmap = spatial_t(to_tensor(x), to_tensor(y), normalize=normalize)
            t2 = time.perf_counter()
            ts_ours += t1 - t0
            ts_peer += t2 - t1
            d_map = max(d_map, float(np.abs(omap - tmap[0, 0].numpy()).max()))
            s_map = max(s_map, float(tmap.abs().max()))
            # The script's arithmetic on its own tensors: to_tensor, > 0.5 -> 1, broadcast, sum / sum.
            mt = to_tensor(m)[:, :3]
            mt[mt > 0.5] = 1
            theirs_m = float(torch.sum(tmap * mt) / torch.sum(mt))
            d_masked = max(d_masked, abs(masked_lpips(omap, m) - theirs_m))
            s_masked = max(s_masked, abs(theirs_m))
        tag = "normalize=True" if normalize else "normalize=False (the script's)"
        row(f"LPIPS {tag}", d_plain, s_plain, t_ours, t_peer)
        row(f"LPIPS map {tag}", d_map, s_map, ts_ours, ts_peer)
        row(f"masked LPIPS {tag}", d_masked, s_masked)
    print(f"  ({len(pairs)} pairs: {', '.join(f'{h}x{w}' for h, w in LPIPS_SIZES)})")


def write_images(folder: Path, n: int, size, rng) -> list[np.ndarray]:
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.png"):
        old.unlink()
    imgs = []
    for i in range(n):
        # Smooth random images (upsampled noise plus a gradient): closer to photographs than white noise.
        coarse = rng.integers(0, 256, (size[0] // 6 + 2, size[1] // 6 + 2, 3)).astype(np.float64)
        img = np.asarray(Image.fromarray(coarse.astype(np.uint8)).resize((size[1], size[0]), Image.BICUBIC))
        img = np.clip(img + rng.normal(0, 12, img.shape), 0, 255).astype(np.uint8)
        Image.fromarray(img).save(folder / f"{i:03d}.png")
        imgs.append(img)
    return imgs


def read_rgb(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def check_fid_kid(models: dict, work: Path, n_ref: int, n_out: int, rng) -> None:
    import torch
    from pytorch_fid import fid_score
    from pytorch_fid.inception import InceptionV3
    from torchmetrics.image.kid import KernelInceptionDistance, poly_mmd

    print("2-4. Inception features, FID, KID (random weights)")
    ref_dir, out_dir = work / "ref", work / "out"
    write_images(ref_dir, n_ref, REF_SIZE, rng)
    write_images(out_dir, n_out, OUT_SIZE, rng)
    state = torch.load(models["inception_weights"], map_location="cpu")
    inception = InceptionModel(models["inception"])

    with ex.fid_weights_from(lambda: state):
        peer_net = InceptionV3([InceptionV3.BLOCK_INDEX_BY_DIM[2048]])
        feats_t, feats_o, t_feat_t, t_feat_o = [], [], 0.0, 0.0
        for folder in (ref_dir, out_dir):
            files = fid_image_files(folder)
            t0 = time.perf_counter()
            feats_o.append(inception.features([read_rgb(p) for p in files]))
            t1 = time.perf_counter()
            feats_t.append(fid_score.get_activations(files, peer_net, 50, 2048, "cpu", 0))
            t2 = time.perf_counter()
            t_feat_o += t1 - t0
            t_feat_t += t2 - t1
        d = max(float(np.abs(a - b).max()) for a, b in zip(feats_o, feats_t))
        scale = max(float(np.abs(b).max()) for b in feats_t)
        row(f"pool3 features ({n_ref} at {REF_SIZE}, {n_out} at {OUT_SIZE})", d, scale, t_feat_o, t_feat_t)
        # The floor: torch against itself with the inputs moved by about one float32 ulp.  A random
        # network of 20 layers amplifies rounding far more than a trained one.
        feats_moved = []
        for folder in (ref_dir, out_dir):
            batch = torch.cat([to_tensor(read_rgb(p)) for p in fid_image_files(folder)])
            with torch.no_grad():
                feats_moved.append(peer_net(batch * (1 + 1e-7))[0].flatten(1).double().numpy())
        d_floor = max(float(np.abs(a - b).max()) for a, b in zip(feats_moved, feats_t))
        row("  floor: torch vs torch, inputs x (1 + 1e-7)", d_floor, scale)

        # The script's call, end to end (its own file listing, loading, network and statistics).
        t0 = time.perf_counter()
        fid_t = float(fid_score.calculate_fid_given_paths([str(ref_dir), str(out_dir)], 50, "cpu", 2048, 0))
        t1 = time.perf_counter()
    ours = fid_from_features(
        inception.features([read_rgb(p) for p in fid_image_files(ref_dir)]),
        inception.features([read_rgb(p) for p in fid_image_files(out_dir)]),
    )
    t2 = time.perf_counter()
    print(f"  FID: r360gpu {ours.value:.6f}  pytorch-fid {fid_t:.6f}  (offset branch taken: {ours.offset_added})")
    row("FID end to end", abs(ours.value - fid_t), abs(fid_t), t2 - t1, t1 - t0)

    # The formula alone, on the same (torch) features.
    t0 = time.perf_counter()
    same = fid_from_features(*feats_t)
    t1 = time.perf_counter()
    mu1, s1 = np.mean(feats_t[0], axis=0), np.cov(feats_t[0], rowvar=False)
    mu2, s2 = np.mean(feats_t[1], axis=0), np.cov(feats_t[1], rowvar=False)
    peer = float(fid_score.calculate_frechet_distance(mu1, s1, mu2, s2))
    t2 = time.perf_counter()
    row("FID formula on the same features", abs(same.value - peer), abs(peer), t1 - t0, t2 - t1)
    moved = fid_from_features(*feats_moved)
    row("  floor: FID of torch's features, inputs x (1 + 1e-7)", abs(moved.value - same.value), abs(same.value))

    # KID: the same subsets through torchmetrics' kernel and MMD.
    subsets = 100
    kid = kid_from_features(*feats_t, subsets=subsets, subset_size=1000, seed=1)
    draw = np.random.default_rng(1)
    vals = []
    for _ in range(subsets):
        ir = draw.choice(len(feats_t[0]), kid.subset_size, replace=False)
        io = draw.choice(len(feats_t[1]), kid.subset_size, replace=False)
        vals.append(poly_mmd(torch.from_numpy(feats_t[0][ir]), torch.from_numpy(feats_t[1][io])))
    vals = torch.stack(vals)
    print(f"  KID: r360gpu {kid.mean:.6e} +- {kid.std:.3e}  torchmetrics {float(vals.mean()):.6e} +- "
          f"{float(vals.std(unbiased=False)):.3e}  (subsets of {kid.subset_size})")
    row("KID mean, same subsets (poly_mmd)", abs(kid.mean - float(vals.mean())), abs(float(vals.mean())))
    row("KID std, same subsets", abs(kid.std - float(vals.std(unbiased=False))), abs(float(vals.mean())))

    # The whole metric class where every subset is the whole set: equal set sizes.
    m = min(n_ref, n_out)
    metric = KernelInceptionDistance(feature=torch.nn.Identity(), subsets=10, subset_size=m)
    metric.update(torch.from_numpy(feats_t[0][:m]), real=True)
    metric.update(torch.from_numpy(feats_t[1][:m]), real=False)
    k_mean, _ = metric.compute()
    ours_full = kid_from_features(feats_t[0][:m], feats_t[1][:m], subsets=10)
    row(f"KID, KernelInceptionDistance ({m} vs {m})", abs(ours_full.mean - float(k_mean)), abs(float(k_mean)))


def main() -> int:
    a = parse_args()
    rng = np.random.default_rng(a.seed)
    if a.models is None:
        t0 = time.perf_counter()
        models = ex.export_all(a.work / "models", random_weights=True, seed=a.seed)
        print(f"exported the random-weight networks in {time.perf_counter() - t0:.1f} s")
    else:
        models = {
            "lpips": a.models / ex.LPIPS_FILE.format(suffix="-random"),
            "lpips_spatial": a.models / ex.LPIPS_SPATIAL_FILE.format(suffix="-random"),
            "inception": a.models / ex.INCEPTION_FILE.format(suffix="-random"),
            "inception_weights": a.models / ex.INCEPTION_RANDOM_WEIGHTS,
        }
    import torch

    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    check_lpips(models, rng, a.seed)
    check_fid_kid(models, a.work, a.n_ref, a.n_out, rng)
    return 0


if __name__ == "__main__":
    sys.exit(main())
