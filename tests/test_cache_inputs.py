"""The view cache holds what was read: any change of any input's bytes at any moment of a run changes the
next run's result exactly as a fresh run would (class 1 of docs/input-validation.md).

Generated, not picked: hypothesis chooses which input file changes (a mask, pre's or the method's RGB or
depth), at which read of the run (the k-th call of :func:`r360gpu.util.filehash.read_file`, the one
place every reader gets its bytes), and whether the original bytes come back right after that read
("replaced, then restored", which a key computed before reading would not notice).  Then the next run on
the same ``--out`` must give the numbers a fresh run on a new ``--out`` gives for the files as they are.

R360_FUZZ_EXAMPLES (default 8) sets the number of generated runs.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from badinput_cases import SCORE_FLAGS, _depth_pre, renders_bundle
from bundle_factory import H, VIEWS, W, write_rgb
import r360gpu.io.exr
import r360gpu.io.masks
import r360gpu.io.npy
import r360gpu.io.ply
import r360gpu.io.renders
import r360gpu.io.splat
from r360gpu import cli
from r360gpu.util import filehash

# Every module that reads input bytes (through filehash.read_file, the one place they are hashed).
READERS = [r360gpu.io.exr, r360gpu.io.masks, r360gpu.io.npy, r360gpu.io.ply, r360gpu.io.renders, r360gpu.io.splat]

EXAMPLES = int(os.environ.get("R360_FUZZ_EXAMPLES", "8"))

# (relative path, how to write the other bytes)
FILES = [f"masks/{v}.png" for v in VIEWS] + [f"{src}/{kind}/{v}.{ext}" for src in ("pre", "a")
                                            for kind, ext in (("rgb", "png"), ("depth", "npy"))
                                            for v in VIEWS]


def _other_bytes(rel: str, tmp: Path) -> bytes:
    """Valid bytes of the same kind that change the scores."""
    p = tmp / "other" / Path(rel).name
    p.parent.mkdir(parents=True, exist_ok=True)
    if rel.startswith("masks/"):
        import cv2

        m = np.zeros((H, W), np.uint8)
        m[H // 2:, W // 2:] = 255  # another target
        assert cv2.imwrite(str(p), m)
    elif "/rgb/" in rel:
        write_rgb(p, seed=99)
    else:
        np.save(p, _depth_pre() * (1.5 if rel.startswith("a/") else 0.5))
    return p.read_bytes()


def _numbers(out: Path) -> dict:
    """What a result says about the methods: per-view records and axes (no times, no warnings)."""
    res = json.loads((out / "results.json").read_text())
    return {s: {m: {"axes": d["axes"], "views": d["views"]} for m, d in sc["methods"].items()}
            for s, sc in res["scenes"].items()}


def _score(bundle: Path, out: Path) -> int:
    return cli.main(["score", str(bundle), "--out", str(out), *SCORE_FLAGS])


def _readers_patched(monkeypatch, on_read):
    """Route every reader's read_file through ``on_read(path, real_read)``."""
    real = filehash.read_file

    def patched(path):
        return on_read(path, real)

    for mod in READERS:  # imported above, so none imports the patched function and keeps it
        assert mod.read_file is real, mod
        monkeypatch.setattr(mod, "read_file", patched)


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(rel=st.sampled_from(FILES), on_own_read=st.booleans(), moment=st.integers(0, 30), restore=st.booleans())
def test_change_during_a_run_then_next_run_is_fresh(rel, on_own_read, moment, restore, tmp_path_factory,
                                                    monkeypatch, capsys):
    """on_own_read: the file changes just before its own ``moment``-th read (mod its reads), else
    just before the ``moment``-th read of any file; restore: the original bytes come back right after
    that read."""
    tmp = tmp_path_factory.mktemp("cache")
    bundle = renders_bundle(tmp / "b")
    target = bundle / rel
    original, other = target.read_bytes(), _other_bytes(rel, tmp)
    out = tmp / "out"
    filehash.forget()
    calls = {"n": 0, "done": False}

    def on_read(path, real):
        counted = not on_own_read or Path(path) == target
        hit = counted and not calls["done"] and calls["n"] >= (moment % 2 if on_own_read else moment)
        calls["n"] += counted
        if not hit:
            return real(path)
        calls["done"] = True
        target.write_bytes(other)  # replaced just before this read (a sync tool, another job)
        try:
            return real(path)
        finally:
            if restore:
                target.write_bytes(original)  # and put back: the bytes the key was made of

    with monkeypatch.context() as m:
        _readers_patched(m, on_read)
        rc = _score(bundle, out)  # the run the change meets
    assert rc in (0, 2)
    next_run = _score(bundle, out)
    filehash.forget()
    fresh = _score(bundle, tmp / "fresh")
    capsys.readouterr()
    assert next_run == 0 and fresh == 0
    assert _numbers(out) == _numbers(tmp / "fresh"), (rel, on_own_read, moment, restore)


