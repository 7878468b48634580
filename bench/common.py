"""Shared helpers of the benchmarks: realistic test data and robust timing."""
from __future__ import annotations

import time

import cv2
import numpy as np


def blob_masks(n: int, height: int, width: int, rng: np.random.Generator) -> np.ndarray:
    """(n, H, W) uint8 masks of one smooth random blob each, areas log-uniform
    between 0.05% and 25% of the frame (like SAM's object masks)."""
    out = np.zeros((n, height, width), np.uint8)
    angles = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    for k in range(n):
        area = np.exp(rng.uniform(np.log(5e-4), np.log(0.25))) * height * width
        r0 = np.sqrt(area / np.pi)
        cx, cy = rng.uniform(0, width), rng.uniform(0, height)
        # Smooth radial wobble: a few low-frequency harmonics.
        r = r0 * (1 + sum(rng.uniform(-0.15, 0.15) * np.cos(f * angles + rng.uniform(0, 2 * np.pi)) for f in (2, 3, 5)))
        pts = np.stack([cx + r * np.cos(angles), cy + r * np.sin(angles)], 1).round().astype(np.int32)
        cv2.fillPoly(out[k], [pts], 1)
    return out


def timeit(fn, repeat: int = 5, warmup: int = 1) -> tuple[float, object]:
    """Median wall time of ``fn()`` in seconds over ``repeat`` runs, and its last result."""
    res = None
    for _ in range(warmup):
        res = fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), res


def header(title: str) -> None:
    from r360gpu.gpu import get_context

    d = get_context().describe()
    print(f"# {title}")
    print(f"adapter: {d['name']} ({d['adapter_type']}, {d['backend']}); CPU cores: {__import__('os').cpu_count()}")


def bytecode_env(folders) -> dict:
    """The environment for timed runs of Python code as a user has it: the bytecode of ``folders``
    (r360gpu's package folder, a peer's checkout) compiled beforehand and read from ``__pycache__``,
    as after any first run or a pip install.

    A shell with PYTHONDONTWRITEBYTECODE set (some CI images and sandboxes set it) would otherwise
    make every timed run compile r360gpu's modules again (about 0.4 s of a 4 s run measured here),
    a cost no user pays twice."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    for folder in folders:
        subprocess.run([sys.executable, "-m", "compileall", "-q", str(folder)], env=env, check=True,
                       capture_output=True)
    return env
