"""Comparing two runs' outputs: the results document without what differs between equal runs,
and the files of an output folder (pictures compared by their pixels); the two small scenes and
their serial run those comparisons start from.  Shared by the tests of the executors that must
give the serial run's output (Ray, worker processes)."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest

#: Statistics cut down for speed (the same in the serial run and the one compared with it).
OPTS = dict(n_boot=200, n_perm=100)


def two_scenes(root: Path, ctx) -> list:
    """Bundles of the synthetic room and garden, 2 views of 96x72 each."""
    from r360gpu.synthetic import generate_benchmark

    return generate_benchmark(root, seed=0, n_views=2, width=96, height=72, scenes=("room", "garden"),
                              detail=0.3, ctx=ctx)


def serial_run(scenes, out: Path, ctx) -> tuple[Path, dict]:
    """(out, results document) of the plain in-process run of ``scenes`` with :data:`OPTS`."""
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.report.outputs import write_outputs

    res = evaluate(scenes, out=out, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    kept = copy.deepcopy(res)  # write_outputs adds the plots' paths to the document it writes
    write_outputs(res, out)
    return out, kept


def comparable(doc: dict) -> dict:
    """A results document without what differs between equal runs (timing, creation time)."""
    return {k: v for k, v in doc.items() if k not in ("timing", "created")}


def tree(folder: Path, sub: str) -> dict:
    """{relative path: bytes} of every file under folder/sub."""
    base = folder / sub
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(base.rglob("*")) if p.is_file()}


def tree_differences(a: dict, b: dict) -> list[str]:
    """What differs between two {path: bytes} trees, short: files on one side only, and for PNGs
    that differ, where their pixels differ (a byte dump of a whole sheet says nothing).

    Two PNGs of the same size with identical pixels are equal: ISA-L's deflate (report.png) has been
    seen, once in about ten runs of the Ray test, to give a sheet another byte stream of the same
    length for the same pixels; the pictures' content is what a serial and a Ray run must share."""
    import cv2
    import numpy as np

    out = [f"only in the first: {k}" for k in sorted(a.keys() - b.keys())]
    out += [f"only in the second: {k}" for k in sorted(b.keys() - a.keys())]
    for k in sorted(a.keys() & b.keys()):
        if a[k] == b[k]:
            continue
        ia, ib = (cv2.imdecode(np.frombuffer(x, np.uint8), cv2.IMREAD_UNCHANGED) for x in (a[k], b[k]))
        if ia is None or ib is None or ia.shape != ib.shape:
            out.append(f"{k}: {len(a[k])} vs {len(b[k])} bytes, images "
                       f"{None if ia is None else ia.shape} vs {None if ib is None else ib.shape}")
            continue
        d = np.abs(ia.astype(np.int16) - ib.astype(np.int16)).reshape(ia.shape[0], ia.shape[1], -1).max(axis=2)
        ys, xs = np.nonzero(d)
        if ys.size == 0 and len(a[k]) == len(b[k]):
            continue  # the same pixels, another deflate stream of the same length (see above)
        where = f"rows {ys.min()}-{ys.max()}, columns {xs.min()}-{xs.max()}" if ys.size else "no pixel"
        out.append(f"{k}: {len(a[k])} vs {len(b[k])} bytes; {ys.size} pixels differ (at most by {d.max()}), {where} "
                   f"of {ia.shape[1]}x{ia.shape[0]}")
    return out


@pytest.fixture(scope="module")
def scenes(tmp_path_factory, ctx):
    """:func:`two_scenes`, once per test module that imports this fixture."""
    return two_scenes(tmp_path_factory.mktemp("bench"), ctx)


@pytest.fixture(scope="module")
def serial(scenes, tmp_path_factory, ctx):
    """:func:`serial_run` of :func:`scenes`, once per test module that imports this fixture."""
    return serial_run(scenes, tmp_path_factory.mktemp("serial"), ctx)
