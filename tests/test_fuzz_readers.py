"""Every reader fuzzed with structured mutations of a valid file, generated rather than picked.

For each reader a valid file is written with r360gpu's own writers (or taken from the test data), then
hypothesis mutates it: truncation, byte flips, inserted and deleted bytes, huge counts in the header
(decimal and binary), non-finite floats, wrong JSON types, and changes of encoding (a BOM, CRLF line
ends) that change nothing.  Every outcome must be one of

* an :class:`~r360gpu.errors.InputError` whose message names the file,
* a result (possibly with a warning) -- for a mutation that changes nothing (a BOM, CRLF) the same
  result as the valid file's,

never another exception, and never more than :data:`MAX_SECONDS` or :data:`MAX_PEAK` bytes of Python
and numpy memory (traced) for one read.  A last test runs ``r360gpu check`` and ``score`` on bundles
with a mutated input: exit 0 or 2, no traceback, the file named, nothing written outside ``--out``.

Counts: the CI run is fixed-seed (``derandomize``) with :data:`EXAMPLES` examples per reader (about a
minute on two cores); ``R360_FUZZ_EXAMPLES=N`` runs N per reader, and ``R360_FUZZ_COUNTS=FILE`` writes
the number run per reader to FILE (JSON).
"""
from __future__ import annotations

import json
import os
import shutil
import struct
import time
import tracemalloc
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from badinput_cases import SCORE_FLAGS, renders_bundle
from bundle_factory import H, W, camera, mask_image, write_rgb
from r360gpu import cli
from r360gpu.errors import InputError, R360Warning

