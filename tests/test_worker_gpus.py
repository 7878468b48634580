"""Each worker on its own GPU (r360gpu.gpu.assign): the GPU a worker was given (Ray's ids,
CUDA_VISIBLE_DEVICES, --processes round-robin) mapped to a wgpu adapter by PCI bus id, by UUID, else
by index with a warning; two workers never share a GPU when two are given.  Adapters are faked (no
GPU here); the --processes plumbing runs for real on lavapipe."""
from __future__ import annotations

import json
import multiprocessing
import types

import cv2
import pytest

from r360gpu.cli import main
from r360gpu.gpu import adapter as adapter_mod
from r360gpu.gpu.adapter import gpu_adapters, select_adapter
from r360gpu.gpu.assign import CudaGpu, given_gpu, match_adapter, worker_adapter, worker_slots
from r360gpu.pipeline import processes

from run_compare import scenes  # noqa: F401 (module fixture)


def fake(device, backend="Vulkan", kind="DiscreteGPU", **ids):
    return types.SimpleNamespace(info={"device": device, "vendor": "NVIDIA", "vendor_id": 0x10DE,
                                       "backend_type": backend, "adapter_type": kind, **ids})


LAVAPIPE = fake("llvmpipe (LLVM 15.0.6, 256 bits)", kind="CPU")
#: nvidia-smi's view: index (PCI bus order), UUID, bus id, name.
SMI = (CudaGpu(0, "GPU-aaaa1111-0000-0000-0000-000000000000", "00000000:17:00.0", "NVIDIA H100 80GB HBM3"),
       CudaGpu(1, "GPU-bbbb2222-0000-0000-0000-000000000000", "00000000:65:00.0", "NVIDIA H100 80GB HBM3"))


def test_gpu_adapters_lists_each_gpu_once_on_the_best_backend():
    a0, a1 = fake("NVIDIA H100 #0"), fake("NVIDIA H100 #1")
    listed = [a0, LAVAPIPE, fake("NVIDIA H100 #0", backend="OpenGL"), a1]
    assert gpu_adapters(listed) == [a0, a1]
    assert gpu_adapters([LAVAPIPE]) == []


def test_select_adapter_takes_the_nth_gpu(monkeypatch):
    a0, a1 = fake("NVIDIA H100 #0"), fake("NVIDIA H100 #1")
    monkeypatch.setattr(adapter_mod, "list_adapters", lambda: [a0, a1, LAVAPIPE])
    assert select_adapter("gpu:1") is a1 and select_adapter("gpu:0") is a0
    with pytest.raises(Exception, match="gpu:2"):
        select_adapter("gpu:2")


def test_matched_by_pci_bus_id_whatever_wgpus_order():
    # wgpu lists GPU 1 (bus 65) first: the bus id, not the order, decides
    listed = [fake("NVIDIA H100", pci_bus_id="0000:65:00.0"), fake("NVIDIA H100", pci_bus_id="0000:17:00.0")]
    p = match_adapter("1", listed, SMI)
    assert (p.choice, p.how, p.warning) == ("gpu:0", "pci bus id", None)
    assert match_adapter("0", listed, SMI).choice == "gpu:1"


def test_matched_by_uuid():
    listed = [fake("NVIDIA H100", uuid="bbbb2222-0000-0000-0000-000000000000"),
              fake("NVIDIA H100", uuid="aaaa1111-0000-0000-0000-000000000000")]
    p = match_adapter("GPU-aaaa1111-0000-0000-0000-000000000000", listed, ())  # Ray / CUDA may give UUIDs
    assert (p.choice, p.how, p.warning) == ("gpu:1", "uuid", None)
    assert match_adapter("0", listed, SMI).choice == "gpu:1"  # index -> UUID through nvidia-smi


def test_by_index_with_a_warning_when_adapters_report_no_ids():
    listed = [fake("NVIDIA H100 80GB HBM3"), LAVAPIPE, fake("NVIDIA H100 80GB HBM3")]
    p = match_adapter("1", listed, SMI)
    assert (p.choice, p.how) == ("gpu:1", "index")
    assert "no PCI bus id or UUID" in p.warning and "GPU adapter 1" in p.warning
    # a UUID becomes its index through nvidia-smi
    assert match_adapter(SMI[1].uuid, listed, SMI).choice == "gpu:1"
    # a name nvidia-smi gives differently is said
    other = match_adapter("0", [fake("NVIDIA A100"), fake("NVIDIA H100 80GB HBM3")], SMI)
    assert "nvidia-smi calls GPU 0 'NVIDIA H100 80GB HBM3'" in other.warning


