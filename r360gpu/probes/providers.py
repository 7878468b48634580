"""Which onnxruntime execution provider runs the learned probes (and LPIPS): ``--probe-device``.

Device names (:data:`DEVICES`): ``cpu``, ``cuda``, ``tensorrt``, ``webgpu``,
``directml``, ``coreml``, or ``auto``.  Each GPU provider comes with an
onnxruntime build or plugin that an extra of r360gpu installs
(:data:`EXTRAS`): ``onnxruntime-gpu`` has CUDA and TensorRT; the WebGPU
provider (Dawn: Vulkan, Metal, D3D12, the adapters wgpu uses) comes either
in the ``onnxruntime-webgpu`` build or as the ``onnxruntime-ep-webgpu``
plugin of a stock onnxruntime, registered here on first use.

``auto`` (:func:`choose`) takes a GPU provider for the GPU the renderer
uses: on an NVIDIA adapter CUDA, then WebGPU; on another GPU WebGPU, then
DirectML (Windows), then CoreML (Apple); the first one the installed
onnxruntime has.  A renderer on a CPU adapter (lavapipe), or none of those
providers installed, gives the CPU provider.  TensorRT is never taken by
``auto``: it builds an engine per input shape on first use (minutes for
SAM's decoder), which a researcher asks for by name.

A device named explicitly whose provider the installed onnxruntime lacks is
an :class:`~r360gpu.errors.InputError` (exit 2 on the command line) naming
the extra to install: a run asked to be on the GPU does not quietly take
hours on the CPU.  A provider that is installed but cannot start (no driver,
no device, the WebGPU provider on lavapipe: "No supported adapters") makes
onnxruntime run the CPU provider instead; :class:`~.onnx_models.OnnxModel`
then warns (printed and recorded in results.json), naming the provider that
ran.  The provider that ran is in every learned probe's ``describe()``, so in
results.json and in the probe cache key.

The CUDA and TensorRT providers run on CUDA device 0 of the process: a Ray
task's or a ``--processes`` worker's own GPU, since both set
``CUDA_VISIBLE_DEVICES`` to it (:mod:`r360gpu.gpu.assign`).
"""
from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass

from r360gpu.errors import InputError, R360Warning

__all__ = [
    "DEVICES",
    "EXTRAS",
    "ProviderPlan",
    "available_providers",
    "choose",
    "open_session",
    "plan",
    "providers_for",
    "started",
]

#: device name -> onnxruntime execution provider.
DEVICES = {
    "cpu": "CPUExecutionProvider",
    "cuda": "CUDAExecutionProvider",
    "tensorrt": "TensorrtExecutionProvider",
    "webgpu": "WebGpuExecutionProvider",
    "directml": "DmlExecutionProvider",
    "coreml": "CoreMLExecutionProvider",
}
#: device name -> what installs its provider (``pip install 'r360gpu[EXTRA]'``).
EXTRAS = {"cuda": "gpu-cuda", "tensorrt": "gpu-cuda", "webgpu": "gpu-webgpu"}
_NVIDIA = 0x10DE  # PCI vendor id
_AUTO_NVIDIA = ("cuda", "webgpu", "directml")
_AUTO_OTHER_GPU = ("webgpu", "directml", "coreml")
_WEBGPU_PLUGIN = "onnxruntime_ep_webgpu"  # the plugin's Python module
_plugin_lock = threading.Lock()
_plugin_registered: dict = {}


def _ort():
    import onnxruntime

    return onnxruntime


def _webgpu_plugin():
    """The ``onnxruntime_ep_webgpu`` module when installed, else None."""
    try:
        import importlib

        return importlib.import_module(_WEBGPU_PLUGIN)
    except ImportError:
        return None


def available_providers() -> list[str]:
    """Execution providers the installed onnxruntime can run: its build's, and the WebGPU
    provider when the ``onnxruntime-ep-webgpu`` plugin is installed."""
    out = list(_ort().get_available_providers())
    if DEVICES["webgpu"] not in out and _webgpu_plugin() is not None:
        out.insert(0, DEVICES["webgpu"])
    return out


@dataclass(frozen=True)
class ProviderPlan:
    """How a session is opened: ``device`` (a name of :data:`DEVICES`), ``providers`` for
    ``InferenceSession(providers=...)`` (the CPU provider last, for the operators a GPU one
    lacks), ``plugin``: True when the WebGPU provider is the plugin's (registered and added
    through the session options)."""

    device: str
    providers: tuple
    plugin: bool = False