EXAMPLES = int(os.environ.get("R360_FUZZ_EXAMPLES", "40"))
CLI_EXAMPLES = max(4, EXAMPLES // 5)
MAX_SECONDS = 10.0
MAX_PEAK = 256 << 20
EXR_DIR = Path(__file__).parent / "data" / "exr"
COUNTS: dict[str, int] = {}


@pytest.fixture(scope="module", autouse=True)
def _report_counts():
    yield
    target = os.environ.get("R360_FUZZ_COUNTS")
    if target:
        Path(target).write_text(json.dumps(COUNTS, indent=1, sort_keys=True))


# --- valid seeds: (file name, writer(path)) and the reader ---------------------------------------

def _gaussians(n=24):
    from r360gpu.io import random_gaussians

    return random_gaussians(n, seed=3)


def _cams():
    return [camera(f"view_{i:02d}.png", z=3.0 + i) for i in range(3)]


def _write_ply(p):
    from r360gpu.io import save_ply

    save_ply(p, _gaussians())


def _write_ply_ascii(p):
    from r360gpu.io import save_ply

    save_ply(p, _gaussians(6), format="ascii")


def _write_splat(p):
    from r360gpu.io import random_gaussians, save_splat

    save_splat(p, random_gaussians(24, sh_degree=0, seed=3))  # a .splat holds SH degree 0 only


def _write_cply(p):
    from r360gpu.io import save_compressed_ply

    save_compressed_ply(p, _gaussians(300))


def _write_colmap(binary: bool, which: str):
    def write(p):
        from r360gpu.io import save_colmap

        folder = p.parent / "model"
        save_colmap(folder, _cams(), binary=binary)
        shutil.copy(folder / f"{which}.{'bin' if binary else 'txt'}", p)
    return write


def _read_colmap(binary: bool, which: str):
    def read(p):
        from r360gpu.io import load_colmap

        folder = p.parent / "model"
        shutil.copy(p, folder / f"{which}.{'bin' if binary else 'txt'}")
        return load_colmap(folder)
    return read


def _write_cameras_json(p):
    from r360gpu.io import save_cameras_json

    save_cameras_json(p, _cams())


def _write_transforms(p):
    from r360gpu.io import save_transforms_json

    save_transforms_json(p, _cams())


def _write_mask(p):
    assert cv2.imwrite(str(p), mask_image())


def _write_palette_mask(p):
    from PIL import Image

    im = Image.fromarray((mask_image() > 0).astype(np.uint8), mode="P")
    im.putpalette([0, 0, 0, 255, 255, 255] + [0] * 762)
    im.save(p)


def _write_depth_png(p):
    d = np.random.default_rng(1).integers(500, 5000, (H, W), dtype=np.uint16)
    assert cv2.imwrite(str(p), d)


def _write_depth_tiff(p):
    assert cv2.imwrite(str(p), np.random.default_rng(2).random((H, W)).astype(np.float32) + 1)


def _write_npy(p):
    np.save(p, np.random.default_rng(3).random((H, W)).astype(np.float32) + 1)


def _copy(name):
    return lambda p: shutil.copy(EXR_DIR / name, p)


def _rle_records():
    from r360gpu.probes import rle

    m = mask_image() > 0
    return [{"segmentation": rle.encode(m), "predicted_iou": 0.9, "area": int(m.sum())},
            {"segmentation": rle.encode(~m, compressed=False), "predicted_iou": 0.5},
            {"segmentation": m.astype(int).tolist(), "predicted_iou": 0.7}]


def _write_sam_json(p):
    p.write_text(json.dumps(_rle_records()), encoding="utf-8")


def _write_gsam2(p):
    from r360gpu.probes import rle

    m = mask_image() > 0
    p.write_text(json.dumps({"img_height": H, "img_width": W, "annotations": [
        {"class_name": "box", "score": 0.8, "segmentation": rle.encode(m)},
        {"class_name": "chair", "score": 0.3, "segmentation": rle.encode(~m)}]}), encoding="utf-8")


def _write_rle(p):
    from r360gpu.probes import rle

    p.write_text(json.dumps(rle.encode(mask_image() > 0)), encoding="utf-8")


def _write_axes_csv(p):
    p.write_text("# axes\nscene,method,s_sem,s_geo,s_str,n_views\nA,x,0.1,0.2,0.3,4\nA,y,0.5,0.6,0.7,4\n"
                 "B,x,0.2,0.3,0.4,5\nB,y,0.9,1.0,0.0,5\n", encoding="utf-8")


def _in_view(fn):
    """Read as the probes do: decoded sizes bounded by the view's (r360gpu.probes.precomputed)."""
    def read(p):
        from r360gpu.probes import rle

        with rle.size_limit(4 * H * W):
            return fn(p)
    return read


def _read_sam(p):
    from r360gpu.probes.sam_records import read_sam_json

    return read_sam_json(p)


def _read_gsam2(p):
    from r360gpu.probes.gsam2_dumps import read_gsam2_json

    return read_gsam2_json(p, "box")


def _read_rle(p):
    from r360gpu.io.jsonfile import read_json
    from r360gpu.probes import rle

    return rle.decode(read_json(p), p)


def _read_axes(p):
    from r360gpu.aggregate.axes_csv import read_axes_csv

    return read_axes_csv(p)


def _load_gaussians(p):
    from r360gpu.io import load_gaussians

    return load_gaussians(p)


def _load_cameras(p):
    from r360gpu.io import load_cameras

    return load_cameras(p)


def _read_rgb(p):
    from r360gpu.io.renders import image_size, read_rgb

    image_size(p)
    return read_rgb(p)


def _read_depth(p):
    from r360gpu.io.renders import depth_size, read_depth

    depth_size(p)
    return read_depth(p)


def _read_mask(p):
    from r360gpu.io.masks import load_mask, mask_size

    mask_size(p)
    return load_mask(p)


def _read_scene_toml(p):
    """scene.toml of a renders bundle: every problem is a listed Problem (a BundleError), never a crash."""
    from r360gpu.bundle import check_bundle, load_bundle

    problems = check_bundle(p.parent)
    try:
        bundle = load_bundle(p.parent)
    except InputError as e:
        assert problems, "load_bundle refused what check_bundle accepted"
        raise e
    assert not problems, problems
    return (bundle.name, bundle.prompt, bundle.views, sorted(bundle.methods))


# name: (file name, writer, reader, kind) -- kind picks the mutations: "bin", "text", "json", "image"
READERS = {
    "ply": ("scene.ply", _write_ply, _load_gaussians, "bin"),
    "ply-ascii": ("scene.ply", _write_ply_ascii, _load_gaussians, "ply-text"),
    "splat": ("scene.splat", _write_splat, _load_gaussians, "bin"),
    "compressed-ply": ("scene.compressed.ply", _write_cply, _load_gaussians, "bin"),
    "colmap-cameras-bin": ("cameras.bin", _write_colmap(True, "cameras"), _read_colmap(True, "cameras"), "bin"),
    "colmap-images-bin": ("images.bin", _write_colmap(True, "images"), _read_colmap(True, "images"), "bin"),
    "colmap-cameras-txt": ("cameras.txt", _write_colmap(False, "cameras"), _read_colmap(False, "cameras"), "text"),
    "colmap-images-txt": ("images.txt", _write_colmap(False, "images"), _read_colmap(False, "images"), "text"),
    "cameras-json": ("cameras.json", _write_cameras_json, _load_cameras, "json"),
    "transforms-json": ("transforms.json", _write_transforms, _load_cameras, "json"),
    "png-rgb": ("view.png", lambda p: write_rgb(p, seed=4), _read_rgb, "image"),
    "png-depth16": ("view.png", _write_depth_png, _read_depth, "image"),
    "png-mask": ("view.png", _write_mask, _read_mask, "image"),
    "png-palette-mask": ("view.png", _write_palette_mask, _read_mask, "image"),
    "exr-zip": ("view.exr", _copy("z_float_zip.exr"), _read_depth, "bin"),
    "exr-rle-half": ("view.exr", _copy("z_half_rle.exr"), _read_depth, "bin"),
    "exr-none": ("view.exr", _copy("z_float_none.exr"), _read_depth, "bin"),
    "npy": ("view.npy", _write_npy, _read_depth, "bin"),
    "tiff": ("view.tiff", _write_depth_tiff, _read_depth, "image"),
    "sam-json": ("view.json", _write_sam_json, _in_view(_read_sam), "json"),
    "gsam2-json": ("view.json", _write_gsam2, _in_view(_read_gsam2), "json"),
    "rle": ("rle.json", _write_rle, _in_view(_read_rle), "json"),
    "scene-toml": ("scene.toml", None, _read_scene_toml, "text"),
    "axes-csv": ("axes.csv", _write_axes_csv, _read_axes, "text"),
}


# --- mutations ---------------------------------------------------------------------------------

HUGE_INTS = [0, -1, 2 ** 31 - 1, 2 ** 31, 2 ** 32 + 1, 2 ** 40, 2 ** 63 - 1, 10 ** 30]
ODD_FLOATS = [float("nan"), float("inf"), float("-inf"), -0.0, 1e38, -1e38, 5e-324]
JSON_VALUES = [None, True, "", "x", -1, 0, 2 ** 64, 1e308, -1e308, [], {}, [[]], [1, 2], {"size": [1e9, 1e9]}]


@st.composite
def byte_mutation(draw, data: bytes, kind: str):
    n = len(data)
    ops = ["truncate", "flip", "insert", "delete", "int-text", "u32", "u64", "float", "double", "duplicate"]
    if kind in ("text", "json"):
        ops += ["bom", "crlf", "latin1", "utf16"]
    if kind == "ply-text":  # a PLY starts with the bytes "ply" (no BOM), lines may end in CRLF
        ops += ["crlf", "latin1"]
    if kind == "image":
        ops += ["header-flip", "header-flip"]
    op = draw(st.sampled_from(ops))
    pos = draw(st.integers(0, max(0, n - 1)))
    if op == "truncate":
        return op, data[:pos]
    if op == "flip":
        out = bytearray(data)
        for p, b in draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, 255)), min_size=1, max_size=8)):
            out[p] = b
        return op, bytes(out)
    if op == "header-flip":  # the first 64 bytes: sizes, bit depth, colour type
        out = bytearray(data)
        for p, b in draw(st.lists(st.tuples(st.integers(0, min(63, n - 1)), st.integers(0, 255)), min_size=1,
                                  max_size=3)):
            out[p] = b
        return op, bytes(out)
    if op == "insert":
        return op, data[:pos] + draw(st.binary(min_size=1, max_size=16)) + data[pos:]
    if op == "delete":
        k = draw(st.integers(1, 16))
        return op, data[:pos] + data[pos + k:]
    if op == "int-text":  # a decimal number in the first 4 KB (a header count) replaced by a huge one
        head = data[:4096]
        spans = [(i, j) for i, j in _digit_runs(head)]
        if not spans:
            return op, data
        i, j = draw(st.sampled_from(spans))
        return op, data[:i] + str(draw(st.sampled_from(HUGE_INTS))).encode() + data[j:]
    if op in ("u32", "u64", "float", "double"):
        fmt, pool = {"u32": ("<I", [0, 1, 2 ** 31, 2 ** 32 - 1]), "u64": ("<Q", [0, 2 ** 40, 2 ** 63, 2 ** 64 - 1]),
                     "float": ("<f", ODD_FLOATS), "double": ("<d", ODD_FLOATS)}[op]
        size = struct.calcsize(fmt)
        if n < size:
            return op, data
        at = draw(st.integers(0, n - size))
        return op, data[:at] + struct.pack(fmt, draw(st.sampled_from(pool))) + data[at + size:]
    if op == "duplicate":
        return op, data + data
    if op == "bom":
        return "neutral", b"\xef\xbb\xbf" + data
    if op == "crlf":
        return "neutral", data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n")
    if op == "latin1":
        return op, data[:pos] + "é".encode("latin-1") + data[pos:]
    if op == "utf16":
        return op, data.decode("utf-8", "replace").encode("utf-16")
    raise AssertionError(op)


