"""Atomic writes: fsync for results, none for regenerable files (pictures, caches)."""
from __future__ import annotations


def test_fsync_unless_sync_false(tmp_path, monkeypatch):
    from r360gpu.util import atomic

    synced = []
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: synced.append(fd))
    atomic.write_bytes(tmp_path / "a.bin", b"x")
    atomic.write_json(tmp_path / "a.json", {"a": 1})
    assert len(synced) == 2
    atomic.write_bytes(tmp_path / "b.bin", b"y", sync=False)
    atomic.write_text(tmp_path / "b.txt", "z", sync=False)
    atomic.write_json(tmp_path / "b.json", {"b": 2}, sync=False)
    assert len(synced) == 2
    assert (tmp_path / "b.bin").read_bytes() == b"y" and (tmp_path / "b.txt").read_text() == "z"
    assert not [p for p in tmp_path.iterdir() if atomic.is_temporary(p.name)]
