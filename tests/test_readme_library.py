"""The scoring samples of docs/library.md, run as written (the code blocks are read from the page).

The second sample makes its inputs (a pipeline's own) from the demo's room; here a small demo bundle."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[1] / "docs" / "library.md"
OPTS = dict(n_boot=200, n_perm=100)


def _samples() -> list[str]:
    text = PAGE.read_text(encoding="utf-8")
    section = text[text.index("## Scoring"):]
    section = section[:section.index("\n## ", 5)]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    return [b for b in blocks if "r360gpu.evaluate(" in b]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory, ctx):
    from r360gpu.synthetic import generate_benchmark

    root = tmp_path_factory.mktemp("readme")
    generate_benchmark(root / "r360-demo" / "benchmark", seed=0, n_views=2, width=96, height=72, detail=0.25,
                       methods=["clean", "recoloured"], ctx=ctx)
    return root


def test_the_page_has_both_samples():
    samples = _samples()
    assert len(samples) == 2
    assert "DeviceViewsSource" in samples[1] and "device=my_wgpu_device" in samples[1]


def test_bundles_on_disk_sample(scenes, monkeypatch):
    import r360gpu

    monkeypatch.chdir(scenes)
    # The sample's own options with the statistics shortened (the sample names xis only).
    real = r360gpu.EvaluateOptions
    monkeypatch.setattr(r360gpu, "EvaluateOptions", lambda **kw: real(**{**OPTS, **kw}), raising=False)
    exec(compile(_samples()[0], "docs/library.md", "exec"), {})
    for f in ("results.json", "results.csv", "tables.md", "tables.tex", "report.html"):
        assert (scenes / "out" / f).is_file(), f  # evaluate(out=...) writes what the CLI writes
    assert any((scenes / "out" / "pictures" / "room").rglob("*.png"))


def test_device_sharing_sample(scenes, monkeypatch, ctx):
    """On a device of its own (not r360gpu's shared one), with DeviceViewsSource made without ctx, pictures
    written."""
    import r360gpu

    monkeypatch.chdir(scenes)
    real_evaluate = r360gpu.evaluate
    runs = []

    def evaluate(*a, **kw):
        kw.setdefault("options", r360gpu.EvaluateOptions(**OPTS))
        runs.append(real_evaluate(*a, progress=False, **kw))
        return runs[-1]

    monkeypatch.setattr(r360gpu, "evaluate", evaluate, raising=False)
    ns: dict = {}
    exec(compile(_samples()[1], "docs/library.md", "exec"), ns)
    assert ns["my_wgpu_device"] is not ctx.device  # the sample's own device, not r360gpu's shared one
    in_memory, on_device = runs
    a = in_memory["scenes"]["room"]["methods"]["mine"]["axes"]
    d = on_device["scenes"]["room"]["methods"]["mine"]["axes"]
    assert (a["s_sem"], a["s_geo"], a["s_str"]) == (d["s_sem"], d["s_geo"], d["s_str"])
    assert on_device["scenes"]["room"]["sources"]["pre"]["kind"] == "device"
    pictures = on_device["scenes"]["room"]["methods"]["mine"]["pictures"]
    assert pictures and all((scenes / "out-mine" / p).is_file() for p in pictures.values())
    assert (scenes / "out-mine" / "report.html").is_file()


def test_device_views_source_on_another_device_is_refused(ctx):
    import wgpu

    from r360gpu.errors import InputError
    from r360gpu.gpu import get_context
    from r360gpu.render.sources import DeviceViewsSource, open_source

    other = wgpu.gpu.request_adapter_sync(power_preference="high-performance").request_device_sync()
    src = DeviceViewsSource({}, ctx=get_context(device=other))
    with pytest.raises(InputError, match="another device"):
        open_source(src, ctx=ctx)
    assert open_source(DeviceViewsSource({}), ctx=ctx).ctx is ctx
