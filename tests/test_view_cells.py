"""A view's typed cells (r360gpu.schema.ScoredView) through the view cache: the cells come back equal,
the view's warnings with them (kept in the first cell's file only), a control's cell without a picture."""
from __future__ import annotations

import json

from r360gpu.metrics.record import ViewRecord
from r360gpu.pipeline.cache import ViewCache
from r360gpu.schema import ScoredView, ViewCell


def _record(method: str) -> ViewRecord:
    return ViewRecord.build("v1", "room", method, geometric={"acc_depth": 0.5})


def test_a_view_stored_and_loaded_keeps_its_cells_and_warnings(tmp_path):
    out = tmp_path / "out"
    (out / "pictures").mkdir(parents=True)
    (out / "pictures" / "a.png").write_bytes(b"png")
    warnings = {"records": [{"message": "odd depth", "scene": "room", "view": "v1"}], "counts": {}}
    scored = ScoredView({"after": ViewCell(_record("after"), {"iou_post": {"E15": 0.5}}, "pictures/a.png"),
                         "pre": ViewCell(_record("pre"))}, warnings)
    cache = ViewCache(tmp_path / "views" / "room", out)
    assert cache.store_view("v1", scored, [])
    files = {m: json.loads((tmp_path / "views" / "room" / m / "v1.json").read_text()) for m in ("after", "pre")}
    assert files["after"]["warnings"] == warnings and "warnings" not in files["pre"]
    assert "inputs" not in files["after"]  # no precomputed probe file was read
    got = cache.load_scored(["after"], ["pre"], "v1", pictures=True)
    assert got.warnings == warnings
    assert {m: (c.record.to_dict(), c.boundary, c.picture, c.inputs) for m, c in got.cells.items()} == {
        m: (c.record.to_dict(), c.boundary, c.picture, c.inputs) for m, c in scored.cells.items()}
    (out / "pictures" / "a.png").unlink()  # a method's picture gone: the view is scored again
    assert cache.load_scored(["after"], ["pre"], "v1", pictures=True) is None
    assert cache.load_view(["pre"], "v1", pictures=False).warnings is None  # only the first cell holds them
