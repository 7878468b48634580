"""Export the networks of the inpainting metrics to ONNX: LPIPS VGG (plain and spatial) and
pytorch-fid's InceptionV3 (pool3, 2048 features).

Run it once, in a throwaway environment with CPU torch and the two libraries (none of them is
an r360gpu dependency, and nothing here runs in r360gpu's tests):

    python -m venv /tmp/torch-env
    /tmp/torch-env/bin/pip install torch torchvision lpips pytorch-fid onnx
    /tmp/torch-env/bin/python bench/export_inpaint_models.py --out models/

It writes

* ``lpips_vgg.onnx``: ``lpips.LPIPS(net="vgg")``, inputs ``in0, in1`` (N, 3, H, W), output
  ``lpips`` (N, 1, 1, 1): the whole-image distance;
* ``lpips_vgg_spatial.onnx``: ``lpips.LPIPS(net="vgg", spatial=True)``, output ``lpips_map``
  (N, 1, H, W): the map masked LPIPS weights;
* ``inception_fid.onnx``: pytorch-fid's ``InceptionV3([3])`` whole (its bilinear resize to
  299 x 299 and ``2 x - 1`` inside the graph), input ``images`` (N, 3, H, W) in [0, 1],
  output ``pool3`` (N, 2048);

all with dynamic N, H and W (opset 17, torch's TorchScript exporter).  The LPIPS graphs take
the images as ``lpips.LPIPS.forward`` does without ``normalize``: r360gpu maps [0, 1] images
to [-1, 1] itself, or feeds them unchanged where a script does (``LpipsModel``'s
``normalize``).  Give the files to r360gpu as ``LpipsModel(...)`` / ``InceptionModel(...)``.

Weights.  The libraries read them from their caches (``TORCH_HOME``, default
``~/.cache/torch``; they try a download when a file is missing there, and the script stops
with exit 2 and says where to put it when that fails): torchvision's ``vgg16-397923af.pth`` and
pytorch-fid's ``pt_inception-2015-12-05-6726825d.pth`` under ``hub/checkpoints/``; lpips's
linear layers ship inside the lpips package.  ``--vgg-weights`` / ``--fid-weights`` take
those files from a path instead.  ``--random-weights`` builds both networks with random
weights (seeded; lpips: ``LPIPS(pretrained=False, pnet_rand=True)`` with the linear layers'
weights made non-negative; Inception: the FID blocks as pytorch-fid builds them, keeping their
initialisation instead of loading the FID weights, batch norms set to the statistics of one
batch of random images) and writes the Inception weights beside the graph (``inception_fid-random.pth``) so
a peer can build the same network (bench/inpaint_models_vs_peers.py): for parity checks
only, never for scores.
"""
from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

LPIPS_FILE = "lpips_vgg{suffix}.onnx"
LPIPS_SPATIAL_FILE = "lpips_vgg_spatial{suffix}.onnx"
INCEPTION_FILE = "inception_fid{suffix}.onnx"
INCEPTION_RANDOM_WEIGHTS = "inception_fid-random.pth"
OPSET = 17


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, type=Path, help="folder the .onnx files are written to")
    ap.add_argument("--random-weights", action="store_true", help="random weights (parity checks only)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the random weights")
    ap.add_argument("--vgg-weights", type=Path, help="torchvision's vgg16 state dict (vgg16-397923af.pth)")
    ap.add_argument("--fid-weights", type=Path, help="pytorch-fid's pt_inception-2015-12-05-6726825d.pth")
    ap.add_argument("--only", choices=("lpips", "inception"), help="export only these networks")
    return ap.parse_args(argv)


def lpips_network(spatial: bool, random_weights: bool, vgg_weights: Path | None = None, seed: int = 0):
    """lpips.LPIPS(net="vgg") in eval mode, with real or seeded random weights."""
    import lpips
    import torch

    if random_weights:
        torch.manual_seed(seed)
        net = lpips.LPIPS(pretrained=False, pnet_rand=True, net="vgg", spatial=spatial, verbose=False)
        # Random linear layers can weight a layer negatively; LPIPS's trained ones are >= 0.
        with torch.no_grad():
            for lin in net.lins:
                lin.model[-1].weight.abs_()
    elif vgg_weights is not None:
        import torchvision

        net = lpips.LPIPS(pnet_rand=True, net="vgg", spatial=spatial, verbose=False)
        vgg = torchvision.models.vgg16()
        vgg.load_state_dict(torch.load(vgg_weights, map_location="cpu"))
        for part in (net.net.slice1, net.net.slice2, net.net.slice3, net.net.slice4, net.net.slice5):
            for index, layer in part.named_children():
                layer.load_state_dict(vgg.features[int(index)].state_dict())
    else:
        net = lpips.LPIPS(net="vgg", spatial=spatial, verbose=False)
    return net.eval()


@contextlib.contextmanager
def fid_weights_from(state_dict_source):
    """pytorch-fid's InceptionV3 built inside takes its FID weights from ``state_dict_source()``
    instead of its download (``pytorch_fid.inception.load_state_dict_from_url``)."""
    import pytorch_fid.inception as pi

    saved = pi.load_state_dict_from_url
    pi.load_state_dict_from_url = lambda *args, **kwargs: state_dict_source()
    try:
        yield
    finally:
        pi.load_state_dict_from_url = saved


