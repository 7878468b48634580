"""Exceptions and warnings raised by r360gpu.

Every error caused by a user's input is an :class:`InputError` whose message
names the offending file (when there is one) and the problem, so the CLI can
print it as a one-line reason.
"""
from __future__ import annotations

import os


class R360Error(Exception):
    """Base class of every error r360gpu raises on purpose."""


class InputError(R360Error, ValueError):
    """Bad user input: a file that cannot be read, wrong shapes, bad values."""

    def __init__(self, problem: str, path: str | os.PathLike | None = None):
        self.path = None if path is None else os.fspath(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}" if self.path else problem)


class GpuUnavailableError(R360Error, RuntimeError):
    """No usable wgpu adapter (e.g. no Vulkan driver installed)."""


class WorkerLostError(R360Error, RuntimeError):
    """A worker process that was scoring views ended without an answer (killed, out of memory)."""


class R360Warning(UserWarning):
    """Non-fatal problems in the input (dropped Gaussians, resized masks, ...)."""
