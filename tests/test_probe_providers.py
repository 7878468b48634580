"""--probe-device: which onnxruntime provider auto takes for the renderer's GPU, the error for a provider
asked for by name that onnxruntime lacks, the recorded warning when one cannot start, and the provider
that ran in describe(), results and the probe cache key.  onnxruntime's GPU providers are faked (this
machine has none; the WebGPU provider refuses lavapipe)."""
from __future__ import annotations

import argparse
import json
import types

import numpy as np
import onnxruntime
import pytest

pytest.importorskip("onnx")

from onnx_graphs import sam_decoder, sam_encoder_nchw  # noqa: E402
from r360gpu import cli  # noqa: E402
from r360gpu.cli.score import probes_from_args  # noqa: E402
from r360gpu.errors import InputError  # noqa: E402
from r360gpu.probes import providers  # noqa: E402
from r360gpu.probes.cache import cache_key  # noqa: E402
from r360gpu.probes.sam_amg import SamAmgProbe  # noqa: E402
from r360gpu.util import warning_log  # noqa: E402

CPU, CUDA, WEBGPU = "CPUExecutionProvider", "CUDAExecutionProvider", "WebGpuExecutionProvider"
NVIDIA = {"device": "NVIDIA H100 80GB HBM3", "vendor_id": 0x10DE, "adapter_type": "DiscreteGPU"}
AMD = {"device": "AMD Radeon RX 7900 XTX", "vendor_id": 0x1002, "adapter_type": "DiscreteGPU"}
LAVAPIPE = {"device": "llvmpipe (LLVM 15.0.6, 256 bits)", "vendor_id": 65541, "adapter_type": "CPU"}


class FakeOrt:
    """onnxruntime with extra providers in its build: sessions are real CPU sessions that report
    ``starts`` as their first provider when it was asked for (else the CPU provider, as onnxruntime
    does when a provider cannot start)."""

    def __init__(self, extra, starts=()):
        self.extra, self.starts, self.asked = list(extra), set(starts), []
        self.SessionOptions = onnxruntime.SessionOptions

    def get_available_providers(self):
        return self.extra + onnxruntime.get_available_providers()

    def InferenceSession(self, source, sess_options=None, providers=None):  # noqa: N802 (onnxruntime's name)
        self.asked.append(list(providers or []))
        real = onnxruntime.InferenceSession(source, sess_options=sess_options, providers=[CPU])
        first = (providers or [CPU])[0]
        active = [first, CPU] if first in self.starts else [CPU]
        real_get = types.SimpleNamespace(get_providers=lambda: active)
        return _Session(real, real_get)


class _Session:
    def __init__(self, real, fake):
        self._real, self._fake = real, fake

    def get_providers(self):
        return self._fake.get_providers()

    def __getattr__(self, name):
        return getattr(self._real, name)


@pytest.fixture()
def sam_pair(tmp_path):
    tokens = dict(iou=[0.99, 0.95, 0.92, 0.93], radius=[80, 160, 168, 240], slope=[1.0, 1.0, 1.0, 1e-5])
    return sam_encoder_nchw(tmp_path / "sam.encoder.onnx"), sam_decoder(tmp_path / "sam.decoder.onnx", **tokens)


def _fake(monkeypatch, extra, starts=()):
    fake = FakeOrt(extra, starts)
    monkeypatch.setattr(providers, "_ort", lambda: fake)
    monkeypatch.setattr(providers, "_webgpu_plugin", lambda: None)
    return fake


@pytest.mark.parametrize("build,gpu,expected", [
    ([CUDA, WEBGPU], NVIDIA, "cuda"),       # the renderer's NVIDIA GPU: CUDA first
    ([WEBGPU], NVIDIA, "webgpu"),           # no CUDA in this build: WebGPU drives the same GPU
    ([CUDA, WEBGPU], AMD, "webgpu"),        # CUDA cannot run on the renderer's AMD GPU
    ([CUDA], AMD, "cpu"),
    ([CUDA, WEBGPU], LAVAPIPE, "cpu"),      # the renderer on a CPU adapter: the probes on the CPU too
    ([], NVIDIA, "cpu"),                    # a CPU-only onnxruntime
    ([WEBGPU, CUDA], None, "cuda"),         # renderer unknown (library use): CUDA, then WebGPU
    (["TensorrtExecutionProvider"], NVIDIA, "cpu"),  # TensorRT only when named
])
def test_auto_takes_a_provider_for_the_renderers_gpu(monkeypatch, build, gpu, expected):
    _fake(monkeypatch, build)
    assert providers.choose("auto", gpu) == expected
    assert providers.plan("auto", gpu).providers[-1] == CPU


