"""A hostile corpus on the [target] surface: each case a bundle (or objects) a user might bring, and
the one outcome it must have: a clear one-line error naming the file, the same from ``r360gpu check``
and ``r360gpu score`` (check OK means score accepts the target), or a recorded warning."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from r360gpu import cli
from r360gpu.bundle import load_bundle
from r360gpu.errors import InputError
from r360gpu.io import load_gaussians, load_mask
from r360gpu.synthetic import generate_benchmark

ARGS = dict(seed=0, n_views=4, width=64, height=48, detail=0.25)


@pytest.fixture(scope="module")
def bench(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("hostile")
    return generate_benchmark(root, scenes=("room",), methods=("clean",), ctx=ctx, **ARGS)[0]


def variant(folder, dst, table: str, given=(), mask=None):
    """A copy of the bundle without top-level masks, with the [target] ``table``; ``given`` views'
    masks are copied to given/ (or replaced by ``mask(view, (H, W) bool)``, bytes or an array)."""
    shutil.copytree(folder, dst)
    text = (dst / "scene.toml").read_text().replace('masks = "masks"\n', "")
    (dst / "given").mkdir()
    for v in given:
        target = dst / "given" / f"{v}.png"
        if mask is None:
            shutil.copy(dst / "masks" / f"{v}.png", target)
        else:
            out = mask(v, load_mask(dst / "masks" / f"{v}.png"))
            if isinstance(out, bytes):
                target.write_bytes(out)
            else:
                from PIL import Image

                Image.fromarray(out.astype(np.uint8) * 255).save(target)
    (dst / "scene.toml").write_text(text + "\n[target]\n" + table + "\n")
    return dst


def shown_views(folder):
    views = sorted(p.stem for p in (folder / "masks").glob("*.png"))
    return [v for v in views if load_mask(folder / "masks" / f"{v}.png").any()]


def _n_pre(folder):
    return load_gaussians(load_bundle(folder).pre.path).n


# name -> (build(folder, dst) -> bundle path, expected problem text, the file the line names)
def _npy(arr):
    def build(folder, dst):
        b = variant(folder, dst, 'indices = "target.npy"')
        np.save(b / "target.npy", arr(_n_pre(folder)))
        return b
    return build


def _table(table, given=False, mask=None):
    def build(folder, dst):
        return variant(folder, dst, table, shown_views(folder) if given else (), mask)
    return build


def _truncated_png(v, m) -> bytes:
    """A PNG whose header reads (so the mask's size checks out) but whose pixels cannot be decoded."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(m.astype(np.uint8) * 255).save(buf, format="PNG")
    data = buf.getvalue()
    return data[: data.index(b"IDAT") + 12]


def _save(write, name="target.npy"):
    """A [target] whose indices file ``name`` is written by ``write(path)``."""
    def build(folder, dst):
        b = variant(folder, dst, f'indices = "{name}"')
        write(b / name)
        return b
    return build


def _labelled(label, extra: int = 0):
    """A [target] given as a PLY of pre's vertex count (plus ``extra``) whose float property 'label'
    is ``label(n)``."""
    def write(path):
        from r360gpu.io.ply import write_ply

        n = load_gaussians(path.parent / "pre.ply").n + extra
        vert = np.zeros(n, [("x", "f4"), ("y", "f4"), ("z", "f4"), ("label", "f4")])
        vert["label"] = label(n)
        write_ply(path, [("vertex", vert)])
    return _save(write, "labels.ply")


def _unseen(folder, dst):
    """Indices of Gaussians no view composites at all (zero weight in every view's lift): their
    rendered target mask is empty at every view."""
    from r360gpu.lift import lift_target

    b = load_bundle(folder)
    g = load_gaussians(b.pre.path)
    cams = [b.cameras[v] for v in b.views]
    lt = lift_target(g, cams, [np.ones((c.height, c.width), bool) for c in cams])
    hidden = np.flatnonzero(lt.w_in + lt.w_out == 0)
    assert hidden.size >= 3
    return _npy(lambda n: hidden[:3])(folder, dst)


def _one_gaussian_pre(folder, dst):
    """pre cut down to one Gaussian, and a target of that Gaussian: nothing would be left."""
    from r360gpu.io.ply import read_ply, write_ply

    b = _npy(lambda n: np.array([0]))(folder, dst)
    vert = read_ply(b / "pre.ply").arrays["vertex"]
    write_ply(b / "pre.ply", [("vertex", vert[:1])])
    return b


def _pickled(path):
    np.save(path, np.array([1, "a", None], dtype=object), allow_pickle=True)


def _list_labels(path):
    """An ASCII PLY of pre's vertex count whose 'label' is a list property."""
    n = load_gaussians(path.parent / "pre.ply").n
    head = ["ply", "format ascii 1.0", f"element vertex {n}", "property float x", "property list uchar int label",
            "end_header"]
    path.write_text("\n".join(head + [f"0 1 {i % 2}" for i in range(n)]) + "\n")


def _npz_bytes() -> bytes:
    import io

    buf = io.BytesIO()
    np.savez(buf, a=np.arange(5))
    return buf.getvalue()


def _npy_claiming(path, shape):
    """A .npy whose header claims ``shape`` of int64 over 64 bytes of data (numpy would allocate it)."""
    with open(path, "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<i8", "fortran_order": False, "shape": shape})
        f.write(bytes(64))


