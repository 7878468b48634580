"""The bad-input corpus: each case builds its inputs into a folder and says what must happen.

Outcomes: ``error`` (exit 2, one line naming the file, nothing half-written),
``warning`` (exit 0, the warning printed once and recorded in results.json
naming the file), ``accepted`` (exit 0, the input is read correctly).
:mod:`test_badinput_corpus` runs every case through the real CLI.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from bundle_factory import H, VIEWS, W, camera, make_bundle, make_remove360, mask_image, write_mask, write_rgb
from r360gpu.io import random_gaussians, save_compressed_ply, save_ply

SCORE_FLAGS = ["--quiet", "--no-boundary", "--no-pictures", "--n-boot", "10", "--n-perm", "10"]

RENDERS_TOML = """\
name = "r"
prompt = "box"
masks = "masks"

[pre]
renders = "pre"

[methods.a]
renders = "a"
{a_extra}
"""


def _depth_pre() -> np.ndarray:
    rng = np.random.default_rng(5)
    return (2.0 + 0.1 * rng.random((H, W))).astype(np.float32)


def _depth_post() -> np.ndarray:
    d = _depth_pre()
    d[mask_image() != 0] += 1.0  # the object is gone: the wall behind it is farther
    return d


def renders_bundle(root: Path, *, a_extra: str = "", post_depth: dict | None = None) -> Path:
    """A renders-only bundle (no rendering: fast): pre and method ``a``, depth as .npy (pre units: metres).
    post_depth: {view: array} replacing method a's depth of those views."""
    for i, v in enumerate(VIEWS):
        write_mask(root / "masks" / f"{v}.png")
        write_rgb(root / "pre" / "rgb" / f"{v}.png", seed=i)
        write_rgb(root / "a" / "rgb" / f"{v}.png", seed=10 + i)
        (root / "pre" / "depth").mkdir(parents=True, exist_ok=True)
        (root / "a" / "depth").mkdir(parents=True, exist_ok=True)
        np.save(root / "pre" / "depth" / f"{v}.npy", _depth_pre())
        d = (post_depth or {}).get(v)
        if d is None:
            np.save(root / "a" / "depth" / f"{v}.npy", _depth_post())
        elif isinstance(d, np.ndarray):
            np.save(root / "a" / "depth" / f"{v}.npy", d)
    (root / "scene.toml").write_text(RENDERS_TOML.format(a_extra=a_extra), encoding="utf-8")
    return root


@dataclass
class Case:
    """One corpus entry.

    build(root) writes the inputs under ``root`` and returns (argv, named): argv of the CLI, where
    "{out}" stands for the output folder, and the text (a file or folder name) the message or warning
    must contain.  outcome: "error" | "warning" | "accepted".  keyword: a word the message must hold.
    verify(out, results, stderr): extra assertions (results is None without results.json).
    """

    id: str
    outcome: str
    build: Callable[[Path], tuple[list[str], str | None]]
    keyword: str = ""
    verify: Callable | None = None


def score(bundle: Path, *extra: str) -> list[str]:
    return ["score", str(bundle), "--out", "{out}", *SCORE_FLAGS, *extra]


def check(bundle: Path, *extra: str) -> list[str]:
    return ["check", str(bundle), *extra]


CASES: list[Case] = []


def case(id: str, outcome: str, keyword: str = "", verify=None):
    def deco(fn):
        CASES.append(Case(id, outcome, fn, keyword, verify))
        return fn
    return deco


def _edit_toml(root: Path, old: str, new: str) -> None:
    p = root / "scene.toml"
    text = p.read_text(encoding="utf-8")
    assert old in text, old
    p.write_text(text.replace(old, new, 1), encoding="utf-8")


def _ply_header_edit(path: Path, old: bytes, new: bytes) -> None:
    data = path.read_bytes()
    end = data.index(b"end_header")
    head = data[:end]
    assert old in head, old
    path.write_bytes(head.replace(old, new, 1) + data[end:])


# --- output folder --------------------------------------------------------------------------------

@case("out-is-a-file", "error", "folder")
def _(root):
    b = renders_bundle(root / "b")
    (root / "o").write_text("not a folder")
    return ["score", str(b), "--out", str(root / "o"), *SCORE_FLAGS], "o"