def choose(device: str = "cpu", gpu: dict | None = None) -> str:
    """The device name ``device`` stands for: itself, checked, or for ``auto`` the first of the
    GPU providers that suit ``gpu`` (the renderer's adapter info, wgpu's or
    ``GpuContext.adapter_info``: ``adapter_type``, ``vendor_id`` / ``vendor`` / ``name``; None:
    unknown, any GPU) that onnxruntime has, else ``cpu``."""
    name = str(device).strip().lower()
    if name != "auto":
        if name not in DEVICES:
            raise InputError(f"unknown device {device!r} for the probes; use one of {', '.join(DEVICES)} or auto")
        return name
    if gpu is not None and str(gpu.get("adapter_type", "")) == "CPU":
        return "cpu"
    if gpu is None:
        order = _AUTO_NVIDIA + _AUTO_OTHER_GPU[2:]
    elif _is_nvidia(gpu):
        order = _AUTO_NVIDIA
    else:
        order = _AUTO_OTHER_GPU
    available = available_providers()
    return next((d for d in order if DEVICES[d] in available), "cpu")


def _is_nvidia(gpu: dict) -> bool:
    """wgpu's adapter info (``vendor_id``) or a GpuContext's (``vendor`` / ``name`` text) names NVIDIA."""
    text = " ".join(str(gpu.get(k, "")) for k in ("vendor", "device", "name")).lower()
    return int(gpu.get("vendor_id", 0) or 0) == _NVIDIA or "nvidia" in text


def plan(device: str = "cpu", gpu: dict | None = None) -> ProviderPlan:
    """The :class:`ProviderPlan` for ``device`` (see :func:`choose`); InputError for a device the
    installed onnxruntime lacks, naming the extra that installs it."""
    name = choose(device, gpu)
    provider = DEVICES[name]
    built_in = list(_ort().get_available_providers())
    if name == "cpu":
        return ProviderPlan("cpu", (provider,))
    if provider in built_in:
        return ProviderPlan(name, (provider, DEVICES["cpu"]))
    if name == "webgpu" and _webgpu_plugin() is not None:
        return ProviderPlan(name, (provider, DEVICES["cpu"]), plugin=True)
    extra = f"; pip install 'r360gpu[{EXTRAS[name]}]'" if name in EXTRAS else ""
    raise InputError(
        f"probe device {name!r} needs onnxruntime's {provider}, which the installed onnxruntime lacks "
        f"(it has: {', '.join(built_in)}){extra}"
    )


def providers_for(device: str = "cpu") -> list[str]:
    """onnxruntime provider list for a device name (:func:`plan`'s providers)."""
    return list(plan(device).providers)


def open_session(source, sess_options, chosen: ProviderPlan):
    """An ``onnxruntime.InferenceSession`` on ``source`` (a path or serialised model) with the
    providers of ``chosen``.  The WebGPU plugin is registered once per process; when it offers no
    device the session runs on the CPU provider (the caller warns: it compares
    ``get_providers()`` with the plan)."""
    ort = _ort()
    if not chosen.plugin:
        return ort.InferenceSession(source, sess_options=sess_options, providers=list(chosen.providers))
    plugin = _webgpu_plugin()
    with _plugin_lock:
        if not _plugin_registered:
            ort.register_execution_provider_library("webgpu", plugin.get_library_path())
            _plugin_registered["webgpu"] = True
    devices = [d for d in ort.get_ep_devices() if d.ep_name == plugin.get_ep_name()][:1]
    if devices:
        sess_options.add_provider_for_devices(devices, {})
        return ort.InferenceSession(source, sess_options=sess_options)
    return ort.InferenceSession(source, sess_options=sess_options, providers=[DEVICES["cpu"]])


def started(session, chosen: ProviderPlan, path, role: str) -> str:
    """The provider ``session`` runs on; an R360Warning naming it when it is not the one
    ``chosen`` asked for (onnxruntime fell back to the CPU provider: no driver, no device)."""
    active = list(session.get_providers())
    if chosen.providers[0] not in active:
        warnings.warn(
            f"{path}: onnxruntime could not start {chosen.providers[0]} for the {role} "
            f"(probe device {chosen.device!r}); running on {active[0]}",
            R360Warning,
            stacklevel=3,
        )
    return active[0]