def _truncated_npy(path):
    np.save(path, np.arange(50))
    path.write_bytes(path.read_bytes()[:-100])


CASES = {
    "indices file missing": (_table('indices = "nowhere.npy"'), "no such file", "nowhere.npy"),
    "indices out of range": (_npy(lambda n: np.array([0, n + 5])), "outside 0..", "target.npy"),
    "indices as text": (_npy(lambda n: np.array(["1", "2"])), "integers or booleans", "target.npy"),
    "indices a 0/1 mask saved as integers": (_npy(lambda n: (np.arange(n) % 7 == 0).astype(np.int64)),
                                             "each 0 or 1", "target.npy"),
    "indices a 2-D array": (_npy(lambda n: np.array([[1, 2], [3, 4]])), "flat (1-D)", "target.npy"),
    "indices every Gaussian": (_npy(lambda n: np.arange(n)), "every one of pre's", "target.npy"),
    "indices a wrong-length bool mask": (_npy(lambda n: np.ones(n - 1, bool)), "one entry per Gaussian", "target.npy"),
    "empty box": (_table("box = { min = [0, 0, 0], max = [0, 1, 1] }"), "no volume", "scene.toml"),
    "zero-size box": (_table("box = { centre = [0, 0, 0], size = [1, 0, 1] }"), "no volume", "scene.toml"),
    "box away from the scene": (_table("box = { min = [900, 900, 900], max = [901, 901, 901] }"),
                                "no Gaussian centre lies in the target box", "scene.toml"),
    "box in the wrong units": (_table("box = { min = [-1e4, -1e4, -1e4], max = [1e4, 1e4, 1e4] }"),
                               "every one of pre's", "scene.toml"),
    "box rotation as text": (_table('box = { centre = [0, 0, 0], size = [1, 1, 1], rotation = "identity" }'),
                             "rotation must be", "scene.toml"),
    "box rotation ragged": (_table("box = { centre = [0, 0, 0], size = [1, 1, 1], "
                                   "rotation = [[1, 0, 0], [0, 1], [0, 0, 1]] }"), "rotation must be", "scene.toml"),
    "undecodable mask": (_table('masks = "given"', given=True, mask=_truncated_png),
                         "given", "given/"),
    "all-empty masks": (_table('masks = "given"', given=True, mask=lambda v, m: np.zeros_like(m)),
                        "no given target mask shows the target", "scene.toml"),
    "all-full masks": (_table('masks = "given"', given=True, mask=lambda v, m: np.ones_like(m)),
                       "target at every pixel", "scene.toml"),
    # -- further cases: values a file can hold that numpy would take without a word
    "indices fractional": (_npy(lambda n: np.array([1.5, 2.0])), "whole numbers", "target.npy"),
    "indices NaN": (_npy(lambda n: np.array([1.0, np.nan])), "whole numbers", "target.npy"),
    "indices negative": (_npy(lambda n: np.array([-1, 3])), "outside 0..", "target.npy"),
    "indices a column (N, 1)": (_npy(lambda n: np.arange(10, 40).reshape(-1, 1)), "flat (1-D)", "target.npy"),
    "indices a row (1, N)": (_npy(lambda n: np.arange(10, 40).reshape(1, -1)), "flat (1-D)", "target.npy"),
    "indices a 0-d array": (_npy(lambda n: np.array(5)), "flat (1-D)", "target.npy"),
    "indices empty": (_npy(lambda n: np.array([], np.int64)), "no Gaussians", "target.npy"),
    "indices complex": (_npy(lambda n: np.array([1 + 0j, 2 + 0j])), "integers or booleans", "target.npy"),
    "indices uint64 beyond int64": (_npy(lambda n: np.array([2 ** 63 + 5, 3], np.uint64)), "too large",
                                    "target.npy"),
    "indices float beyond int64": (_npy(lambda n: np.array([1e300, 3.0])), "too large", "target.npy"),
    "indices pickled objects": (_save(_pickled), "Object arrays cannot be loaded", "target.npy"),
    "indices truncated .npy": (_save(_truncated_npy), "more than the file's", "target.npy"),
    "indices .npy header claiming 1e15 values": (_save(lambda p: _npy_claiming(p, (10 ** 15,))), "more than the file's",
                                                 "target.npy"),
    "indices an empty file": (_save(lambda p: p.write_bytes(b"")), "not a valid .npy file", "target.npy"),
    "labels a list property": (_save(_list_labels, "labels.ply"), "list properties (label)", "labels.ply"),
    "labels an empty file": (_save(lambda p: p.write_bytes(b""), "labels.ply"), "not a PLY file", "labels.ply"),
    "indices an .npz archive": (_save(lambda p: p.write_bytes(_npz_bytes())), "an .npz archive",
                                "target.npy"),
    "indices a text file": (_save(lambda p: p.write_text("1 2 3\n"), "target.txt"), ".npy or .ply", "target.txt"),
    "indices of Gaussians no view shows": (_unseen, "shows in none of the", "target.npy"),
    "labels with NaN": (_labelled(lambda n: np.where(np.arange(n) < 20, 1.0, np.where(np.arange(n) < 40, np.nan,
                                                                                       0.0))),
                        "is NaN at 20", "labels.ply"),
    "labels all zero": (_labelled(np.zeros), "no Gaussians", "labels.ply"),
    "labels one vertex too many": (_labelled(lambda n: np.arange(n) < 20, extra=1), "vertices, pre's file has",
                                   "labels.ply"),
    "target of pre's only Gaussian": (_one_gaussian_pre, "every one of pre's 1 Gaussians", "target.npy"),
    "box coordinates as text": (_table('box = { min = ["0", "0", "0"], max = ["1", "1", "1"] }'),
                                "must be 3 finite numbers", "scene.toml"),
    "box coordinates as booleans": (_table("box = { min = [false, false, false], max = [true, true, true] }"),
                                    "must be 3 finite numbers", "scene.toml"),
    "box coordinates nested": (_table("box = { min = [[0, 0, 0]], max = [[1, 1, 1]] }"),
                               "must be 3 finite numbers", "scene.toml"),
    "box NaN centre": (_table("box = { centre = [nan, 0, 0], size = [1, 1, 1] }"), "finite numbers", "scene.toml"),
    "box infinite size": (_table("box = { centre = [0, 0, 0], size = [inf, 1, 1] }"), "finite numbers",
                          "scene.toml"),
    "box negative size": (_table("box = { centre = [0, 0, 0], size = [-1, 1, 1] }"), "size must be > 0",
                          "scene.toml"),
    "box rotation scaled": (_table("box = { centre = [0, 0, 0], size = [1, 1, 1], "
                                   "rotation = [[2, 0, 0], [0, 1, 0], [0, 0, 1]] }"), "rotation must be", "scene.toml"),
    "box rotation quaternion as text": (_table('box = { centre = [0, 0, 0], size = [1, 1, 1], '
                                               'rotation = ["1", "0", "0", "0"] }'), "rotation must be", "scene.toml"),
    "box with min, max and centre": (_table("box = { min = [0, 0, 0], max = [1, 1, 1], centre = [0, 0, 0] }"),
                                     "needs min and max, or centre and size", "scene.toml"),
    "box a string": (_table('box = "0 0 0 1 1 1"'), "must be a table", "scene.toml"),
    "property without a .ply": (_table('box = { min = [0, 0, 0], max = [1, 1, 1] }\nproperty = "label"'),
                                "[target].property names", "scene.toml"),
    "masks folder empty": (_table('masks = "given"'), "masks folder has no", "given"),
    "masks of views with no camera": (lambda folder, dst: _orphan_masks(folder, dst), "with no camera",
                                      "scene.toml"),
    "masks in both folders differ": (lambda folder, dst: _masks_twice(folder, dst),
                                     "different mask in masks and in [target].masks", "scene.toml"),
    "masks at half size": (_table('masks = "given"', given=True, mask=lambda v, m: m[::2, ::2]), "mask is 32x24",
                           "given/"),
}