def _digit_runs(b: bytes):
    i = 0
    while i < len(b):
        if 48 <= b[i] <= 57:
            j = i
            while j < len(b) and 48 <= b[j] <= 57:
                j += 1
            yield i, j
            i = j
        else:
            i += 1


@st.composite
def json_mutation(draw, data: bytes):
    """A value somewhere in the document replaced by one of another type or size."""
    doc = json.loads(data)
    paths = list(_json_paths(doc))
    path = draw(st.sampled_from(paths))
    value = draw(st.sampled_from(JSON_VALUES))
    doc = _json_set(doc, path, value)
    return "json-type", json.dumps(doc).encode()


def _json_paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _json_paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:4]):
            yield from _json_paths(v, prefix + (i,))


def _json_set(doc, path, value):
    if not path:
        return value
    head, rest = path[0], path[1:]
    if isinstance(doc, dict):
        return {**doc, head: _json_set(doc[head], rest, value)}
    out = list(doc)
    out[head] = _json_set(out[head], rest, value)
    return out


def mutation(data: bytes, kind: str):
    strategies = [byte_mutation(data, kind)]
    if kind == "json":
        strategies.append(json_mutation(data))
    return st.one_of(*strategies)


# --- the outcome rule -----------------------------------------------------------------------------

def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if hasattr(a, "__dict__") and type(a) is type(b):
        return _same(vars(a), vars(b))
    return a == b


