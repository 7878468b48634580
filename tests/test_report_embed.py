"""The contact sheets' embedding JPEGs: made by the picture writer from the sheet in memory,
the same bytes as made from the PNG at report time, and report.html the same either way."""
from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest

from r360gpu.errors import R360Warning
from r360gpu.report import embed
from r360gpu.report.embed import EMBED_WIDTH, JPEG_QUALITY, jpeg_from_png, load_embed, sheet_jpeg, store_embed
from r360gpu.report.html import write_html
from r360gpu.report.contact_sheets import contact_sheet, sheet_image

from report_fake import fake_results


def _panels(n: int, seed: int):
    rng = np.random.default_rng(seed)
    # photographic-ish content: smooth gradients plus noise, so the JPEG is not trivial
    out = []
    for i in range(n):
        h, w = int(rng.integers(40, 200)), int(rng.integers(40, 260))
        yy, xx = np.mgrid[0:h, 0:w]
        img = np.stack([xx * 255 // max(1, w - 1), yy * 255 // max(1, h - 1), np.full_like(xx, 40 * i)], -1)
        img = np.clip(img + rng.integers(-30, 30, img.shape), 0, 255).astype(np.uint8)
        out.append((f"panel {i}", img))
    return out


def _area_jpeg(png: bytes) -> bytes:
    """report.html's JPEG as first made: decode, area resize to EMBED_WIDTH, encode (embed_jpeg
    still averages areas for sheets that are not reduced, or reduced 2x and more)."""
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    if img.shape[1] > EMBED_WIDTH:
        h = max(1, round(img.shape[0] * EMBED_WIDTH / img.shape[1]))
        img = cv2.resize(img, (EMBED_WIDTH, h), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    assert ok
    return buf.tobytes()


# (panels, panel width) -> sheet widths 108 (narrow), 109 (odd), 960 (exactly EMBED_WIDTH),
# 976 (just wider), 1629 (odd, wide), 4 + 5 * 804 = 4024 (4x wider)
@pytest.mark.parametrize("n,width", [(1, 100), (1, 101), (2, 474), (3, 320), (5, 321), (5, 800)])
def test_writer_jpeg_is_the_jpeg_made_from_the_png(tmp_path, n, width):
    panels = _panels(n, seed=n * 1000 + width)
    path = contact_sheet(tmp_path / "sheet.png", panels, panel_width=width, title="t", lines=["a line"],
                         embed_cache=tmp_path / "embed")
    png = path.read_bytes()
    rgb = sheet_image(panels, panel_width=width, title="t", lines=["a line"])
    assert rgb.shape[1] == 4 + n * (width + 4)
    # the premise: the PNG is lossless, decoding it gives the array the writer had
    assert np.array_equal(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR),
                          cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    cached = load_embed(tmp_path / "embed", png)
    assert cached is not None and cached[:2] == b"\xff\xd8"
    assert cached == jpeg_from_png(png)
    jpg = cv2.imdecode(np.frombuffer(cached, np.uint8), cv2.IMREAD_COLOR)
    assert jpg.shape[1] == min(rgb.shape[1], EMBED_WIDTH)
    area = _area_jpeg(png)
    if not EMBED_WIDTH < rgb.shape[1] < 2 * EMBED_WIDTH:  # not reduced, or reduced 2x and more: areas averaged
        assert cached == area
    else:  # reduced less than 2x: bilinear, about a grey level from the area average (noisy panels: the most)
        diff = np.abs(jpg.astype(int) - cv2.imdecode(np.frombuffer(area, np.uint8), cv2.IMREAD_COLOR))
        assert diff.mean() < 1.5, diff.mean()


def test_no_cache_folder_writes_no_jpeg(tmp_path):
    contact_sheet(tmp_path / "sheet.png", _panels(2, 0), panel_width=120)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sheet.png"]


def _report(results, out, cache=None):
    with warnings.catch_warnings():
        warnings.simplefilter("error", R360Warning)  # every picture must embed
        return write_html(results, out, embed_cache=cache).read_bytes()


@pytest.fixture(scope="module")
def fake(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    results = fake_results(out)
    return results, out, _report(results, out)


def _sheets(results):
    return [p for s in results["scenes"].values() for m in s["methods"].values()
            for p in (m.get("pictures") or {}).values()]


def test_report_is_the_same_with_and_without_the_cache(fake, tmp_path, monkeypatch):
    results, out, plain = fake
    cache = tmp_path / "embed"
    for rel in _sheets(results):  # as the picture writer would have left them
        png = (out / rel).read_bytes()
        store_embed(cache, png, embed.embed_jpeg(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)))
    n = len(list(cache.iterdir()))
    assert n == len(set(_sheets(results))) > 4

    calls = []
    real = embed.jpeg_from_png
    monkeypatch.setattr(embed, "jpeg_from_png", lambda png: calls.append(1) or real(png))
    assert _report(results, out, cache) == plain
    assert calls == []  # every sheet came from the cache, no PNG decoded
    for p in list(cache.iterdir())[: n // 2]:  # half the entries gone: made again, and stored
        p.unlink()
    assert _report(results, out, cache) == plain
    assert len(calls) == n - n // 2 and len(list(cache.iterdir())) == n
    assert _report(results, out, cache) == plain and len(calls) == n - n // 2


def _damage(p, how):
    data = p.read_bytes()
    if how == "truncated":
        p.write_bytes(data[: len(data) // 2])
    elif how == "flipped":  # one bit of the JPEG: still starts and ends like a JPEG
        b = bytearray(data)
        b[len(b) // 2] ^= 0x10
        p.write_bytes(bytes(b))
    elif how == "empty":
        p.write_bytes(b"")
    elif how == "header only":
        p.write_bytes(data[:16])
    elif how == "directory":  # unreadable, and cannot be replaced either
        p.unlink()
        p.mkdir()
        (p / "f").write_bytes(data)


@pytest.mark.parametrize("how", ["truncated", "flipped", "empty", "header only", "other entry", "directory"])
def test_damaged_cache_entries_fall_back_to_the_png(fake, tmp_path, how):
    results, out, plain = fake
    cache = tmp_path / "embed"
    assert _report(results, out, cache) == plain  # fills the cache
    entries = sorted(cache.iterdir())
    if how == "other entry":  # each holds another sheet's valid entry
        datas = [p.read_bytes() for p in entries]
        for p, d in zip(entries, datas[1:] + datas[:1]):
            p.write_bytes(d)
    for p in entries if how != "other entry" else ():
        _damage(p, how)
    assert _report(results, out, cache) == plain
    if how != "directory":  # damaged entries were replaced by good ones
        for rel in set(_sheets(results)):
            png = (out / rel).read_bytes()
            assert load_embed(cache, png) == jpeg_from_png(png)


def test_unwritable_cache_folder_is_skipped(fake, tmp_path):
    results, out, plain = fake
    (tmp_path / "file").write_bytes(b"not a folder")
    assert _report(results, out, tmp_path / "file" / "embed") == plain


def test_sheet_jpeg_of_a_broken_png_is_none(tmp_path):
    assert sheet_jpeg(b"\x89PNG\r\n\x1a\n broken", tmp_path) is None
    assert list(tmp_path.iterdir()) == []


def test_cache_key_covers_the_recipe(tmp_path, monkeypatch):
    png = contact_sheet(tmp_path / "s.png", _panels(1, 3), panel_width=90, embed_cache=tmp_path / "e").read_bytes()
    assert load_embed(tmp_path / "e", png) is not None
    monkeypatch.setattr(embed, "_RECIPE", embed._RECIPE.replace(b"q80", b"q95"))
    assert load_embed(tmp_path / "e", png) is None  # another quality: a miss, not the old JPEG


def test_a_run_embeds_without_decoding_pictures(tmp_path, ctx, monkeypatch):
    """evaluate(): the picture writer leaves every sheet's JPEG in OUT/.r360cache/embed, so report.html
    decodes no PNG; a rerun from the view cache after the JPEGs are gone makes them from the PNGs."""
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.synthetic import generate_benchmark

    bundle = generate_benchmark(tmp_path / "bench", seed=0, n_views=2, width=96, height=72, scenes=("room",),
                                detail=0.3, ctx=ctx)[0]
    calls = []
    real = embed.jpeg_from_png
    monkeypatch.setattr(embed, "jpeg_from_png", lambda png: calls.append(1) or real(png))
    out = tmp_path / "out"
    opts = EvaluateOptions(n_boot=50, n_perm=20)
    res = evaluate(bundle, out=out, options=opts, device=ctx, progress=False)
    sheets = set(_sheets(res))
    assert len(sheets) >= 4 and calls == []
    assert len(list((out / ".r360cache" / "embed").iterdir())) == len(sheets)
    first = (out / "report.html").read_text(encoding="utf-8")
    for p in (out / ".r360cache" / "embed").iterdir():
        p.unlink()
    evaluate(bundle, out=out, options=opts, device=ctx, progress=False)  # every view from the view cache
    assert len(calls) == len(sheets) and len(list((out / ".r360cache" / "embed").iterdir())) == len(sheets)
    again = (out / "report.html").read_text(encoding="utf-8")
    # the page differs only where results.json does (creation time, timings), never in a picture
    uris = lambda t: [s.split('"')[0] for s in t.split('src="data:image/jpeg;base64,')[1:]]  # noqa: E731
    assert uris(first) == uris(again) and len(uris(first)) >= len(sheets)