def _masks_twice(folder, dst):
    """Top-level masks kept, and [target].masks giving other masks of the same views."""
    b = _table('masks = "given"', given=True, mask=lambda v, m: np.roll(m, 20, axis=1))(folder, dst)
    (b / "scene.toml").write_text('masks = "masks"\n' + (b / "scene.toml").read_text())
    return b


def _orphan_masks(folder, dst):
    """Given masks named for views no camera has."""
    b = _table('masks = "given"', given=True)(folder, dst)
    for p in sorted((b / "given").glob("*.png")):
        p.rename(p.with_name("nosuch_" + p.name))
    return b


@pytest.mark.parametrize("case", sorted(CASES))
def test_check_and_score_refuse_alike(bench, tmp_path, capsys, case):
    build, text, file = CASES[case]
    b = build(bench, tmp_path / "b")
    assert cli.main(["check", str(b)]) == 2
    out = capsys.readouterr().out
    assert any(text in ln and file in ln for ln in out.splitlines()), out
    assert cli.main(["score", str(b), "--out", str(tmp_path / "out"), "--no-pictures", "--no-controls",
                     "--n-boot", "10", "--n-perm", "10"]) == 2
    err = capsys.readouterr().err  # one line, or a bundle's list of problems (one line each)
    assert "Traceback" not in err and any(text in ln and file in ln for ln in err.splitlines()), err
    assert not (tmp_path / "out" / "results.json").exists()