@case("out-parent-is-a-file", "error", "file")
def _(root):
    b = renders_bundle(root / "b")
    (root / "f").write_text("x")
    return ["score", str(b), "--out", str(root / "f" / "o"), *SCORE_FLAGS], "f"


@case("out-locked-by-another-run", "error", "pid")
def _(root):
    b = renders_bundle(root / "b")
    return score(b), "out"   # the test holds the lock (see test_badinput_corpus.HOLD_LOCK)


@case("out-stale-lock-of-a-dead-run", "accepted")
def _(root):
    b = renders_bundle(root / "b")
    (root / "out").mkdir()
    (root / "out" / ".r360lock").write_text(json.dumps({"pid": 2 ** 22 + 7, "host": "x", "started": 0}))
    return score(b), None


def _no_tmp(out, results, stderr):
    left = [p for p in Path(out).rglob("*.tmp")]
    assert not left, left


@case("out-stale-temporaries-removed", "accepted", verify=_no_tmp)
def _(root):
    b = renders_bundle(root / "b")
    (root / "out" / ".r360cache").mkdir(parents=True)
    (root / "out" / ".results.json.k3j4h5g6.tmp").write_text("{half")
    (root / "out" / ".r360cache" / ".view_00.json.abcdefgh.tmp").write_text("{")
    return score(b), None


# --- view selection: check and score validate the same selection ----------------------------------

def _views_no_mask(root):
    b = renders_bundle(root / "b")
    return b, ["--views", "view_00", "--views", "view_09"]


@case("score-views-without-mask", "error", "view_09")
def _(root):
    b, v = _views_no_mask(root)
    return score(b, *v), "scene.toml"


@case("check-views-without-mask", "error", "view_09")
def _(root):
    b = renders_bundle(root / "b")
    return check(b, "--views", "view_00", "--views", "view_09"), "scene.toml"


@case("score-views-mask-is-a-folder", "error", "view_02")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_02.png").unlink()
    (b / "masks" / "view_02.png").mkdir()
    return score(b, "--views", "view_00,view_02"), "scene.toml"


@case("check-views-mask-is-a-folder", "error", "view_02")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_02.png").unlink()
    (b / "masks" / "view_02.png").mkdir()
    return check(b, "--views", "view_00", "--views", "view_02"), "scene.toml"


@case("score-views-mask-is-a-jpg", "error", "view_01")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_01.png").unlink()
    assert cv2.imwrite(str(b / "masks" / "view_01.jpg"), mask_image())
    return score(b, "--views", "view_0[01]"), "view_01.jpg"


@case("score-views-match-nothing", "error", "matches no view")
def _(root):
    b = renders_bundle(root / "b")
    return score(b, "--views", "frame_*"), "scene.toml"


# --- masks ----------------------------------------------------------------------------------------

def _jpeg_as_png(path: Path) -> None:
    ok, buf = cv2.imencode(".jpg", mask_image())
    path.write_bytes(buf.tobytes())


@case("check-mask-jpeg-bytes-as-png", "error", "JPEG")
def _(root):
    b = renders_bundle(root / "b")
    _jpeg_as_png(b / "masks" / "view_01.png")
    return check(b), "view_01.png"


@case("score-mask-jpeg-bytes-as-png", "error", "JPEG")
def _(root):
    b = renders_bundle(root / "b")
    _jpeg_as_png(b / "masks" / "view_01.png")
    return score(b), "view_01.png"


def _alpha_mask(path: Path) -> None:
    rgba = np.zeros((H, W, 4), np.uint8)
    rgba[..., 3] = mask_image()
    assert cv2.imwrite(str(path), rgba)


def _alpha_read(out, results, stderr):
    views = results["scenes"]["r"]["methods"]["a"]["views"]
    v1 = [r for r in views if r["view"] == "view_01"][0]
    assert v1["geometric"]["n_mask"] == int((mask_image() != 0).sum())  # the view stays in, with its target


@case("score-mask-rgba-target-in-alpha", "warning", "alpha", verify=_alpha_read)
def _(root):
    b = renders_bundle(root / "b")
    _alpha_mask(b / "masks" / "view_01.png")
    return score(b), "view_01.png"


@case("check-mask-rgba-target-in-alpha", "accepted")
def _(root):
    b = renders_bundle(root / "b")
    _alpha_mask(b / "masks" / "view_01.png")
    return check(b), None


@case("check-mask-corrupt-bytes", "error", "decode")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_02.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    return check(b), "view_02.png"


