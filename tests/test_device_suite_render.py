"""bench/device_suite.py's renderer rows read bench_render_sort.py's keys/s and bench_render.py's host recording."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import device_suite as S  # noqa: E402

SORT_OUTPUT = """\
WGSL radix sort alone (median of 3; device = sum of its passes' timestamp queries):
 variant               case      keys bits   wall ms   Mkeys/s device ms   Mkeys/s sorted
  serial           1M pairs   1000000   32   1132.10       0.9   891.461       1.1   True
  serial         depth keys   1000000   32    750.88       1.3   633.417       1.6   True
  serial: the renderer's exact sorts (N=1000000 by 32 bits + K=6406903 by 13 bits) 4300.9 ms wall vs the packed 32-bit sort of K keys 5771.9 ms (1.34x); device 3294.46 vs 6512.71 ms (1.98x)
  blocks           1M pairs   1000000   32      0.95    1052.6         -         -   True
  blocks: the renderer's exact sorts (N=1000000 by 32 bits + K=6406903 by 13 bits) 6651.8 ms wall vs the packed 32-bit sort of K keys 10558.3 ms (1.59x)
"""

RECORDING_OUTPUT = """\
host recording per frame, 1920x1080, 3 frames of one camera per process, medians of 2 alternating rounds
        N  side  host ms dispatches groups new uniforms new      keys  r360gpu
  1000000  ours     3.61       39.0        0.0          0.0   6406903  /x/r360gpu
  1000000  peer     6.13       39.0          -            -   6406903  /y/r360gpu
"""


def test_sort_row_reads_keys_per_second():
    step = S.Step("render sort", ["x"], 0.05)
    step.output = SORT_OUTPUT
    S.describe(step, small=False, renders=1_000_000)
    assert step.figure == ("serial: 1M pairs 0.9 Mkeys/s wall, 1.1 Mkeys/s device (packed-key sort of the frame's "
                           "keys 1.34x the exact pair's time); blocks: 1M pairs 1052.6 Mkeys/s wall "
                           "(packed-key sort of the frame's keys 1.59x the exact pair's time)")
    assert step.goal == "wgpu_sort: 1M pairs in 317 us on an RTX A5000 (3155 Mkeys/s)"


def test_recording_row_reads_our_host_time():
    step = S.Step("render recording", ["x"], 0.05)
    step.output = RECORDING_OUTPUT
    S.describe(step, small=False, renders=1_000_000)
    assert step.figure == "3.61 ms host recording per frame (39.0 passes)"
    step.output = "nothing printed"
    S.describe(step, small=False, renders=1_000_000)
    assert step.figure == ""