def test_auto_reads_a_gpu_context_description(monkeypatch):
    # GpuContext.adapter_info has the device name and vendor text, not the PCI vendor id
    _fake(monkeypatch, [CUDA, WEBGPU])
    assert providers.choose("auto", {"name": "NVIDIA H200", "vendor": "", "adapter_type": "DiscreteGPU"}) == "cuda"


def test_a_provider_named_but_missing_is_an_error_naming_the_extra(monkeypatch):
    _fake(monkeypatch, [])
    with pytest.raises(InputError, match=r"CUDAExecutionProvider.*r360gpu\[gpu-cuda\]"):
        providers.plan("cuda")
    with pytest.raises(InputError, match=r"r360gpu\[gpu-webgpu\]"):
        providers.plan("webgpu")
    with pytest.raises(InputError, match="unknown device"):
        providers.plan("tpu")
    assert providers.plan("CPU").providers == (CPU,)


def test_a_provider_that_cannot_start_is_a_recorded_warning(monkeypatch, sam_pair):
    fake = _fake(monkeypatch, [CUDA])  # in the build, but no device: onnxruntime runs the CPU provider
    with warning_log.collecting(None):
        probe = SamAmgProbe(*sam_pair, device="cuda")
        records = warning_log.records()
    assert fake.asked[0] == [CUDA, CPU]
    assert probe.describe()["params"]["provider"] == CPU
    messages = [r["message"] for r in records]
    assert any("could not start CUDAExecutionProvider" in m and "running on CPUExecutionProvider" in m
               for m in messages), messages
    assert all(r["file"] for r in records)


def test_the_provider_that_ran_is_in_the_cache_key(monkeypatch, sam_pair):
    _fake(monkeypatch, [CUDA], starts=[CUDA])
    on_gpu = SamAmgProbe(*sam_pair, device="cuda")
    on_cpu = SamAmgProbe(*sam_pair, device="cpu")
    assert on_gpu.describe()["params"]["provider"] == CUDA
    assert on_cpu.describe()["params"]["provider"] == CPU
    image = np.zeros((8, 8, 3), np.uint8)
    assert cache_key(image, "sam-amg", on_gpu.describe()) != cache_key(image, "sam-amg", on_cpu.describe())


def test_the_encoder_and_decoder_providers_are_both_recorded(monkeypatch, sam_pair):
    fake = _fake(monkeypatch, [CUDA], starts=[CUDA])
    probe = SamAmgProbe(*sam_pair, device="cuda")
    probe.models.decoder.provider = CPU  # as if the decoder's session had fallen back
    assert probe.describe()["params"]["provider"] == f"encoder: {CUDA}, decoder: {CPU}"
    assert fake.asked


def _args(structural, device, adapter=None):
    return argparse.Namespace(semantic_probe=None, structural_probe=structural, probe_device=device,
                              adapter=adapter)


def test_probe_device_reaches_specs_without_their_own(monkeypatch, sam_pair):
    _fake(monkeypatch, [CUDA], starts=[CUDA])
    enc, dec = sam_pair
    _, (probe,) = probes_from_args(_args([f"sam:encoder={enc},decoder={dec}"], "cuda"))
    assert probe.describe()["params"]["provider"] == CUDA
    _, (probe,) = probes_from_args(_args([f"sam:encoder={enc},decoder={dec},device=cpu"], "cuda"))
    assert probe.describe()["params"]["provider"] == CPU  # the spec's device wins


def test_auto_on_lavapipe_runs_the_probes_on_the_cpu(sam_pair):
    # the renderer here is lavapipe: auto gives the CPU provider, without a warning
    enc, dec = sam_pair
    with warning_log.collecting(None):
        _, (probe,) = probes_from_args(_args([f"sam:encoder={enc},decoder={dec}"], "auto", adapter="cpu"))
        assert not [r for r in warning_log.records() if "could not start" in r["message"]]
    assert probe.describe()["params"]["provider"] == CPU


def test_cli_refuses_a_missing_provider_before_any_work(tmp_path, sam_pair, capsys, monkeypatch):
    from badinput_cases import renders_bundle

    _fake(monkeypatch, [])
    enc, dec = sam_pair
    out = tmp_path / "out"
    rc = cli.main(["score", str(renders_bundle(tmp_path / "b")), "--out", str(out), "--probe-device", "cuda",
                   "--structural-probe", f"sam:encoder={enc},decoder={dec}"])
    err = capsys.readouterr().err
    assert rc == 2 and "gpu-cuda" in err and "Traceback" not in err
    assert not out.exists()


def test_cli_refuses_an_unknown_probe_device(tmp_path, capsys):
    from badinput_cases import renders_bundle

    rc = cli.main(["score", str(renders_bundle(tmp_path / "b")), "--out", str(tmp_path / "o"), "--probe-device",
                   "tpu"])
    assert rc == 2 and "unknown device 'tpu'" in capsys.readouterr().err


