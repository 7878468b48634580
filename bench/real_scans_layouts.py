"""Real scans scored in every layout: the axes agree across layouts and the frame check never cries wolf.

Usage:
    python bench/real_scans_layouts.py SCENE.ply [SCENE.ply ...] [--views 6] [--size 160x120]
                                       [--out DIR] [--n-boot 200]

SCENE.ply: splat files r360gpu reads, e.g. the PlayCanvas engine's
``examples/assets/splats/biker.compressed.ply`` and ``guitar.compressed.ply``.
Each is made into a bundle as ``bench/frame_check_scenes.py --real`` frames
one: cameras on a ring around the scene (COLMAP model), a target cut out
(``bench/real_scene_controls.py``; each camera turned by up to 3 degrees, as held by
hand), its visible pixels as masks, the scene
without the target as reference and two methods (``removed``: the target
deleted; ``half``: half of its Gaussians deleted).  The bundle is written
again in every other layout by ``r360gpu convert`` (an INRIA output folder,
gsplat's output in its normalised world, a nerfstudio export in a dataparser
frame, public Remove360 folders of 16-bit renders), and each is scored with
``r360gpu score``, as a user would run them (one process per run).  Then the
wrong frames: the nerfstudio export and gsplat's output scored with
``--frame cameras`` (their splats taken to be in the cameras' world), and the
INRIA folder with ``--frame`` the nerfstudio export's
``dataparser_transforms.json`` (splats in the cameras' world taken to be in
nerfstudio's).

Printed per scan and run: the exit code, the frame check's verdict on pre
(level, cone agreement, outline step, removal against the reference; the
public layout's renders are images and are not checked), the largest
difference of any method's axes (s_sem, s_geo, s_str, RQS) from the bundle's,
and of the probes' mIoU readings (IoU_pre, IoU_post).  The last lines state
whether the axes agree (1e-6; 1e-4 for the public layout, whose colours are
rounded to 16 bits) and the mIoU readings (1e-4: splats moved into another
frame are rounded to float32 there, which can flip a probe's pixel), whether
every correct layout is "ok" or "note" and every wrong frame refused (exit 2).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(ROOT / "tests"))  # the frame generators shared with the tests (tests/frame_class.py)

from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io.frames import DATAPARSER_TRANSFORMS  # noqa: E402
from r360gpu.io import load_gaussians, save_colmap, save_ply  # noqa: E402
from r360gpu.synthetic.bundle import encode_mask  # noqa: E402

from frame_check_scenes import visible_masks  # noqa: E402
from frame_class import rotation  # noqa: E402
from r360gpu.io import Camera  # noqa: E402
from real_scene_controls import cut_target, orbit  # noqa: E402

#: The cameras are turned about their centres by up to this (degrees), as a hand-held capture's are: a
#: ring exactly about an axis has its mean up exactly on it, where gsplat's normalisation is degenerate.
JITTER_DEG = 3.0
AXES = ("s_sem", "s_geo", "s_str", "rqs")
#: The probes' mIoU readings beside the axes: a pixel of a probe's mask flipped by the float32 rounding
#: of positions moved into another frame moves them by ~1e-5 at these sizes.
DIAGNOSTICS = ("iou_pre", "iou_post")
#: Largest difference of an axis from the bundle's that counts as agreeing (public: 16-bit colours).
AGREE = {"public": 1e-4}
AGREE_DEFAULT = 1e-6
#: ... and of a diagnostic.
AGREE_DIAGNOSTIC = 1e-4
METHODS = ("removed", "half")


def write_bundle(path: str, folder: Path, views: int, size: tuple[int, int], ctx) -> str:
    """The scan as a bundle in ``folder`` (the module docstring); returns the scene's name."""
    name = Path(path).name.split(".")[0]
    g = load_gaussians(path)
    target = cut_target(g.means)
    rng = np.random.default_rng(0)
    cams = {v: hand_held(c, rng) for v, c in orbit(g.means, views, *size).items()}
    masks = visible_masks(g, target, cams, ctx)
    half = target & (rng.random(g.n) < 0.5)
    (folder / "masks").mkdir(parents=True)
    (folder / "methods").mkdir()
    for v, m in masks.items():
        (folder / "masks" / f"{v}.png").write_bytes(encode_mask(m))
    save_colmap(folder / "colmap", [cams[v] for v in sorted(cams)], binary=True)
    save_ply(folder / "pre.ply", g)
    save_ply(folder / "reference.ply", g.subset(~target))
    save_ply(folder / "methods" / "removed.ply", g.subset(~target))
    save_ply(folder / "methods" / "half.ply", g.subset(~half))
    (folder / "scene.toml").write_text(
        f'name = "{name}"\nprompt = "object"\ncameras = "colmap"\nmasks = "masks"\n\n[pre]\nscene = "pre.ply"\n\n'
        '[reference]\nscene = "reference.ply"\n\n'
        + "".join(f'[methods.{m}]\nscene = "methods/{m}.ply"\n\n' for m in METHODS))
    print(f"{name}: {g.n} Gaussians, target {int(target.sum())}; {len(masks)} of {views} views see it "
          f"({size[0]}x{size[1]})", flush=True)
    return name