def test_one_full_mask_among_others_is_warned(bench, tmp_path, capsys):
    shown = shown_views(bench)
    full = shown[0]
    b = variant(bench, tmp_path / "b", 'masks = "given"', shown,
                mask=lambda v, m: np.ones_like(m) if v == full else m)
    assert cli.main(["check", str(b)]) == 0
    out = capsys.readouterr()
    assert f"given/{full}.png: the target mask is target at every pixel" in out.out + out.err


def test_a_target_of_most_of_the_scene_is_warned_and_recorded(bench, tmp_path, capsys):
    import json

    b = _npy(lambda n: np.arange(int(0.8 * n)))(bench, tmp_path / "b")
    assert cli.main(["check", str(b)]) == 0
    out = capsys.readouterr()
    assert "target.npy: the target (indices) is" in out.out + out.err and "most of the scene" in out.out + out.err
    assert cli.main(["score", str(b), "--out", str(tmp_path / "out"), "--no-pictures", "--no-controls",
                     "--no-boundary", "--n-boot", "10", "--n-perm", "10", "--quiet"]) == 0
    warned = json.loads((tmp_path / "out" / "results.json").read_text())["warnings"]
    assert any("most of the scene" in json.dumps(w) and "target.npy" in json.dumps(w) for w in warned), warned


def test_indices_and_box_together_are_warned_and_recorded(bench, tmp_path, capsys):
    """The documented priority (indices over box) holds, and the ignored box is said, by check and score."""
    import json

    b = _npy(lambda n: _visible_target(bench))(bench, tmp_path / "b")
    (b / "scene.toml").write_text((b / "scene.toml").read_text() + "box = { min = [0, 0, 0], max = [1, 1, 1] }\n")
    assert cli.main(["check", str(b)]) == 0
    out = capsys.readouterr()
    assert "gives both indices and box" in out.out + out.err
    assert cli.main(["score", str(b), "--out", str(tmp_path / "out"), "--no-pictures", "--no-controls",
                     "--no-boundary", "--n-boot", "10", "--n-perm", "10", "--quiet"]) == 0
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert any("box is ignored" in json.dumps(w) for w in res["warnings"]), res["warnings"]
    assert res["scenes"]["room"]["target"]["source"] == "indices"