@case("check-mask-empty-file", "error", "")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_02.png").write_bytes(b"")
    return check(b), "view_02.png"


@case("check-every-mask-empty", "error", "empty")
def _(root):
    b = renders_bundle(root / "b")
    for v in VIEWS:
        assert cv2.imwrite(str(b / "masks" / f"{v}.png"), np.zeros((H, W), np.uint8))
    return check(b), "view_00.png"


@case("score-every-mask-empty", "error", "empty")
def _(root):
    b = renders_bundle(root / "b")
    for v in VIEWS:
        assert cv2.imwrite(str(b / "masks" / f"{v}.png"), np.zeros((H, W), np.uint8))
    return score(b), "view_00.png"


@case("check-masks-folder-missing", "error", "does not exist")
def _(root):
    b = renders_bundle(root / "b")
    _edit_toml(b, 'masks = "masks"', 'masks = "nomasks"')
    return check(b), "nomasks"


@case("check-masks-only-jpg", "error", "PNG")
def _(root):
    b = renders_bundle(root / "b")
    for v in VIEWS:
        (b / "masks" / f"{v}.png").unlink()
        assert cv2.imwrite(str(b / "masks" / f"{v}.jpg"), mask_image())
    return check(b), "masks"


@case("check-mask-other-aspect", "error", "camera")
def _(root):
    b = make_bundle(root / "b")
    write_mask(b / "masks" / "view_01.png", W, H + 5)
    return check(b), "view_01.png"


@case("check-mask-twice-the-size", "error", "camera")
def _(root):
    b = make_bundle(root / "b")
    write_mask(b / "masks" / "view_01.png", 2 * W, 2 * H)
    return check(b), "view_01.png"


# --- depth ----------------------------------------------------------------------------------------

def _notes(note):
    def verify(out, results, stderr):
        assert results["scenes"]["r"]["methods"]["a"]["axes"]["geo_notes"].get(note, 0) >= 1
    return verify


@case("score-method-depth-all-nan", "warning", "no valid depth", verify=_notes("no valid post depth"))
def _(root):
    return score(renders_bundle(root / "b", post_depth={"view_01": np.full((H, W), np.nan, np.float32)})), "a"


@case("score-method-depth-all-zero", "warning", "no valid depth", verify=_notes("no valid post depth"))
def _(root):
    return score(renders_bundle(root / "b", post_depth={"view_00": np.zeros((H, W), np.float32)})), "a"


@case("score-method-depth-in-mm", "warning", "depth_scale", verify=_notes("depth unit differs from pre"))
def _(root):
    mm = {v: _depth_post() * 1000.0 for v in VIEWS}
    return score(renders_bundle(root / "b", post_depth=mm)), "a"


@case("score-method-depth-in-mm-with-depth-scale", "accepted")
def _(root):
    mm = {v: _depth_post() * 1000.0 for v in VIEWS}
    return score(renders_bundle(root / "b", post_depth=mm, a_extra="depth_scale = 0.001")), None


@case("score-method-depth-16bit-png-mm", "warning", "depth_scale")
def _(root):
    b = renders_bundle(root / "b", post_depth={v: False for v in VIEWS})
    for v in VIEWS:
        assert cv2.imwrite(str(b / "a" / "depth" / f"{v}.png"), np.round(_depth_post() * 1000).astype(np.uint16))
    return score(b), "a"


@case("score-depth-negative", "error", "negative")
def _(root):
    return score(renders_bundle(root / "b", post_depth={"view_01": -_depth_post()})), "view_01.npy"


@case("score-depth-colour-mapped-png", "error", "colour")
def _(root):
    b = renders_bundle(root / "b", post_depth={"view_00": False})
    img = np.random.default_rng(1).integers(0, 255, (H, W, 3), np.uint8)
    assert cv2.imwrite(str(b / "a" / "depth" / "view_00.png"), img)
    return score(b), "view_00.png"


@case("check-depth-npy-wrong-shape", "error", "shape")
def _(root):
    return check(renders_bundle(root / "b", post_depth={"view_02": np.zeros((3, H, W), np.float32)})), "view_02.npy"


@case("check-depth-npy-garbage", "error", ".npy")
def _(root):
    b = renders_bundle(root / "b", post_depth={"view_02": False})
    (b / "a" / "depth" / "view_02.npy").write_bytes(b"not numpy at all")
    return check(b), "view_02.npy"


