"""Which GPU adapter a worker opens: the GPU its scheduler gave it.

Ray gives each task its GPUs (``ray.get_gpu_ids()``, and sets
``CUDA_VISIBLE_DEVICES`` to them); ``score --processes N`` gives each worker
process one GPU round-robin (:func:`worker_slots`); a job scheduler sets
``CUDA_VISIBLE_DEVICES``.  CUDA honours that variable, Vulkan does not: wgpu
enumerates every GPU of the machine whatever the variable says, so without
this module every worker would open the same first GPU.

The given GPU is named as CUDA names it: an index (the NVIDIA driver's
index, PCI bus order, as ``nvidia-smi`` and Ray number GPUs) or a UUID
(``GPU-...``).  :func:`match_adapter` finds the wgpu adapter for it:

1. by PCI bus id, or by UUID, when the adapters report one (wgpu's adapter
   info has neither today, only vendor and device ids; a backend that adds
   ``pci_bus_id`` / ``uuid`` is matched exactly) and ``nvidia-smi`` says
   which bus id / UUID the given GPU has;
2. else by index: the given index (a UUID turned into its index by
   ``nvidia-smi``) is taken as the position among the GPU adapters in wgpu's
   order (:func:`~.adapter.gpu_adapters`), with a warning saying so, since
   Vulkan's order is the driver's, usually but not always PCI bus order;
3. a GPU that cannot be placed (an index past the adapters, a UUID
   ``nvidia-smi`` does not know) leaves the adapter choice as it was, with a
   warning.

An adapter chosen by name (``--adapter H100``, ``cpu``) is kept as given.
"""
from __future__ import annotations

import functools
import os
import shutil
import subprocess
from dataclasses import dataclass

from .adapter import ENV_VAR, gpu_adapters

__all__ = ["CudaGpu", "Placement", "given_gpu", "match_adapter", "nvidia_gpus", "worker_adapter", "worker_slots"]

#: Adapter-info keys a backend may use for the PCI bus id and for the device UUID.
PCI_KEYS = ("pci_bus_id", "device_pci_bus_id")
UUID_KEYS = ("uuid", "device_uuid")
#: Adapter choices under which a worker takes its given GPU (others name an adapter themselves).
FOLLOWS_GIVEN = (None, "", "auto", "gpu")


@dataclass(frozen=True)
class CudaGpu:
    """One GPU as the NVIDIA driver names it: ``nvidia-smi``'s index, UUID, PCI bus id and name."""

    index: int
    uuid: str
    pci_bus_id: str
    name: str


@dataclass(frozen=True)
class Placement:
    """Where a worker's given GPU landed: ``choice`` (an adapter choice for
    :func:`~.adapter.select_adapter`, e.g. ``"gpu:1"``, or the choice as it was), ``how``
    ("pci bus id", "uuid", "index", "only GPU" or "not placed") and a ``warning`` (or None)."""

    given: str
    choice: str | None
    how: str
    warning: str | None = None

    def describe(self, adapter_name: str) -> str:
        return f"given GPU {self.given} -> {adapter_name} ({self.how})"


def _norm_uuid(text) -> str:
    t = str(text or "").strip().lower()
    for prefix in ("gpu-", "mig-"):
        if t.startswith(prefix):
            t = t[len(prefix):]
    return t.replace("-", "")


def _norm_bus(text):
    """(domain, bus, device, function) of "0000:17:00.0" / "00000000:17:00.0", or None."""
    try:
        head, fn = str(text).strip().lower().rsplit(".", 1)
        parts = head.split(":")
        domain = parts[-3] if len(parts) >= 3 else "0"
        return int(domain, 16), int(parts[-2], 16), int(parts[-1], 16), int(fn, 16)
    except (ValueError, IndexError):
        return None


def _follows(choice: str | None) -> bool:
    """Whether an adapter choice (else R360GPU_ADAPTER) lets a worker take the GPU it was given."""
    return (choice or os.environ.get(ENV_VAR) or "").strip().lower() in FOLLOWS_GIVEN


def _reported(info, keys) -> str | None:
    for k in keys:
        if info.get(k):
            return str(info[k])
    return None


