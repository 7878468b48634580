"""Choosing a wgpu adapter: a real GPU when present, else Mesa lavapipe.

The choice comes from the ``adapter`` argument or, when that is ``None``, from
the environment variable ``R360GPU_ADAPTER``:

``auto`` (default)
    the best non-CPU adapter on a native backend (Vulkan, Metal, D3D12);
    otherwise a CPU adapter (lavapipe / llvmpipe via Vulkan).
``gpu``
    a non-CPU adapter; an error if there is none.
``gpu:N``
    the N-th GPU adapter (from 0) in wgpu's order (:func:`gpu_adapters`); a
    worker given GPU N opens it (:mod:`r360gpu.gpu.assign`).
``cpu``
    a CPU (software) adapter such as lavapipe; an error if there is none.
any other text
    the first adapter whose device name, vendor or description contains that
    text (case-insensitive), e.g. ``R360GPU_ADAPTER=llvmpipe`` or ``=H100``.
"""
from __future__ import annotations

import os

from ..errors import GpuUnavailableError

ENV_VAR = "R360GPU_ADAPTER"

# Backends wgpu can drive compute shaders on; OpenGL is a last resort because
# its compute support depends on the driver's GLSL translation.
_BACKEND_ORDER = {"Vulkan": 0, "Metal": 0, "D3D12": 1, "OpenGL": 3}
_TYPE_ORDER = {"DiscreteGPU": 0, "IntegratedGPU": 1, "VirtualGPU": 2, "Unknown": 3, "CPU": 4}

INSTALL_HINT = (
    "no usable GPU adapter was found. On Debian/Ubuntu install the Vulkan CPU "
    "driver (Mesa lavapipe) with:  sudo apt-get install -y mesa-vulkan-drivers  "
    "(a real GPU needs its vendor's Vulkan driver instead)."
)


def _describe(info) -> str:
    return f"{info.get('device', '?')} [{info.get('backend_type', '?')}, {info.get('adapter_type', '?')}]"


def _is_cpu(info) -> bool:
    return info.get("adapter_type") == "CPU" or "llvmpipe" in str(info.get("device", "")).lower()


def _quiet_runtime_dir() -> None:
    # Mesa's window-system loader prints an error on every start when
    # XDG_RUNTIME_DIR is unset (headless machines, CI); give it a private one.
    if not os.environ.get("XDG_RUNTIME_DIR"):
        import tempfile

        d = os.path.join(tempfile.gettempdir(), f"r360gpu-runtime-{os.getuid() if hasattr(os, 'getuid') else 0}")
        os.makedirs(d, mode=0o700, exist_ok=True)
        os.environ["XDG_RUNTIME_DIR"] = d


def list_adapters() -> list:
    """All adapters wgpu can see, best first (backend, then GPU type)."""
    _quiet_runtime_dir()
    import wgpu

    try:
        adapters = list(wgpu.gpu.enumerate_adapters_sync())
    except Exception as e:  # the native library fails to load without a driver
        raise GpuUnavailableError(f"{INSTALL_HINT} (wgpu said: {e})") from e
    return sorted(
        adapters,
        key=lambda a: (
            _BACKEND_ORDER.get(a.info.get("backend_type"), 2),
            _TYPE_ORDER.get(a.info.get("adapter_type"), 3),
        ),
    )


def gpu_adapters(adapters: list) -> list:
    """The GPU (non-CPU) adapters of ``adapters`` on one backend, each physical GPU once: the
    backend listed first (Vulkan / Metal, then D3D12, then OpenGL), in wgpu's order."""
    gpus = [a for a in adapters if not _is_cpu(a.info)]
    if not gpus:
        return []
    backend = min(gpus, key=lambda a: _BACKEND_ORDER.get(a.info.get("backend_type"), 2)).info.get("backend_type")
    return [a for a in gpus if a.info.get("backend_type") == backend]


def select_adapter(choice: str | None = None):
    """Return a ``wgpu.GPUAdapter`` for ``choice`` (see the module docstring)."""
    choice = (choice or os.environ.get(ENV_VAR) or "auto").strip()
    adapters = list_adapters()
    if not adapters:
        raise GpuUnavailableError(INSTALL_HINT)
    key = choice.lower()
    if key == "auto":
        gpus = [a for a in adapters if not _is_cpu(a.info)]
        native_gpus = [a for a in gpus if a.info.get("backend_type") != "OpenGL"]
        cpus = [a for a in adapters if _is_cpu(a.info) and a.info.get("backend_type") != "OpenGL"]
        for group in (native_gpus, cpus, gpus, adapters):
            if group:
                return group[0]
    if key.startswith("gpu:") and key[4:].strip().isdigit():
        gpus = gpu_adapters(adapters)
        n = int(key[4:])
        found = gpus[n : n + 1]
    elif key == "gpu":
        found = [a for a in adapters if not _is_cpu(a.info)]
    elif key in ("cpu", "lavapipe"):
        found = [a for a in adapters if _is_cpu(a.info)]
    else:
        found = [
            a
            for a in adapters
            if key
            in " ".join(str(a.info.get(k, "")) for k in ("device", "vendor", "description", "backend_type")).lower()
        ]
    if not found:
        seen = "; ".join(_describe(a.info) for a in adapters)
        raise GpuUnavailableError(
            f"no adapter matches {ENV_VAR}/adapter={choice!r}; available: {seen}"
            + ("" if key != "cpu" else f". {INSTALL_HINT}")
        )
    return found[0]