@case("check-depth-exr-garbage-valid-magic", "error", "corrupt EXR")
def _(root):
    b = renders_bundle(root / "b", post_depth={"view_02": False})
    (b / "a" / "depth" / "view_02.exr").write_bytes(b"\x76\x2f\x31\x01" + bytes(range(7, 250)) * 4)
    return check(b), "view_02.exr"


@case("check-depth-folder-missing", "error", "depth")
def _(root):
    b = renders_bundle(root / "b")
    for f in (b / "a" / "depth").iterdir():
        f.unlink()
    (b / "a" / "depth").rmdir()
    return check(b), "depth"


@case("check-depth-missing-one-view", "error", "view_01")
def _(root):
    return check(renders_bundle(root / "b", post_depth={"view_01": False})), "depth"


@case("check-depth-scale-negative", "error", "depth_scale")
def _(root):
    return check(renders_bundle(root / "b", a_extra="depth_scale = -1")), "scene.toml"


@case("check-depth-scale-on-a-splat-scene", "error", "depth_scale")
def _(root):
    b = make_bundle(root / "b")
    _edit_toml(b, 'scene = "methods/clean.ply"', 'scene = "methods/clean.ply"\ndepth_scale = 0.001')
    return check(b), "scene.toml"


# --- renderings -----------------------------------------------------------------------------------

@case("check-rgb-missing-one-view", "error", "view_02")
def _(root):
    b = renders_bundle(root / "b")
    (b / "a" / "rgb" / "view_02.png").unlink()
    return check(b), "rgb"


@case("check-rgb-wrong-size", "error", "mask")
def _(root):
    b = renders_bundle(root / "b")
    write_rgb(b / "a" / "rgb" / "view_00.png", W + 2, H)
    return check(b), "view_00.png"


@case("check-rgb-garbage", "error", "")
def _(root):
    b = renders_bundle(root / "b")
    (b / "a" / "rgb" / "view_00.png").write_bytes(b"garbage")
    return check(b), "view_00.png"


@case("check-rgb-folder-missing", "error", "does not exist")
def _(root):
    b = renders_bundle(root / "b")
    _edit_toml(b, 'renders = "a"', 'renders = "nothere"')
    return check(b), "nothere"


# --- splat files ----------------------------------------------------------------------------------

@case("check-ply-without-rot_3", "error", "rot_3")
def _(root):
    b = make_bundle(root / "b")
    p = b / "methods" / "clean.ply"
    _ply_header_edit(p, b"property float rot_3", b"property float rot_x")
    return check(b), "clean.ply"


@case("check-ply-with-5-f_rest", "error", "f_rest")
def _(root):
    b = make_bundle(root / "b")
    p = b / "methods" / "clean.ply"
    head = p.read_bytes()[:p.read_bytes().index(b"end_header")]
    names = re.findall(rb"property float (f_rest_\d+)", head)
    assert len(names) == 9
    data = p.read_bytes()
    for i, n in enumerate(names[5:]):  # rename 4 of 9 so only f_rest_0..4 remain
        data = data.replace(b"property float " + n + b"\n", b"property float extra_%d\n" % i, 1)
    p.write_bytes(data)
    return check(b), "clean.ply"


@case("check-compressed-ply-too-few-chunks", "error", "chunks")
def _(root):
    b = make_bundle(root / "b")
    p = b / "methods" / "clean.compressed.ply"
    save_compressed_ply(p, random_gaussians(3 * 256 - 10, sh_degree=0, seed=4))  # needs 3 chunks
    _ply_header_edit(p, b"element chunk 3", b"element chunk 2")
    _edit_toml(b, 'scene = "methods/clean.ply"', 'scene = "methods/clean.compressed.ply"')
    return check(b), "clean.compressed.ply"


@case("check-ply-truncated", "error", "truncated")
def _(root):
    b = make_bundle(root / "b")
    p = b / "pre.ply"
    p.write_bytes(p.read_bytes()[:-7])
    return check(b), "pre.ply"


@case("check-ply-extra-bytes", "error", "more than")
def _(root):
    b = make_bundle(root / "b")
    p = b / "pre.ply"
    p.write_bytes(p.read_bytes() + b"\0" * 5)
    return check(b), "pre.ply"