@pytest.mark.parametrize("ids", ["-1 for unlabelled", "object ids"])
def test_labels_that_are_not_0_and_1_are_warned_and_recorded(bench, tmp_path, capsys, ids):
    import json

    def label(n):
        out = np.zeros(n)
        out[_visible_target(bench)] = 1.0
        out[np.flatnonzero(out == 0)[::50]] = -1.0 if ids == "-1 for unlabelled" else 7.0
        return out

    b = _labelled(label)(bench, tmp_path / "b")
    assert cli.main(["check", str(b)]) == 0
    out = capsys.readouterr()
    assert "labels.ply: vertex property 'label' takes 2 non-zero value(s)" in out.out + out.err
    assert cli.main(["score", str(b), "--out", str(tmp_path / "out"), "--no-pictures", "--no-controls",
                     "--no-boundary", "--n-boot", "10", "--n-perm", "10", "--quiet"]) == 0
    warned = json.loads((tmp_path / "out" / "results.json").read_text())["warnings"]
    assert any("map of object ids" in json.dumps(w) for w in warned), warned


_VISIBLE: dict = {}


def _visible_target(folder) -> np.ndarray:
    """The indices of the target lifted from the bundle's own masks (a target every check accepts)."""
    from r360gpu.lift.resolve import check_target

    if folder not in _VISIBLE:
        b = variant(folder, folder.parent / "visible", 'masks = "given"', shown_views(folder))
        _VISIBLE[folder] = check_target(load_bundle(b)).indices
    return _VISIBLE[folder]


def _rgba(v, m) -> bytes:
    import io

    from PIL import Image

    a = np.zeros(m.shape + (4,), np.uint8)
    a[..., 0], a[..., 3] = m * 255, 255
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG")
    return buf.getvalue()


def _grey16(v, m) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(m.astype(np.uint16) * 40000).save(buf, format="PNG")
    return buf.getvalue()


# name -> (build, the build whose target it must equal): forms a user may write that mean the same
SAME_TARGET = {
    "indices with duplicates": (lambda f, d: _npy(lambda n: np.repeat(_visible_target(f), 3))(f, d),
                                lambda f, d: _npy(lambda n: _visible_target(f))(f, d)),
    "indices as whole floats": (lambda f, d: _npy(lambda n: _visible_target(f).astype(np.float64))(f, d),
                                             lambda f, d: _npy(lambda n: _visible_target(f))(f, d)),
    "indices as booleans": (lambda f, d: _npy(lambda n: np.isin(np.arange(n), _visible_target(f)))(f, d),
                            lambda f, d: _npy(lambda n: _visible_target(f))(f, d)),
    "box rotation a reflection": (_table("box = { centre = [0.8, 1.97, 0.4], size = [4.8, 1.75, 1.0], "
                                         "rotation = [[1, 0, 0], [0, 1, 0], [0, 0, -1]] }"),
                                  _table("box = { centre = [0.8, 1.97, 0.4], size = [4.8, 1.75, 1.0] }")),
    "box quaternion not unit": (_table("box = { centre = [0.8, 1.97, 0.4], size = [4.8, 1.75, 1.0], "
                                       "rotation = [2, 0, 0, 0] }"),
                                _table("box = { centre = [0.8, 1.97, 0.4], size = [4.8, 1.75, 1.0] }")),
    "box as min/max": (_table("box = { min = [-1.6, 1.095, -0.1], max = [3.2, 2.845, 0.9] }"),
                       _table("box = { centre = [0.8, 1.97, 0.4], size = [4.8, 1.75, 1.0] }")),
    "masks 16-bit": (_table('masks = "given"', given=True, mask=_grey16), _table('masks = "given"', given=True)),
    "masks RGBA": (_table('masks = "given"', given=True, mask=_rgba), _table('masks = "given"', given=True)),
    "one folder as masks and [target].masks": (
        lambda f, d: _also_top_level(_table('masks = "given"', given=True)(f, d)),
        _table('masks = "given"', given=True)),
}


def _also_top_level(b):
    """The bundle ``b`` with its [target] mask folder also named as the top-level masks."""
    (b / "scene.toml").write_text('masks = "given"\n' + (b / "scene.toml").read_text())
    return b


@pytest.mark.parametrize("case", sorted(SAME_TARGET))
def test_equivalent_forms_give_the_same_target(bench, tmp_path, case):
    from r360gpu.lift.resolve import check_target

    build, same = SAME_TARGET[case]
    got = check_target(load_bundle(build(bench, tmp_path / "a")))
    want = check_target(load_bundle(same(bench, tmp_path / "b")))
    assert 0 < got.target.sum() < got.n and np.array_equal(got.target, want.target)


