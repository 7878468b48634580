"""Which r360gpu code computed something: a digest of the package's own source.

The version string stays the same between releases while the code under it changes (a checkout
pulled again, a local edit), so caches keyed by it would serve numbers an older probe or metric
computed.  :func:`code_digest` hashes every ``.py`` file of the package and every ``.wgsl``
shader it can load (the package's, the checkout's top-level ``shaders/``, and
``R360GPU_SHADER_DIR`` when set), once per process.
The run's caches are keyed by it (:mod:`r360gpu.pipeline.cache`, :mod:`r360gpu.probes.cache`),
and workers on other nodes or processes must report the same :func:`version_id` as the driver.
"""
from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

_PKG = Path(__file__).resolve().parent.parent  # .../r360gpu
_SUFFIXES = (".py", ".wgsl")


def _roots() -> list[Path]:
    roots = [_PKG, _PKG.parent / "shaders"]
    env = os.environ.get("R360GPU_SHADER_DIR")
    if env:
        roots.append(Path(env))
    return [r for r in roots if r.is_dir()]


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """Hex BLAKE2b-128 of the source files (relative path and bytes of each, in sorted order)."""
    h = hashlib.blake2b(digest_size=16)
    for i, root in enumerate(_roots()):
        for p in sorted(root.rglob("*")):
            if p.suffix in _SUFFIXES and "__pycache__" not in p.parts and p.is_file():
                data = p.read_bytes()
                h.update(f"{i}:{p.relative_to(root).as_posix()}:{len(data)}\n".encode())
                h.update(data)
    return h.hexdigest()


def version_id() -> str:
    """``VERSION+DIGEST``: the release and the first 12 hex digits of :func:`code_digest`."""
    from .. import __version__

    return f"{__version__}+{code_digest()[:12]}"
