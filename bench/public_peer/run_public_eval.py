"""Run the public Remove360 evaluation modules, unchanged, on a public-layout scene folder.

This is the peer of ``r360gpu score --compat``: it produced the expected
numbers of ``tests/data/compat_public`` (see the README there).  It needs a
checkout of github.com/simonakocour/anything_left and an environment with
numpy, pillow, matplotlib, opencv, scipy and tqdm; when torch is not
installed, ``torch_standin.py`` (next to this file) is put on the path as
``torch`` for this process only.

    python bench/public_peer/run_public_eval.py --anything-left DIR --scene SCENE --out expected.json

Writes, per compat mode ("public": ``save_intermediate=True``;
"public-default": the scripts' default), the per-view records and the
summaries that the public functions return.  The scene folder is copied to a
temporary folder first, since the public code writes its outputs into it.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _torch_standin(tmp: Path) -> str:
    pkg = tmp / "standin" / "torch"
    (pkg / "nn").mkdir(parents=True)
    shutil.copy(HERE / "torch_standin.py", pkg / "__init__.py")
    (pkg / "nn" / "__init__.py").write_text("from . import functional\n")
    (pkg / "nn" / "functional.py").write_text("from torch import _interpolate as interpolate\n")
    return str(tmp / "standin")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--anything-left", required=True, help="checkout (or bare git mirror) of simonakocour/anything_left")
    ap.add_argument("--scene", required=True, help="public-layout scene folder")
    ap.add_argument("--out", required=True, help="JSON file to write")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        src = Path(args.anything_left)
        commit = None
        if (src / "HEAD").is_file() and not (src / "remove360").is_dir():  # a bare git mirror
            commit = subprocess.check_output(["git", "--git-dir", str(src), "rev-parse", "HEAD"], text=True).strip()
            code = tmp / "anything_left"
            code.mkdir()
            archive = subprocess.check_output(["git", "--git-dir", str(src), "archive", "HEAD"])
            subprocess.run(["tar", "-x", "-C", str(code)], input=archive, check=True)
            src = code
        elif (src / ".git").exists():
            commit = subprocess.check_output(["git", "-C", str(src), "rev-parse", "HEAD"], text=True).strip()
        torch_kind = "torch"
        if importlib.util.find_spec("torch") is None:
            sys.path.insert(0, _torch_standin(tmp))
            torch_kind = "bench/public_peer/torch_standin.py"
        sys.path.insert(0, str(src))
        from remove360.evaluation.depth import evaluate_depth_scene, summarize_depth_results
        from remove360.evaluation.sam import evaluate_sam_scene
        from remove360.evaluation.semantic import evaluate_semantic_scene, summarize_semantic_results
        from remove360.preprocessing.depth_diff import batch_process_depths
        import cv2, matplotlib, numpy as np, PIL, scipy  # noqa: E401

        scene = tmp / "scene"
        shutil.copytree(args.scene, scene)
        out: dict = {
            "anything_left_commit": commit, "torch": torch_kind,
            "versions": {"numpy": np.__version__, "pillow": PIL.__version__, "matplotlib": matplotlib.__version__,
                         "opencv": cv2.__version__, "scipy": scipy.__version__,
                         "python": sys.version.split()[0]},
        }
        sem = evaluate_semantic_scene(str(scene), verbose=False)
        out["semantic"] = {"views": sem, "summary": summarize_semantic_results(sem, label="")}
        try:
            matched = evaluate_sam_scene(str(scene), verbose=False)
            sims = [v["sim_sam"] for v in matched.values() if isinstance(v, dict)]
            out["sam"] = {"views": matched, "mean_sim_sam": float(np.mean(sims)) if sims else None}
        except FileNotFoundError as e:
            out["sam"] = {"error": str(e)}
        out["depth"] = {}
        for mode, save_intermediate in (("public", True), ("public-default", False)):
            sub = f"depth_diff_{mode}"
            batch_process_depths(str(scene / "depth" / "before"), str(scene / "depth" / "after"), str(scene / sub),
                                 save_intermediate=save_intermediate, skip_existing=False)
            res = evaluate_depth_scene(str(scene), depth_subdir=sub, output_subdir=f"eval_{mode}", verbose=False)
            out["depth"][mode] = {"views": res, "summary": summarize_depth_results(res, label="")}
    Path(args.out).write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