OBJECT_CASES = {
    "indices a string": ({"indices": "12"}, "got a str"),
    "indices a set": ({"indices": {1, 2}}, "got a set"),
    "indices ragged": ({"indices": [[1, 2], [3]]}, "ragged"),
    "indices objects": ({"indices": [None, 1]}, "integers or booleans"),
    "box rotation text": ({"box": {"centre": [0, 0, 0], "size": [1, 1, 1], "rotation": "I"}}, "rotation must be"),
    "box rotation ragged": ({"box": {"centre": [0, 0, 0], "size": [1, 1, 1], "rotation": [[1, 0, 0], [0, 1]]}},
                            "rotation must be"),
    "mask text": ({"masks": {"VIEW": "mask.png"}}, "must be an (H, W) array"),
    "mask with NaN": ({"masks": {"VIEW": np.full((48, 64), np.nan)}}, "the mask is NaN at 3072 pixels"),
    "box corners as text": ({"box": {"min": ["0", "0", "0"], "max": [1, 1, 1]}}, "must be 3 finite numbers"),
    "box corners as booleans": ({"box": {"min": np.zeros(3, bool), "max": np.ones(3)}}, "must be 3 finite numbers"),
}


def test_a_box_of_numpy_arrays_is_taken():
    from r360gpu.io.box import Box

    box = Box.from_table({"centre": np.zeros(3, np.float32), "size": np.full(3, 2), "rotation": np.eye(3)})
    assert box.contains(np.array([[0.9, -0.9, 0.5], [1.1, 0, 0]])).tolist() == [True, False]


@pytest.mark.parametrize("case", sorted(OBJECT_CASES))
def test_scene_from_objects_refuses_values_numpy_cannot_take(bench, case):
    import r360gpu

    target, text = OBJECT_CASES[case]
    b = load_bundle(bench)
    if "masks" in target:
        target = {"masks": {b.views[0]: target["masks"]["VIEW"]}}
    pre = load_gaussians(b.pre.path)
    with pytest.raises(InputError) as e:
        r360gpu.scene_from_objects("room", "sofa", {}, pre, {"clean": pre}, cameras=b.cameras, target=target)
    assert text in str(e.value) and "\n" not in str(e.value)


# --- options: each bad value refused when EvaluateOptions is built, and by the CLI (exit 2, one line)

OPTION_CASES = [  # (EvaluateOptions keyword, bad value, CLI arguments or None, text of the error)
    ("orbit", -2, ["--orbit", "-2"], "orbit (--orbit)"),
    ("orbit", 2.5, ["--orbit", "2.5"], "orbit"),
    ("orbit", "4", None, "orbit (--orbit)"),
    ("orbit", True, None, "orbit (--orbit)"),
    ("orbit", 100000, ["--orbit", "100000"], "orbit (--orbit)"),  # a typo that would run for days
    ("orbit", 10 ** 12, None, "orbit (--orbit)"),
    ("orbit_radius", float("nan"), ["--orbit", "2", "--orbit-radius", "nan"], "orbit_radius (--orbit-radius)"),
    ("orbit_radius", 0.0, ["--orbit", "2", "--orbit-radius", "0"], "orbit_radius (--orbit-radius)"),
    ("orbit_elevation", (0.0, 95.0), ["--orbit", "2", "--orbit-elevation", "0", "95"], "orbit_elevation"),
    ("orbit_elevation", (float("nan"), 10.0), ["--orbit", "2", "--orbit-elevation", "nan", "10"],
     "orbit_elevation"),
    ("orbit_azimuth", (10.0, 10.0), ["--orbit", "2", "--orbit-azimuth", "10", "10"], "orbit_azimuth"),
    ("orbit_azimuth", (0.0, 720.0), ["--orbit", "2", "--orbit-azimuth", "0", "720"], "orbit_azimuth"),
    ("prune_residuals", float("nan"), ["--prune-residuals", "nan"], "prune_residuals (--prune-residuals)"),
    ("prune_residuals", -3, ["--prune-residuals", "-3"], "prune_residuals (--prune-residuals)"),
    ("prune_residuals", 1.0, ["--prune-residuals", "1.0"], "prune_residuals (--prune-residuals)"),
    ("residuals", "yes", None, "residuals (--residuals)"),
    ("prune_residuals", 0, ["--prune-residuals", "0"], "prune_residuals (--prune-residuals)"),
    ("prune_residuals", 1.5, ["--prune-residuals", "1.5"], "prune_residuals (--prune-residuals)"),
    ("prune_residuals", "10", ["--prune-residuals", "ten"], "prune"),
    ("boundary", 1, None, "boundary"),
    ("pictures", None, None, "pictures"),
    ("controls", "no", None, "controls"),
    ("antialiased", 0, None, "antialiased"),
    ("reference_free", "yes", None, "reference_free"),
    ("lpips_model", 3, None, "lpips_model"),
    ("ght", {"nu": -1.0}, None, "ght.nu"),
    ("ght", {"omega": 2.0}, None, "ght.omega"),
    ("ght", {"mu": 1.0}, None, "unknown parameter"),
    ("ght", "default", None, "ght must be"),
    ("xis", (0.3, 1.5), ["--xi", "0.3,1.5"], "xi"),
    ("n_boot", 0, ["--n-boot", "0"], "n_boot"),
    ("seed", -1, ["--seed", "-1"], "seed"),
    ("depth", "mean", None, "depth"),
]


