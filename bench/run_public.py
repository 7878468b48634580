"""Run the public Remove360 evaluation (simonakocour/anything_left) on one scene folder.

    python bench/run_public.py PUBLIC_CHECKOUT SCENE_DIR

The steps of its ``scripts/run_pipeline.py`` after SAM, with their scripts'
defaults: ``compute_depth_diff.py`` (no intermediate images, recompute),
then ``evaluate_semantic.py``, ``evaluate_depth.py`` and
``evaluate_sam.py`` (each writes its JSON into the scene folder).  They run
in this one process (run_pipeline.py starts one per script, which would
only add interpreter and import time to the peer).  Without torch installed,
``bench/public_peer/torch_standin.py`` stands in for the few torch calls the
modules make (the same stand-in the compat fixture's numbers were made with).
The code is loaded from PUBLIC_CHECKOUT at run time; none of it is part of
this repository.
"""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path


def main(argv=None) -> int:
    public, scene = (Path(a).resolve() for a in (argv or sys.argv[1:]))
    if importlib.util.find_spec("torch") is None:
        import tempfile

        sys.path.insert(0, str(Path(__file__).resolve().parent / "public_peer"))
        from run_public_eval import _torch_standin

        sys.path.insert(0, _torch_standin(Path(tempfile.mkdtemp(prefix="r360-torch-standin-"))))
    sys.path.insert(0, str(public))
    from remove360.evaluation.depth import evaluate_depth_scene, summarize_depth_results
    from remove360.evaluation.sam import evaluate_sam_scene
    from remove360.evaluation.semantic import evaluate_semantic_scene, summarize_semantic_results
    from remove360.preprocessing.depth_diff import batch_process_depths
    from remove360.utils.io import save_json

    batch_process_depths(str(scene / "depth" / "before"), str(scene / "depth" / "after"),
                         str(scene / "depth_diff"), save_intermediate=False, skip_existing=False)
    sem = summarize_semantic_results(evaluate_semantic_scene(str(scene), verbose=False), label="")
    geo = summarize_depth_results(evaluate_depth_scene(str(scene), verbose=False), label="")
    matched = evaluate_sam_scene(str(scene), verbose=False)
    (scene / "evaluation_sam").mkdir(exist_ok=True)
    save_json(matched, str(scene / "evaluation_sam" / "results.json"))
    sims = [v["sim_sam"] for v in matched.values()]
    print(json.dumps({"acc_seg_30": sem.get("acc_seg_30"), "acc_delta_depth": geo.get("mean_acc_delta_depth"),
                      "sim_sam": sum(sims) / len(sims) if sims else None, "n_sam_views": len(sims)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
