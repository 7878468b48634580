"""Caches answer only for the code that filled them: r360gpu.util.code_id.code_digest covers every
source file and shader, and a run under other code recomputes (probe outputs, view cells, fits)."""
from __future__ import annotations

import json

import pytest

from badinput_cases import SCORE_FLAGS, renders_bundle
from r360gpu.cli import main
from r360gpu.util import code_id


@pytest.fixture
def fake_package(tmp_path, monkeypatch):
    """code_id looking at a small package of its own: r360gpu/{a.py, sub/b.py}, shaders/k.wgsl."""
    pkg = tmp_path / "r360gpu"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "sub" / "b.py").write_text("y = 2\n")
    (tmp_path / "shaders").mkdir()
    (tmp_path / "shaders" / "k.wgsl").write_text("fn f() {}\n")
    monkeypatch.setattr(code_id, "_PKG", pkg)
    monkeypatch.delenv("R360GPU_SHADER_DIR", raising=False)
    code_id.code_digest.cache_clear()
    yield pkg
    code_id.code_digest.cache_clear()


def _digest() -> str:
    code_id.code_digest.cache_clear()
    return code_id.code_digest()


def test_the_digest_follows_every_source_file_and_shader(fake_package, tmp_path, monkeypatch):
    first = _digest()
    assert _digest() == first  # deterministic
    # what does not matter: bytecode, data files
    (fake_package / "__pycache__").mkdir()
    (fake_package / "__pycache__" / "a.cpython-311.pyc").write_bytes(b"\0")
    (fake_package / "notes.txt").write_text("x")
    assert _digest() == first
    seen = {first}
    for change in (lambda: (fake_package / "a.py").write_text("x = 2\n"),
                   lambda: (fake_package / "sub" / "b.py").rename(fake_package / "sub" / "c.py"),
                   lambda: (fake_package / "new.py").write_text(""),
                   lambda: (tmp_path / "shaders" / "k.wgsl").write_text("fn g() {}\n")):
        change()
        d = _digest()
        assert d not in seen
        seen.add(d)
    elsewhere = tmp_path / "override"
    elsewhere.mkdir()
    (elsewhere / "k.wgsl").write_text("fn h() {}\n")
    monkeypatch.setenv("R360GPU_SHADER_DIR", str(elsewhere))
    assert _digest() not in seen
    assert code_id.version_id().endswith("+" + code_id.code_digest()[:12])


def test_a_run_under_other_code_recomputes_what_the_cache_holds(tmp_path, monkeypatch, capsys):
    """Same inputs, same options, same --out: under the same code the second run scores nothing
    (view cache); under other code it scores every view again and probes again (the probe cache
    misses too), with the same numbers."""
    bundle = renders_bundle(tmp_path / "b")
    out = tmp_path / "out"
    args = ["score", str(bundle), "--out", str(out), *SCORE_FLAGS, "--structural-probe", "builtin"]
    assert main(args) == 0, capsys.readouterr().err
    first = json.loads((out / "results.json").read_text())
    assert main(args) == 0
    again = json.loads((out / "results.json").read_text())
    assert again["timing"]["stages_s"].get("measure", 0) == 0  # all from the view cache

    from r360gpu.probes import cache as probe_cache

    misses = []
    real_load = probe_cache.ProbeCache.load

    def counting_load(self, probe_name, key, kind):
        got = real_load(self, probe_name, key, kind)
        misses.append(got is None)
        return got

    monkeypatch.setattr(probe_cache.ProbeCache, "load", counting_load)
    monkeypatch.setattr(code_id, "code_digest", lambda: "another-checkout")
    assert main(args) == 0, capsys.readouterr().err
    other = json.loads((out / "results.json").read_text())
    assert other["timing"]["stages_s"].get("measure", 0) > 0  # every view scored again
    assert misses and all(misses)  # and every probe reading computed again
    assert other["scenes"] == first["scenes"]