def test_a_gpu_that_cannot_be_placed_keeps_the_choice_with_a_warning():
    two = [fake("A"), fake("B")]
    for given, why in (("5", "past wgpu's 2 GPU adapters"), ("GPU-ffff", "not an index")):
        p = match_adapter(given, two, SMI)
        assert p.choice is None and p.how == "not placed" and why in p.warning
    p = match_adapter("0", [LAVAPIPE], SMI)
    assert p.choice is None and "no GPU adapter" in p.warning
    assert match_adapter("3", [fake("only")], ()).choice == "gpu:0"  # one GPU: it, whatever the index


def test_what_a_worker_was_given(monkeypatch):
    assert given_gpu({"CUDA_VISIBLE_DEVICES": "3,1"}) == "3"
    assert given_gpu({"CUDA_VISIBLE_DEVICES": ""}) is None and given_gpu({}) is None
    assert given_gpu({"CUDA_VISIBLE_DEVICES": "0"}, ray_ids=["2"]) == "2"  # Ray's ids first
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "1")
    two = [fake("A"), fake("B")]
    assert worker_adapter(None, adapters=two, cuda=()).choice == "gpu:1"
    assert worker_adapter("auto", ray_ids=[0], adapters=two, cuda=()).choice == "gpu:0"
    assert worker_adapter("H100", adapters=two, cuda=()) is None  # an adapter named by the user is kept
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES")
    assert worker_adapter(None, adapters=two, cuda=()) is None


def test_worker_slots():
    two = [fake("A"), LAVAPIPE, fake("B")]
    assert worker_slots(None, {}, two) == ["0", "1"]
    assert worker_slots("gpu", {"CUDA_VISIBLE_DEVICES": "2,3"}, two) == ["2", "3"]
    assert worker_slots(None, {}, [fake("A")]) == [] and worker_slots(None, {}, [LAVAPIPE]) == []
    assert worker_slots("cpu", {}, two) == []


@pytest.mark.parametrize("workers,gpus", [(2, 2), (3, 4), (4, 2), (5, 3)])
def test_processes_workers_spread_round_robin_and_never_share_while_gpus_last(monkeypatch, workers, gpus):
    """The k-th worker to start takes slot k mod K: no GPU has two workers while workers <= GPUs,
    and none has more than ceil(workers / K)."""
    listed = [fake(f"NVIDIA H100 #{i}") for i in range(gpus)]
    slots = worker_slots(None, {}, listed)
    counter = multiprocessing.get_context("spawn").Value("i", 0)
    monkeypatch.setattr(processes.signal, "signal", lambda *a: None)  # the test process keeps its Ctrl-C
    monkeypatch.setenv("LP_NUM_THREADS", "1")
    placed = []
    for _ in range(workers):
        processes._worker_start(cv2.getNumThreads(), slots, counter)
        placed.append(worker_adapter(None, adapters=listed, cuda=()).choice)
    per_gpu = {c: placed.count(c) for c in set(placed)}
    if workers <= gpus:
        assert len(set(placed)) == workers
    assert max(per_gpu.values()) == -(-workers // gpus) and len(per_gpu) == min(workers, gpus)


def test_processes_record_the_gpu_each_worker_was_given(scenes, tmp_path, monkeypatch, capsys):  # noqa: F811
    """--processes 2 with two GPUs given: each worker takes its own, and results.json says where each
    landed (here on lavapipe, which is no GPU: "not placed", warned)."""
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    out = tmp_path / "out"
    rc = main(["score", str(scenes[0]), "--out", str(out), "--processes", "2", "--n-boot", "50", "--n-perm", "50",
               "--quiet", "--no-pictures", "--no-boundary", "--no-controls"])
    assert rc == 0, capsys.readouterr().err
    doc = json.loads((out / "results.json").read_text())
    gpus = doc["timing"]["executor"]["gpus"]
    # which worker takes which task is the pool's; every task's worker was given one of the two
    assert gpus and {g.split(" -> ")[0] for g in gpus} <= {"given GPU 0", "given GPU 1"}, gpus
    assert all(g.endswith("(not placed)") for g in gpus)
    messages = [w["message"] for w in doc["warnings"]]
    assert any("was given, but wgpu sees no GPU adapter" in m for m in messages), messages