@functools.lru_cache(maxsize=1)
def nvidia_gpus() -> tuple:
    """The machine's NVIDIA GPUs from ``nvidia-smi`` (it ignores CUDA_VISIBLE_DEVICES), or () without it."""
    exe = shutil.which("nvidia-smi")
    if exe is None:
        return ()
    try:
        out = subprocess.run([exe, "--query-gpu=index,uuid,pci.bus_id,name", "--format=csv,noheader"],
                             capture_output=True, text=True, timeout=15, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return ()
    gpus = []
    for line in out.splitlines():
        fields = [f.strip() for f in line.split(",", 3)]
        if len(fields) == 4 and fields[0].isdigit():
            gpus.append(CudaGpu(int(fields[0]), fields[1], fields[2], fields[3]))
    return tuple(gpus)


def given_gpu(environ=None, ray_ids=None) -> str | None:
    """The GPU this process was given: Ray's first (``ray_ids``: ``ray.get_gpu_ids()`` in a Ray
    task), else the first entry of ``CUDA_VISIBLE_DEVICES``; None when nothing was given."""
    if ray_ids:
        return str(ray_ids[0]).strip()
    env = os.environ if environ is None else environ
    first = str(env.get("CUDA_VISIBLE_DEVICES", "")).split(",")[0].strip()
    return first or None


def match_adapter(given: str, adapters: list, cuda: tuple = ()) -> Placement:
    """The adapter for the GPU ``given`` (an index or a UUID, as CUDA names it) among ``adapters``
    (wgpu's, best first), using ``cuda`` (:func:`nvidia_gpus`) for the GPU's bus id and UUID."""
    gpus = gpu_adapters(adapters)
    if not gpus:
        return Placement(given, None, "not placed", f"GPU {given} was given, but wgpu sees no GPU adapter")
    if len(gpus) == 1:
        return Placement(given, "gpu:0", "only GPU")
    token = given.strip()
    known = None
    if token.isdigit():
        known = next((g for g in cuda if g.index == int(token)), None)
    else:
        known = next((g for g in cuda if _norm_uuid(g.uuid) == _norm_uuid(token)), None)
    want_bus = _norm_bus(known.pci_bus_id) if known else None
    want_uuid = _norm_uuid(known.uuid if known else token)
    for n, a in enumerate(gpus):
        bus, uuid = _reported(a.info, PCI_KEYS), _reported(a.info, UUID_KEYS)
        if want_bus is not None and bus is not None and _norm_bus(bus) == want_bus:
            return Placement(given, f"gpu:{n}", "pci bus id")
        if uuid is not None and want_uuid and _norm_uuid(uuid) == want_uuid:
            return Placement(given, f"gpu:{n}", "uuid")
    index = int(token) if token.isdigit() else (known.index if known else None)
    if index is None or index >= len(gpus):
        why = "is not an index nvidia-smi knows" if index is None else f"is past wgpu's {len(gpus)} GPU adapters"
        return Placement(given, None, "not placed", f"GPU {given} was given, but it {why}; the adapter is "
                                                    "chosen as without it")
    name = str(gpus[index].info.get("device", "?"))
    said = f"; nvidia-smi calls GPU {index} {known.name!r}" if known and known.name.lower() not in name.lower() else ""
    return Placement(given, f"gpu:{index}", "index",
                     f"the GPU adapters report no PCI bus id or UUID, so GPU {given} is taken as GPU adapter "
                     f"{index} in wgpu's order ({name}){said}; Vulkan's order is usually, not always, the "
                     "driver's")


def worker_adapter(choice: str | None, ray_ids=None, adapters=None, cuda=None) -> Placement | None:
    """The Placement for this worker process when it was given a GPU and ``choice`` (else
    R360GPU_ADAPTER) lets it follow (:data:`FOLLOWS_GIVEN`), else None.  adapters, cuda: wgpu's and nvidia-smi's lists
    (None: asked for here)."""
    if not _follows(choice):
        return None
    given = given_gpu(ray_ids=ray_ids)
    if given is None:
        return None
    if adapters is None:
        from .adapter import list_adapters

        adapters = list_adapters()
    return match_adapter(given, adapters, nvidia_gpus() if cuda is None else cuda)


def worker_slots(choice: str | None, environ=None, adapters=None) -> list[str]:
    """The GPUs ``--processes`` workers take round-robin (worker k: entry k mod len): the entries of
    ``CUDA_VISIBLE_DEVICES`` when set, else one per GPU adapter when there are two or more; [] when
    there is nothing to spread over or ``choice`` names an adapter."""
    if not _follows(choice):
        return []
    env = os.environ if environ is None else environ
    visible = [t.strip() for t in str(env.get("CUDA_VISIBLE_DEVICES", "")).split(",") if t.strip()]
    if "CUDA_VISIBLE_DEVICES" in env:
        return visible
    if adapters is None:
        from .adapter import list_adapters

        adapters = list_adapters()
    n = len(gpu_adapters(adapters))
    return [str(i) for i in range(n)] if n >= 2 else []