def hand_held(cam: Camera, rng: np.random.Generator) -> Camera:
    """``cam`` turned about its centre by a random rotation of up to :data:`JITTER_DEG` degrees."""
    c2w = cam.camera_to_world
    c2w[:3, :3] = rotation(rng.normal(size=3), np.radians(rng.uniform(0.0, JITTER_DEG))) @ c2w[:3, :3]
    return Camera.from_camera_to_world(c2w, cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height, cam.name)


def r360(*args) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "r360gpu", *map(str, args)], capture_output=True, text=True, env=env)


def score(inputs: list, out: Path, n_boot: int, *extra) -> dict:
    """One ``r360gpu score`` run: its exit code, the message of a refusal, pre's frame check and the
    methods' axes."""
    t0 = time.perf_counter()
    p = r360("score", *inputs, "--out", out, "--no-pictures", "--no-boundary", "--no-controls",
             "--n-boot", n_boot, "--n-perm", max(20, n_boot // 2), "--quiet", *extra)
    row = {"rc": p.returncode, "seconds": time.perf_counter() - t0, "check": None, "axes": {}, "diag": None,
           "message": p.stderr.strip().splitlines()[-1] if p.returncode else ""}
    if p.returncode == 0:
        res = json.loads((out / "results.json").read_text())
        (scene,) = res["scenes"].values()
        row["check"] = scene.get("frame_check", {}).get("pre")
        row["axes"] = {m: {k: e["axes"].get(k) for k in (*AXES, *DIAGNOSTICS)} for m, e in scene["methods"].items()}
    return row


def largest_difference(axes: dict, base: dict, keys) -> float:
    """The largest absolute difference of ``keys`` over the methods (inf: one is missing on one side)."""
    diffs = [abs(axes[m][k] - base[m][k]) for m in base if m in axes for k in keys
             if axes[m][k] is not None and base[m][k] is not None]
    missing = any(m not in axes for m in base) or any((axes[m][k] is None) != (base[m][k] is None)
                                                     for m in base if m in axes for k in keys)
    return float("inf") if missing or not diffs else max(diffs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--views", type=int, default=6, help="cameras on the ring (default 6)")
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--n-boot", type=int, default=200)
    ap.add_argument("--out", default=None, help="work folder (default: a temporary one, removed)")
    a = ap.parse_args(argv)
    size = tuple(int(x) for x in a.size.lower().split("x"))
    ctx = get_context()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(a.out or tmp)
        rows, failures = [], []
        for path in a.scenes:
            stem = Path(path).name.split(".")[0]
            bundle = work / stem / "bundle"
            name = write_bundle(path, bundle, a.views, size, ctx)
            conv = r360("convert", bundle, "--out", work / stem / "layouts",
                        "--layouts", "inria,gsplat,nerfstudio,public")
            if conv.returncode:
                raise SystemExit(f"convert failed: {conv.stderr}")
            lay = work / stem / "layouts"
            prompt = "object"
            runs = [("bundle", "correct", [bundle], ()),
                    ("inria", "correct", [lay / "inria" / name], ()),
                    ("gsplat", "correct", [lay / "gsplat" / name], ()),
                    ("nerfstudio", "correct", [lay / "nerfstudio" / name], ()),
                    ("public", "correct", [f"{m}={lay / 'public' / m / f'{name}_{prompt}'}" for m in METHODS],
                     ("--scene-name", name)),
                    ("nerfstudio --frame cameras", "wrong", [lay / "nerfstudio" / name], ("--frame", "cameras")),
                    ("gsplat --frame cameras", "wrong", [lay / "gsplat" / name], ("--frame", "cameras")),
                    ("inria --frame nerfstudio's", "wrong", [lay / "inria" / name],
                     ("--frame", lay / "nerfstudio" / name / "exports" / "pre" / DATAPARSER_TRANSFORMS))]
            base = None
            for label, truth, inputs, extra in runs:
                row = score(inputs, work / stem / "out" / label.replace(" ", "_"), a.n_boot, *extra)
                row.update(scene=name, layout=label, truth=truth)
                if label == "bundle":
                    base = row["axes"]
                ok = row["rc"] == 0 and base
                row["diff"] = largest_difference(row["axes"], base, AXES) if ok else None
                row["diag"] = largest_difference(row["axes"], base, DIAGNOSTICS) if ok else None
                rows.append(row)
                print_row(row)
                failures += judge(row)
        print()
        print_table(rows)
        print()
        print("all layouts agree and every verdict is right" if not failures else "FAILED: " + "; ".join(failures))
        return 1 if failures else 0


def judge(row) -> list[str]:
    """What is wrong with one run's outcome (empty: as it should be)."""
    where = f"{row['scene']} {row['layout']}"
    if row["truth"] == "wrong":
        return [] if row["rc"] == 2 and "world frames" in row["message"] else [f"{where}: not refused (rc {row['rc']})"]
    if row["rc"] != 0:
        return [f"{where}: exit {row['rc']}: {row['message']}"]
    out = []
    level = (row["check"] or {}).get("level")
    if row["layout"] != "public" and level not in ("ok", "note"):
        out.append(f"{where}: frame check {level}")
    if row["diff"] is None or row["diff"] > AGREE.get(row["layout"], AGREE_DEFAULT):
        out.append(f"{where}: axes differ from the bundle's by {row['diff']}")
    if row["diag"] is None or row["diag"] > AGREE_DIAGNOSTIC:
        out.append(f"{where}: mIoU readings differ from the bundle's by {row['diag']}")
    return out


def _f(x, nd=2) -> str:
    return "-" if x is None else f"{x:.{nd}f}"


def _e(x) -> str:
    return "-" if x is None else f"{x:.1e}"


def print_row(r) -> None:
    c = r["check"] or {}
    print(f"{r['scene']:7s} {r['layout']:28s} rc {r['rc']} check {c.get('level', '-'):6s} cones {_f(c.get('cones'))} "
          f"step {_f(c.get('step'))} removed {_f(c.get('removed'))} max|axes - bundle| "
          f"{_e(r['diff'])} mIoU {_e(r['diag'])} "
          f"({r['seconds']:.0f} s){'  ' + r['message'][:160] if r['rc'] else ''}", flush=True)


def print_table(rows) -> None:
    print("| scan | layout | frame | exit | frame check | cones | step | removed | axes vs bundle | mIoU vs bundle | "
          "RQS removed / half |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        c = r["check"] or {}
        level = c.get("level", "not checked (renders)" if r["layout"] == "public" and r["rc"] == 0 else "-")
        if r["rc"] == 2:
            level = "refused"
        rqs = " / ".join(_f((r["axes"].get(m) or {}).get("rqs"), 3) for m in METHODS) if r["axes"] else "-"
        print(f"| {r['scene']} | {r['layout']} | {r['truth']} | {r['rc']} | {level} | {_f(c.get('cones'))} | "
              f"{_f(c.get('step'))} | {_f(c.get('removed'))} | "
              f"{_e(r['diff'])} | {_e(r['diag'])} | {rqs} |")


if __name__ == "__main__":
    sys.exit(main())