def _outcome(read, path: Path):
    """("ok", result) or ("error", InputError); any other exception fails the test.  Time and traced
    peak memory are bounded."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", R360Warning)
            return "ok", read(path)
    except InputError as e:
        text = str(e) + " " + str(e.path or "")
        assert path.name in text or str(path.parent) in text, f"the error does not name the file: {e}"
        return "error", e
    finally:
        elapsed = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert elapsed < MAX_SECONDS, f"{path.name}: {elapsed:.1f} s"
        assert peak < MAX_PEAK, f"{path.name}: {peak / 2 ** 20:.0f} MiB traced"


def _seed(name: str, folder: Path) -> Path:
    file, write, _, _ = READERS[name]
    if name == "scene-toml":
        renders_bundle(folder)
        return folder / "scene.toml"
    path = folder / file
    write(path)
    return path


@pytest.mark.parametrize("name", list(READERS))
def test_reader_survives_mutations(name, tmp_path_factory):
    folder = tmp_path_factory.mktemp(name)
    path = _seed(name, folder)
    valid = path.read_bytes()
    read = READERS[name][2]
    kind, baseline = _outcome(read, path)
    assert kind == "ok", f"the valid seed of {name} is refused: {baseline}"
    COUNTS[name] = 0

    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(mut=mutation(valid, READERS[name][3]))
    def run(mut):
        op, data = mut
        COUNTS[name] += 1
        path.write_bytes(data)
        try:
            kind, result = _outcome(read, path)
            if op == "neutral":  # a BOM or CRLF line ends: the same reading as the valid file
                assert kind == "ok", f"{name}: a {op} change is refused: {result}"
                assert _same(result, baseline), f"{name}: a {op} change reads differently"
        finally:
            path.write_bytes(valid)

    run()


# --- through the command line: check and score on a bundle with one mutated input ------------------

BUNDLE_FILES = ["scene.toml", "masks/view_01.png", "pre/rgb/view_02.png", "a/depth/view_00.npy",
                "pre/depth/view_01.npy"]


def _snapshot(root: Path, skip: Path) -> dict:
    return {p.relative_to(root).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in root.rglob("*") if p.is_file() and skip not in p.parents}


@pytest.mark.parametrize("command", ["check", "score"])
def test_cli_on_a_mutated_bundle(command, tmp_path_factory, capsys):
    root = tmp_path_factory.mktemp(f"cli-{command}")
    bundle = renders_bundle(root / "b")
    originals = {f: (bundle / f).read_bytes() for f in BUNDLE_FILES}
    COUNTS[f"cli-{command}"] = 0

    @settings(max_examples=CLI_EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(data=st.data())
    def run(data):
        rel = data.draw(st.sampled_from(BUNDLE_FILES))
        kind = "text" if rel.endswith(".toml") else "image" if rel.endswith(".png") else "bin"
        op, mutated = data.draw(byte_mutation(originals[rel], kind))
        COUNTS[f"cli-{command}"] += 1
        out = root / "out"
        shutil.rmtree(out, ignore_errors=True)
        (bundle / rel).write_bytes(mutated)
        before = _snapshot(root, out)
        try:
            argv = ["check", str(bundle)] if command == "check" else [
                "score", str(bundle), "--out", str(out), *SCORE_FLAGS]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", R360Warning)
                rc = cli.main(argv)
            text = "".join(capsys.readouterr())
            assert "Traceback" not in text
            assert rc in (0, 2), (rel, op, rc, text)
            if rc == 2:
                assert Path(rel).name in text or str(bundle) in text, (rel, op, text)
            if op == "neutral":
                assert rc == 0, (rel, op, text)
            assert _snapshot(root, out) == {**before}, "written outside --out"
        finally:
            (bundle / rel).write_bytes(originals[rel])

    run()
