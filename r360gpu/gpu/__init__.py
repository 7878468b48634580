"""The device layer: adapter choice, one context per device, shader loading."""
from __future__ import annotations

from .adapter import ENV_VAR, list_adapters, select_adapter
from .context import BufferRange, GpuContext, get_context, open_ahead
from .shaders import available_shaders, shader_path

__all__ = [
    "ENV_VAR",
    "BufferRange",
    "GpuContext",
    "available_shaders",
    "get_context",
    "list_adapters",
    "open_ahead",
    "select_adapter",
    "shader_path",
]
