"""bench/device_suite.py: the step comparing our SAM automatic masks on the GPU provider with the official
generator on CUDA torch says "not available" with what is missing (here: no CUDA torch), and its table
row reads bench/bench_amg.py's output (counts, pixel-identical pairs, least IoU, the ratio, the goal)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import device_suite as S  # noqa: E402

AMG_OUTPUT = """\
# SAM automatic masks: official (torch 2.9.0 on cuda: NVIDIA H200, torchvision) vs r360gpu (onnxruntime, probe device auto)
  official runs on ...
  official:     4.1 s wall,    4.0 CPU-s, 61 masks   (load 0.5 0.4 0.3)
  after runs on CUDAExecutionProvider
  after   :     1.2 s wall,    1.1 CPU-s, 61 masks   (load 0.5 0.4 0.3)
mask sets (Hungarian matching on IoU):
  official vs after: 61 / 61 masks, 58 pixel-identical pairs, min IoU 0.9950 -> DIFFERENT
ratios (official or before / after):
  official/after: wall 3.42x, CPU 3.64x
"""


def test_the_official_step_row_reads_bench_amg():
    step = S.Step("probe vs official", ["x"], 0.3)
    step.output = AMG_OUTPUT
    S.describe(step, small=False, renders=1_000_000)
    assert step.figure == ("official 4.1 s, r360gpu 1.2 s per image, 3.42x; masks 61 / 61, 58 pixel-identical, "
                           "least IoU 0.9950")
    assert step.goal == ">= 3x, equal mask sets MET"
    step.output = AMG_OUTPUT.replace("3.42x", "2.10x")
    S.describe(step, small=False, renders=1_000_000)
    assert step.goal.endswith("NOT MET")
    step.output = AMG_OUTPUT.replace("61 / 61", "61 / 60")
    S.describe(step, small=False, renders=1_000_000)
    assert step.goal.endswith("NOT MET")


def test_the_official_step_says_what_is_missing(tmp_path):
    args = argparse.Namespace(sam_src=None, samexporter_src=None, sam_work=None, small=True)
    step = S.official_step(args, tmp_path)
    try:
        import torch

        cuda = torch.cuda.is_available()
    except ImportError:
        cuda = False
    if not cuda:
        assert step.argv is None and step.figure.startswith("not available: no torch with CUDA")