def inception_network(random_weights: bool, fid_weights: Path | None = None, seed: int = 0):
    """(pytorch-fid's ``InceptionV3([3])`` (2048 pool3 features) in eval mode, the FID-Inception
    state dict it was built from (None for the library's own weights)).

    Random weights: the torchvision skeleton with pytorch-fid's FID blocks keeps its own
    initialisation (the loader is handed the network's own state dict)."""
    import pytorch_fid.inception as pi
    import torch

    if random_weights:
        torch.manual_seed(seed)
        built = []
        make = pi._inception_v3

        def recording(*args, **kwargs):
            built.append(make(*args, **kwargs))
            return built[-1]

        pi._inception_v3 = recording
        try:
            with fid_weights_from(lambda: built[-1].state_dict()):
                net = pi.InceptionV3([pi.InceptionV3.BLOCK_INDEX_BY_DIM[2048]])
        finally:
            pi._inception_v3 = make
        _calibrate_batch_norms(net)
        return net.eval(), {k: v.clone() for k, v in built[-1].state_dict().items()}
    if fid_weights is not None:
        state = torch.load(fid_weights, map_location="cpu")
        with fid_weights_from(lambda: state):
            return pi.InceptionV3([pi.InceptionV3.BLOCK_INDEX_BY_DIM[2048]]).eval(), state
    return pi.InceptionV3([pi.InceptionV3.BLOCK_INDEX_BY_DIM[2048]]).eval(), None


def _calibrate_batch_norms(net, images: int = 8) -> None:
    """Set every batch norm's running statistics to those of one batch of random images.

    Without it, 20 randomly initialised layers shrink the pool3 features to ~1e-8, where any
    FID agrees with any other; with it each layer's output has about unit scale on images like
    the calibration batch, as the trained network's roughly has.  The batch is smooth random
    images (upsampled noise plus a little fine noise), closer to photographs than white noise."""
    import torch
    import torch.nn.functional as F

    for m in net.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.reset_running_stats()
            m.momentum = None  # a cumulative average: after one batch, that batch's statistics
    coarse = F.interpolate(torch.rand(images, 3, 20, 20), size=(299, 299), mode="bicubic", align_corners=False)
    batch = (coarse + 0.05 * torch.randn(images, 3, 299, 299)).clamp(0, 1)
    net.train()
    with torch.no_grad():
        net(batch)
    net.eval()


def _export(module, args, path: Path, input_names, output_names, dynamic_axes) -> Path:
    import torch

    path.parent.mkdir(parents=True, exist_ok=True)
    with torch.no_grad():
        torch.onnx.export(module, args, str(path), input_names=input_names, output_names=output_names,
                          dynamic_axes=dynamic_axes, opset_version=OPSET, dynamo=False)
    return path


def export_lpips(net, path: Path, spatial: bool) -> Path:
    import torch

    class Pair(torch.nn.Module):
        def __init__(self, inner):
            super().__init__()
            self.inner = inner

        def forward(self, in0, in1):
            return self.inner(in0, in1)

    x = torch.rand(1, 3, 64, 64) * 2 - 1
    image_axes = {0: "N", 2: "H", 3: "W"}
    out = "lpips_map" if spatial else "lpips"
    axes = {"in0": image_axes, "in1": image_axes, out: image_axes if spatial else {0: "N"}}
    return _export(Pair(net), (x, x.flip(3)), path, ["in0", "in1"], [out], axes)


def export_inception(net, path: Path) -> Path:
    import torch

    class Pool3(torch.nn.Module):
        def __init__(self, inner):
            super().__init__()
            self.inner = inner

        def forward(self, images):
            return self.inner(images)[0].flatten(1)

    x = torch.rand(2, 3, 120, 160)
    axes = {"images": {0: "N", 2: "H", 3: "W"}, "pool3": {0: "N"}}
    return _export(Pool3(net), (x,), path, ["images"], ["pool3"], axes)


def export_all(out: Path, random_weights: bool, seed: int = 0, vgg_weights=None, fid_weights=None,
               only: str | None = None) -> dict[str, Path]:
    """Write the exports (see the module docstring); returns role -> path."""
    import torch

    suffix = "-random" if random_weights else ""
    paths = {}
    if only in (None, "lpips"):
        for spatial, name in ((False, LPIPS_FILE), (True, LPIPS_SPATIAL_FILE)):
            net = lpips_network(spatial, random_weights, vgg_weights, seed)
            role = "lpips_spatial" if spatial else "lpips"
            paths[role] = export_lpips(net, out / name.format(suffix=suffix), spatial)
    if only in (None, "inception"):
        net, fid_state = inception_network(random_weights, fid_weights, seed)
        paths["inception"] = export_inception(net, out / INCEPTION_FILE.format(suffix=suffix))
        if random_weights:
            paths["inception_weights"] = out / INCEPTION_RANDOM_WEIGHTS
            torch.save(fid_state, paths["inception_weights"])
    return paths


def main(argv=None) -> int:
    a = parse_args(argv)
    try:
        paths = export_all(a.out, a.random_weights, a.seed, a.vgg_weights, a.fid_weights, a.only)
    except OSError as exc:  # the libraries' loaders try a download when the cache lacks the weights
        print(f"export_inpaint_models: cannot read the weights ({exc}); put them in TORCH_HOME's "
              "hub/checkpoints/ or give --vgg-weights / --fid-weights", file=sys.stderr)
        return 2
    for role, path in paths.items():
        print(f"{role}: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