def test_lpips_takes_the_probe_device_and_records_its_provider(monkeypatch, tmp_path):
    from test_metrics_fidelity import _lpips_like_model

    from r360gpu.metrics.fidelity import LpipsModel

    path = _lpips_like_model(tmp_path / "lpips.onnx")
    assert LpipsModel(path).describe()["provider"] == CPU
    fake = _fake(monkeypatch, [WEBGPU])
    with warning_log.collecting(None):
        lp = LpipsModel(path, "webgpu")
        records = warning_log.records()
    assert fake.asked == [[WEBGPU, CPU]]
    assert lp.describe()["provider"] == CPU
    assert any("could not start WebGpuExecutionProvider for the LPIPS model" in r["message"] for r in records)
    x = np.zeros((12, 12, 3))
    assert lp.distance(x, x) == pytest.approx(0.0, abs=1e-7)


class FakePlugin:
    """The onnxruntime-ep-webgpu module's interface."""

    @staticmethod
    def get_library_path():
        return "/fake/libonnxruntime_providers_webgpu.so"

    @staticmethod
    def get_ep_name():
        return WEBGPU


def test_the_webgpu_plugin_is_registered_and_added_through_the_session_options(monkeypatch, sam_pair):
    calls = []

    class PluginOrt(FakeOrt):
        def register_execution_provider_library(self, name, path):
            calls.append(("register", name, path))

        def get_ep_devices(self):
            return [types.SimpleNamespace(ep_name="CPUExecutionProvider"), types.SimpleNamespace(ep_name=WEBGPU)]

    class Options:
        def __init__(self):
            self.log_severity_level = 0

        def add_provider_for_devices(self, devices, opts):
            calls.append(("add", [d.ep_name for d in devices], opts))

    fake = PluginOrt([], starts=[])
    monkeypatch.setattr(providers, "_ort", lambda: fake)
    monkeypatch.setattr(providers, "_webgpu_plugin", lambda: FakePlugin)
    monkeypatch.setattr(providers, "_plugin_registered", {})
    assert WEBGPU in providers.available_providers()
    chosen = providers.plan("auto", AMD)
    assert chosen.device == "webgpu" and chosen.plugin

    def session(source, sess_options=None, providers=None):
        calls.append(("session", providers))
        return types.SimpleNamespace(get_providers=lambda: [WEBGPU, CPU])

    fake.InferenceSession = session
    s = providers.open_session(str(sam_pair[0]), Options(), chosen)
    assert s.get_providers()[0] == WEBGPU
    assert calls == [("register", "webgpu", FakePlugin.get_library_path()), ("add", [WEBGPU], {}),
                     ("session", None)]


def test_evaluate_options_check_the_probe_device(monkeypatch):
    from r360gpu.pipeline import EvaluateOptions

    with pytest.raises(InputError, match="unknown device 'tpu'"):
        EvaluateOptions(probe_device="tpu")
    _fake(monkeypatch, [])
    with pytest.raises(InputError, match="gpu-cuda"):  # LPIPS would run on it: refused when the options are built
        EvaluateOptions(lpips_model="lpips.onnx", probe_device="cuda")
    assert "probe_device" not in EvaluateOptions(probe_device="cpu").scoring_key()  # changes no value without LPIPS
    with_lpips = EvaluateOptions(lpips_model="lpips.onnx", probe_device="cpu").scoring_key()
    assert with_lpips["probe_device"] == "cpu"


def test_a_run_records_the_fallback_and_the_provider_that_ran(tmp_path, sam_pair, capsys, monkeypatch):
    """score --probe-device cuda on a build whose CUDA provider cannot start: the run goes on, on the CPU
    provider, and says so on stderr and in results.json; the probe's description names the CPU."""
    from badinput_cases import renders_bundle

    _fake(monkeypatch, [CUDA])
    enc, dec = sam_pair
    out = tmp_path / "out"
    rc = cli.main(["score", str(renders_bundle(tmp_path / "b")), "--out", str(out), "--probe-device", "cuda",
                   "--structural-probe", f"sam:encoder={enc},decoder={dec},points_per_side=4", "--no-pictures",
                   "--no-boundary", "--no-controls", "--n-boot", "50", "--n-perm", "50", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "could not start CUDAExecutionProvider" in err
    doc = json.loads((out / "results.json").read_text())
    assert any("could not start CUDAExecutionProvider" in w["message"] and "running on CPUExecutionProvider"
               in w["message"] for w in doc["warnings"]), doc["warnings"]
    (scene,) = doc["scenes"].values()
    (probe,) = scene["probes"]["structural"]
    assert probe["params"]["provider"] == CPU