@pytest.mark.parametrize("key, value, argv, text", OPTION_CASES)
def test_every_option_is_checked_when_built_and_by_the_cli(bench, tmp_path, capsys, key, value, argv, text):
    from r360gpu.pipeline import EvaluateOptions

    with pytest.raises(InputError, match=text.replace("(", r"\(").replace(")", r"\)")) as e:
        EvaluateOptions(**{key: value})
    assert "\n" not in str(e.value)
    if argv is None:
        return
    out = tmp_path / "out"
    try:
        rc = cli.main(["score", str(bench), "--out", str(out), "--no-pictures", *argv])
    except SystemExit as exit_:  # argparse refuses what its own type cannot read: usage and one error line
        rc = exit_.code
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith(("r360gpu: error", "usage"))
           or "error:" in ln]
    assert rc == 2 and not out.exists()
    assert sum("error" in ln for ln in err) == 1, err


def test_the_orbit_pose_count_is_bounded_where_poses_are_made_and_for_inpaint():
    from r360gpu.lift.orbit import MAX_POSES, orbit_cameras
    from r360gpu.pipeline.inpaint import score_scenes

    with pytest.raises(InputError, match=f"from 1 to {MAX_POSES}"):
        orbit_cameras(np.zeros(3), [], MAX_POSES + 1)
    with pytest.raises(InputError, match="orbit"):
        score_scenes([], protocol="remove360", orbit=MAX_POSES + 1)


@pytest.mark.parametrize("workers", [0, -3, 2.5, "4", True])
def test_process_counts_are_checked_by_one_function(workers):
    from r360gpu.pipeline.processes import ProcessExecutor

    with pytest.raises(InputError, match="--processes must be at least 1"):
        ProcessExecutor(workers)


# --- names: a method may not take the name of another method's derived output

@pytest.mark.parametrize("names, refused", [
    (("clean", "clean+pruned"), True),
    (("clean", "CLEAN+Pruned"), True),      # equal ignoring case: the same file on macOS and Windows
    (("clean+pruned",), False),             # no method 'clean': its own what-if is clean+pruned+pruned
    (("clean", "clean+pruned2"), False),
])
def test_a_method_named_like_anothers_pruned_what_if_is_refused(bench, tmp_path, capsys, names, refused):
    import r360gpu

    b = tmp_path / "b"
    shutil.copytree(bench, b)
    text = (b / "scene.toml").read_text()
    for name in names:
        if name != "clean":
            text += f'\n[methods."{name}"]\nscene = "methods/clean.ply"\n'
    if "clean" not in names:
        text = text.replace("[methods.clean]", "[methods.other]").replace("[expected.clean]", "[expected.other]")
    (b / "scene.toml").write_text(text)
    rc = cli.main(["check", str(b)])
    out = capsys.readouterr().out
    assert rc == (2 if refused else 0), out
    assert ("pruned what-if" in out) == refused
    pre = load_gaussians(load_bundle(bench).pre.path)
    call = lambda: r360gpu.scene_from_objects("room", "sofa", {}, pre, {n: pre for n in names},  # noqa: E731
                                              cameras=load_bundle(bench).cameras, target={"indices": [0, 1, 2]})
    if refused:
        with pytest.raises(InputError, match="pruned what-if"):
            call()
    else:
        call()