def test_replaced_and_restored_during_a_read_is_not_cached(tmp_path, monkeypatch, capsys):
    """The method's depth of one view is replaced (by pre's: nothing removed)
    while the run reads it, then restored.  Its cell must not be kept under the original key."""
    bundle = renders_bundle(tmp_path / "b")
    target = bundle / "a" / "depth" / "view_01.npy"
    original = target.read_bytes()
    np.save(tmp_path / "same.npy", _depth_pre())
    other = (tmp_path / "same.npy").read_bytes()
    filehash.forget()

    def on_read(path, real):
        if Path(path) == target:
            target.write_bytes(other)
            try:
                return real(path)
            finally:
                target.write_bytes(original)
        return real(path)

    out = tmp_path / "out"
    with monkeypatch.context() as m:
        _readers_patched(m, on_read)
        assert _score(bundle, out) == 0
    res = json.loads((out / "results.json").read_text())
    capsys.readouterr()
    assert _score(bundle, out) == 0
    filehash.forget()
    assert _score(bundle, tmp_path / "fresh") == 0
    assert _numbers(out) == _numbers(tmp_path / "fresh")
    assert any("changed while the run read it" in w["message"] and w["file"].endswith("view_01.npy")
               for w in res["warnings"]), res["warnings"]


def test_read_file_hashes_the_bytes_it_returns(tmp_path):
    p = tmp_path / "f.bin"
    p.write_bytes(b"abc")
    filehash.forget()
    assert filehash.read_file(p) == b"abc"
    import hashlib

    assert filehash.decoded_digest(p) == hashlib.blake2b(b"abc", digest_size=16).hexdigest()
    assert filehash.content_digest(p) == filehash.decoded_digest(p)
    p.write_bytes(b"abd")
    assert filehash.content_digest(p) != filehash.decoded_digest(p)
    with pytest.raises(OSError):
        filehash.read_file(tmp_path / "missing")


def test_the_patched_readers_are_every_module_that_reads_through_read_file():
    root = Path(r360gpu.io.__file__).resolve().parents[1]
    users = sorted(".".join(("r360gpu", *p.relative_to(root).with_suffix("").parts))
                   for p in root.rglob("*.py") if "filehash import read_file" in p.read_text(encoding="utf-8"))
    assert users == sorted(m.__name__ for m in READERS)


def test_digests_are_remembered_only_for_settled_files(tmp_path, monkeypatch):
    """A file written in the last 2 s may be rewritten in the same tick of the file system's clock
    (same size, same times): its digest is not remembered.  An older one is, so a rerun reads nothing."""
    p = tmp_path / "f.bin"
    p.write_bytes(b"one")
    filehash.forget()
    filehash.content_digest(p)
    assert str(p) not in filehash._memo
    monkeypatch.setattr(filehash, "_SETTLED_NS", -1)  # as if the file were old
    first = filehash.content_digest(p)
    assert filehash._memo[str(p)][1] == first
    reads = []
    real_open = open
    monkeypatch.setattr("builtins.open", lambda *a, **k: reads.append(a[0]) or real_open(*a, **k))
    assert filehash.content_digest(p) == first and reads == []  # remembered: not read again


def test_a_file_keyed_before_is_not_hashed_again_when_decoded(tmp_path, monkeypatch):
    """A run keys its inputs (content_digest) and then decodes them (read_file): the digest taken for
    the key is the decoded bytes' as long as the file's identity and times did not change; a write
    in between (new ctime) makes read_file hash what it read."""
    import hashlib

    p = tmp_path / "f.bin"
    p.write_bytes(b"one")
    filehash.forget()
    monkeypatch.setattr(filehash, "_SETTLED_NS", -1)  # as if the file were old
    keyed = filehash.content_digest(p)
    hashed = []
    real = hashlib.blake2b
    monkeypatch.setattr(filehash.hashlib, "blake2b", lambda *a, **k: hashed.append(a) or real(*a, **k))
    assert filehash.read_file(p) == b"one" and filehash.decoded_digest(p) == keyed and hashed == []
    import time

    time.sleep(0.05)  # past the file system clock's tick (what _SETTLED_NS, patched here, guards against)
    p.write_bytes(b"two")  # same size, new bytes, new ctime: the key no longer holds
    assert filehash.read_file(p) == b"two" and hashed
    assert filehash.decoded_digest(p) == real(b"two", digest_size=16).hexdigest() != keyed