@case("check-ply-mesh-not-splat", "error", "not a Gaussian")
def _(root):
    b = make_bundle(root / "b")
    (b / "pre.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                               "property float z\nend_header\n0 0 0\n")
    return check(b), "pre.ply"


@case("check-ply-bad-header", "error", "")
def _(root):
    b = make_bundle(root / "b")
    (b / "pre.ply").write_bytes(b"ply\nformat banana 9\nend_header\n")
    return check(b), "pre.ply"


@case("check-ply-zero-gaussians", "error", "no Gaussians")
def _(root):
    b = make_bundle(root / "b")
    n = re.search(rb"element vertex (\d+)", (b / "pre.ply").read_bytes()).group(0)
    _ply_header_edit(b / "pre.ply", n, b"element vertex 0")
    return check(b), "pre.ply"


@case("check-splat-truncated", "error", "truncated")
def _(root):
    b = make_bundle(root / "b")
    p = b / "ref.splat"
    p.write_bytes(p.read_bytes()[:-5])
    return check(b), "ref.splat"


@case("check-splat-empty", "error", "empty")
def _(root):
    b = make_bundle(root / "b")
    (b / "ref.splat").write_bytes(b"")
    return check(b), "ref.splat"


@case("check-scene-unknown-format", "error", "unknown")
def _(root):
    b = make_bundle(root / "b")
    (b / "methods" / "clean.txt").write_text("hello")
    _edit_toml(b, 'scene = "methods/clean.ply"', 'scene = "methods/clean.txt"')
    return check(b), "clean.txt"


@case("check-scene-missing-file", "error", "no such file")
def _(root):
    b = make_bundle(root / "b")
    (b / "methods" / "clean.ply").unlink()
    return check(b), "clean.ply"


@case("check-inria-folder-without-point-cloud", "error", "")
def _(root):
    b = make_bundle(root / "b")
    (b / "methods" / "inria").mkdir()
    _edit_toml(b, 'scene = "methods/clean.ply"', 'scene = "methods/inria"')
    return check(b), "inria"


# --- cameras --------------------------------------------------------------------------------------

@case("check-cameras-missing-key", "error", "cameras")
def _(root):
    b = make_bundle(root / "b")
    _edit_toml(b, 'cameras = "cameras"\n', "")
    return check(b), "scene.toml"


@case("check-cameras-json-garbage", "error", "")
def _(root):
    b = make_bundle(root / "b")
    (b / "cams.json").write_text("{not json")
    _edit_toml(b, 'cameras = "cameras"', 'cameras = "cams.json"')
    return check(b), "cams.json"


@case("check-cameras-path-missing", "error", "")
def _(root):
    b = make_bundle(root / "b")
    _edit_toml(b, 'cameras = "cameras"', 'cameras = "nocams"')
    return check(b), "nocams"


# --- scene.toml -----------------------------------------------------------------------------------

@case("check-toml-with-utf8-bom", "accepted")
def _(root):
    b = renders_bundle(root / "b")
    p = b / "scene.toml"
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    return check(b), None


@case("score-toml-with-utf8-bom", "accepted")
def _(root):
    b = renders_bundle(root / "b")
    p = b / "scene.toml"
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    return score(b), None


@case("check-toml-invalid", "error", "invalid TOML")
def _(root):
    b = renders_bundle(root / "b")
    (b / "scene.toml").write_text("prompt = \n[[[")
    return check(b), "scene.toml"


@case("check-toml-not-utf8", "error", "UTF-8")
def _(root):
    b = renders_bundle(root / "b")
    (b / "scene.toml").write_bytes(b'prompt = "caf\xe9"\n')
    return check(b), "scene.toml"


@case("check-toml-missing-prompt", "error", "prompt")
def _(root):
    b = renders_bundle(root / "b")
    _edit_toml(b, 'prompt = "box"\n', "")
    return check(b), "scene.toml"


@case("check-toml-unknown-key", "error", "did you mean")
def _(root):
    b = renders_bundle(root / "b")
    _edit_toml(b, 'masks = "masks"', 'masks = "masks"\nmaks = "x"')
    return check(b), "scene.toml"


@case("check-method-named-pre", "error", "reserved")
def _(root):
    b = renders_bundle(root / "b")
    _edit_toml(b, "[methods.a]", "[methods.Pre]")
    return check(b), "scene.toml"


@case("check-methods-differ-in-case", "error", "case")
def _(root):
    b = renders_bundle(root / "b")
    (b / "scene.toml").write_text((b / "scene.toml").read_text() + '\n[methods.A]\nrenders = "a"\n')
    return check(b), "scene.toml"


@case("check-scene-name-with-slash", "error", "separator")
def _(root):
    b = renders_bundle(root / "b")
    _edit_toml(b, 'name = "r"', 'name = "r/x"')
    return check(b), "scene.toml"


@case("check-background-out-of-range", "error", "background")
def _(root):
    b = make_bundle(root / "b")
    _edit_toml(b, "background = [1.0, 1.0, 1.0]", "background = [2.0, 0.0, 0.0]")
    return check(b), "scene.toml"


@case("check-depth-mode-typo", "error", "did you mean")
def _(root):
    b = make_bundle(root / "b")
    _edit_toml(b, 'depth = "median"', 'depth = "medain"')
    return check(b), "scene.toml"


@case("check-not-a-bundle", "error", "not a bundle")
def _(root):
    (root / "empty").mkdir()
    return check(root / "empty"), "empty"


@case("check-bundle-missing", "error", "no such")
def _(root):
    return check(root / "nope"), "nope"


@case("check-remove360-without-prompt", "error", "prompt")
def _(root):
    return check(make_remove360(root / "s", prompt=None)), "s"


@case("check-remove360-valid", "accepted")
def _(root):
    return check(make_remove360(root / "s")), None


@case("check-valid-bundle", "accepted")
def _(root):
    return check(make_bundle(root / "b")), None


# --- command line ---------------------------------------------------------------------------------

@case("score-xi-out-of-range", "error", "--xi")
def _(root):
    return score(renders_bundle(root / "b"), "--xi", "1.5"), "--xi"


@case("score-unknown-probe-spec", "error", "probe")
def _(root):
    return score(renders_bundle(root / "b"), "--structural-probe", "nonsense:x"), "nonsense"


@case("score-probe-dir-missing", "error", "does not exist")
def _(root):
    return score(renders_bundle(root / "b"), "--structural-probe", f"sam-json:{root / 'nosam'}"), "nosam"


@case("score-gsam2-json-garbage", "error", "Grounded-SAM-2")
def _(root):
    b = renders_bundle(root / "b")
    for r in ("pre", "post"):
        write_mask(root / "g" / r / "view_00.png")
        (root / "g" / r / "view_01.json").write_text("{}")
    return score(b, "--semantic-probe", f"gsam2-json:{root / 'g'}"), "view_01.json"


# --- precomputed probes ---------------------------------------------------------------------------

def _amg_folder(folder: Path, n: int, seed: int) -> None:
    from r360gpu.probes.amg_folders import AMG_HEADER

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    rows = [AMG_HEADER]
    for i in range(n):
        m = np.zeros((H, W), np.uint8)
        y, x = rng.integers(0, H - 4), rng.integers(0, W - 4)
        m[y:y + 4, x:x + 4] = 255
        if i == 0:
            m = mask_image()  # one segment on the target, so every view has a retained mask
        assert cv2.imwrite(str(folder / f"{i}.png"), m)
        rows.append(f"{i},16,{x},{y},4,4,{x + 2}.0,{y + 2}.0,0.9{i},0.95,0,0,{W},{H}")
    (folder / "metadata.csv").write_text("\n".join(rows))  # amg.py writes no final newline


def _amg(root: Path) -> Path:
    for r, seed in (("pre", 0), ("post", 1)):
        for i, v in enumerate(VIEWS):
            _amg_folder(root / "sam" / r / v, 3, seed * 10 + i)
    return root / "sam"


def _amg_read(out, results, stderr):
    views = results["scenes"]["r"]["methods"]["a"]["views"]
    for rec in views:
        (st,) = rec["structural"].values()
        assert st["n_a"] >= 1 and st["n_b"] >= 1, st  # read (before: every view "no detection", 0 and 0)
    assert not results["warning_counts"], results["warning_counts"]


@case("score-sam-amg-layout", "accepted", verify=_amg_read)
def _(root):
    sam = _amg(root)
    return score(renders_bundle(root / "b"), "--structural-probe", f"sam-json:{sam}", "--reference-free"), None


@case("score-sam-amg-bad-metadata", "error", "metadata")
def _(root):
    sam = _amg(root)
    (sam / "post" / "view_01" / "metadata.csv").write_text("id;area\n0;16")
    return score(renders_bundle(root / "b"), "--structural-probe", f"sam-json:{sam}"), "metadata.csv"


@case("score-sam-amg-listed-png-missing", "error", "missing")
def _(root):
    sam = _amg(root)
    (sam / "pre" / "view_02" / "1.png").unlink()
    return score(renders_bundle(root / "b"), "--structural-probe", f"sam-json:{sam}"), "1.png"


def _missing_counted(out, results, stderr):
    counts = results["warning_counts"]["missing_probe_files"]
    assert sum(counts.values()) == 2, counts  # view_01 and view_02 of post
    assert stderr.count("no precomputed mask") == 1


@case("score-probe-files-missing-counted", "warning", "no precomputed mask", verify=_missing_counted)
def _(root):
    sam = _amg(root)
    for v in ("view_01", "view_02"):
        for f in (sam / "post" / v).iterdir():
            f.unlink()
        (sam / "post" / v).rmdir()
    return score(renders_bundle(root / "b"), "--structural-probe", f"sam-json:{sam}"), "post"


@case("score-sam-json-garbage", "error", "")
def _(root):
    b = renders_bundle(root / "b")
    for r in ("pre", "post"):
        (root / "sj" / r).mkdir(parents=True)
        for v in VIEWS:
            (root / "sj" / r / f"{v}.json").write_text("[{\"segmentation\": 5}]")
    return score(b, "--structural-probe", f"sam-json:{root / 'sj'}"), "view_00.json"


# --- each class of docs/input-validation.md, refused where the input enters -------------------------

@case("score-pre-depth-all-inf", "warning", "pre has no valid depth", verify=_notes("no valid pre depth"))
def _(root):
    b = renders_bundle(root / "b")
    np.save(b / "pre" / "depth" / "view_01.npy", np.full((H, W), np.inf, np.float32))
    return score(b), "view_01.npy"


def _jpeg_depth_as_png(root: Path) -> Path:
    b = renders_bundle(root / "b", post_depth={"view_01": False})
    ok, buf = cv2.imencode(".jpg", np.full((H, W), 120, np.uint8))
    (b / "a" / "depth" / "view_01.png").write_bytes(buf.tobytes())
    return b


@case("score-depth-jpeg-bytes-as-png", "error", "JPEG")
def _(root):
    return score(_jpeg_depth_as_png(root)), "view_01.png"


@case("check-depth-jpeg-bytes-as-png", "error", "JPEG")
def _(root):
    return check(_jpeg_depth_as_png(root)), "view_01.png"


@case("check-depth-saved-as-jpg", "error", "view_02.jpg")
def _(root):
    b = renders_bundle(root / "b", post_depth={"view_02": False})
    assert cv2.imwrite(str(b / "a" / "depth" / "view_02.jpg"), np.full((H, W), 120, np.uint8))
    return check(b), "depth"


def _palette_inverted(path: Path) -> None:
    from PIL import Image

    im = Image.fromarray((mask_image() > 0).astype(np.uint8), mode="P")
    im.putpalette([255, 255, 255, 0, 0, 0] + [0] * 762)  # index 0 (background) drawn white
    im.save(path)


@case("score-mask-palette-index-0-white", "warning", "palette", verify=_alpha_read)  # index != 0 is target
def _(root):
    b = renders_bundle(root / "b")
    _palette_inverted(b / "masks" / "view_01.png")
    return score(b), "view_01.png"


@case("check-mask-dangling-symlink", "error", "symbolic link")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_01.png").unlink()
    (b / "masks" / "view_01.png").symlink_to(root / "nowhere.png")
    return check(b), "view_01.png"


@case("score-mask-symlink-loop", "error", "symbolic link")
def _(root):
    b = renders_bundle(root / "b")
    (b / "masks" / "view_01.png").unlink()
    (b / "masks" / "view_01.png").symlink_to(b / "masks" / "view_01.png")
    return score(b), "view_01.png"


@case("check-rgb-dangling-symlink", "error", "symbolic link")
def _(root):
    b = renders_bundle(root / "b")
    (b / "a" / "rgb" / "view_02.png").unlink()
    (b / "a" / "rgb" / "view_02.png").symlink_to(root / "gone.png")
    return check(b), "view_02.png"


@case("out-empty", "error", "--out is empty")
def _(root):
    return ["score", str(renders_bundle(root / "b")), "--out", "", *SCORE_FLAGS], "--out"


@case("out-dangling-symlink", "error", "symbolic link")
def _(root):
    b = renders_bundle(root / "b")
    (root / "o").symlink_to(root / "missing-target")
    return ["score", str(b), "--out", str(root / "o"), *SCORE_FLAGS], "o"


@case("score-n-boot-zero", "error", "n_boot")
def _(root):
    return ["score", str(renders_bundle(root / "b")), "--out", "{out}", "--quiet", "--no-pictures",
            "--n-boot", "0"], "--n-boot"


@case("score-n-perm-negative", "error", "n_perm")
def _(root):
    return ["score", str(renders_bundle(root / "b")), "--out", "{out}", "--quiet", "--n-perm", "-3"], "--n-perm"


def _sam_dir(root: Path, claim: tuple[int, int]) -> Path:
    d = root / "sam"
    h, w = claim
    for rendering in ("pre", "post"):
        (d / rendering).mkdir(parents=True)
        for v in VIEWS:
            (d / rendering / f"{v}.json").write_text(
                json.dumps([{"segmentation": {"size": [h, w], "counts": [h * w]}}]))
    return d


@case("score-sam-json-rle-claims-huge-size", "error", "larger than the view")
def _(root):
    b = renders_bundle(root / "b")
    d = _sam_dir(root, (50000, 50000))
    return score(b, "--structural-probe", f"sam-json:{d}"), "view_00.json"


def _distorted_colmap(root: Path) -> Path:
    b = make_bundle(root / "b")
    from r360gpu.io import save_colmap

    save_colmap(b / "cameras", [camera(f"{v}.jpg") for v in VIEWS], binary=False)
    for f in ("cameras.bin", "images.bin", "points3D.bin"):
        (b / "cameras" / f).unlink(missing_ok=True)
    lines = (b / "cameras" / "cameras.txt").read_text().splitlines()
    out = []
    for line in lines:
        if line and not line.startswith("#"):
            w = line.split()
            line = " ".join([w[0], "OPENCV", *w[2:], "0.1", "0.01", "0", "0"])
        out.append(line)
    (b / "cameras" / "cameras.txt").write_text("\n".join(out) + "\n")
    return b


def _distortion_recorded(out, results, stderr):
    hits = [w for w in results["warnings"] if "distortion" in w["message"]]
    assert hits and hits[0]["scene"] == "room", results["warnings"]


@case("score-colmap-distortion-recorded", "warning", "distortion", verify=_distortion_recorded)
def _(root):
    return score(_distorted_colmap(root), "--no-controls"), "cameras/"


def _bom_read(out, results, stderr):
    prompt = results["scenes"]["room_table"]["prompt"]
    assert prompt == "table", repr(prompt)


@case("score-prompt-txt-with-bom", "warning", "byte-order mark", verify=_bom_read)
def _(root):
    f = make_remove360(root / "room_table")
    (f / "prompt.txt").write_bytes("\ufefftable\n".encode("utf-8"))
    return score(f), "prompt.txt"


@case("check-scene-every-gaussian-nan", "error", "")
def _(root):
    b = make_bundle(root / "b")
    p = b / "methods" / "clean.ply"
    save_ply(p, random_gaussians(35, sh_degree=1, seed=3), format="ascii")
    head, body = p.read_text().split("end_header\n")
    rows = ["nan " + line.split(" ", 1)[1] for line in body.splitlines()]
    p.write_text(head + "end_header\n" + "\n".join(rows) + "\n")
    return check(b), "clean.ply"


@case("check-public-folder-rgb-depth-png", "error", "colour")
def _(root):
    f = make_remove360(root / "room_table")
    img = np.random.default_rng(1).integers(0, 255, (H, W, 3), np.uint8)
    assert cv2.imwrite(str(f / "depth" / "after" / "view_01.png"), img)
    return check(f), "view_01.png"


@case("score-ray-address-refuses", "error", "127.0.0.1:1")
def _(root):
    return score(renders_bundle(root / "b"), "--ray", "127.0.0.1:1"), "Ray cluster"


@case("score-benchmark-dangling-method-folder", "error", "symbolic link")
def _(root):
    make_remove360(root / "bench" / "gc" / "room_table")
    (root / "bench" / "af").symlink_to(root / "not-there")
    return ["score", "--benchmark", str(root / "bench"), "--out", "{out}", *SCORE_FLAGS], "af"
