"""Shared fixtures: one GPU context for the session, and small-limit contexts
that force the chunking paths on small inputs."""
from __future__ import annotations

import os

import pytest

# A failing adapter should fail loudly, not silently skip: CI installs lavapipe.
os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")


@pytest.fixture(scope="session")
def ctx():
    from r360gpu.gpu import get_context

    return get_context()


@pytest.fixture(scope="session")
def small_ctx(ctx):
    """Same device, but bindings capped at 4 KiB and 7 workgroups per dimension."""
    from r360gpu.gpu import GpuContext

    return GpuContext(ctx.device, limit_binding_bytes=4096, limit_workgroups=7)
