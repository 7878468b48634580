"""Options and addresses checked before any work (classes 5, 6 and 10 of docs/input-validation.md)."""
from __future__ import annotations

import socket

import pytest

from badinput_cases import renders_bundle
from r360gpu import cli
from r360gpu.errors import InputError
from r360gpu.pipeline import EvaluateOptions


@pytest.mark.parametrize("flag", ["--views", "--xi"])
@pytest.mark.parametrize("value", ["", ",", " , "])
def test_an_empty_list_flag_is_refused(flag, value, tmp_path, capsys):
    b = renders_bundle(tmp_path / "b")
    with pytest.raises(SystemExit) as e:
        cli.main(["score", str(b), "--out", str(tmp_path / "out"), flag, value])
    assert e.value.code == 2
    assert f"{flag}: empty value" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_check_refuses_an_empty_views_flag_too(tmp_path, capsys):
    with pytest.raises(SystemExit):
        cli.main(["check", str(renders_bundle(tmp_path / "b")), "--views", ""])
    assert "--views: empty value" in capsys.readouterr().err


@pytest.mark.parametrize("kw,fragment", [
    ({"xis": (0.3, 1.5)}, "xi"), ({"xis": (float("nan"),)}, "xi"), ({"xis": ()}, "xis"),
    ({"n_boot": 0}, "n_boot"), ({"n_boot": -5}, "n_boot"), ({"n_perm": 0}, "n_perm"),
    ({"n_boot": 2.5}, "n_boot"), ({"seed": -1}, "seed"), ({"depth": "mean"}, "depth"),
    ({"views": ()}, "views"), ({"views": ("",)}, "views"), ({"fit_views": 0}, "fit_views"),
])
def test_library_options_are_refused_when_built(kw, fragment):
    with pytest.raises(InputError, match=fragment):
        EvaluateOptions(**kw)


def test_options_changed_after_building_are_refused_before_any_work(tmp_path):
    from r360gpu import evaluate

    opts = EvaluateOptions()
    opts.xis = (0.3, 2.0)
    with pytest.raises(InputError, match="xi"):
        evaluate(str(tmp_path / "no-such-bundle"), options=opts, out=tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()  # refused before the bundle is even looked at


def test_ray_address_that_refuses_is_named_at_once(tmp_path, capsys):
    pytest.importorskip("ray")
    rc = cli.main(["score", str(renders_bundle(tmp_path / "b")), "--out", str(tmp_path / "o"),
                   "--ray", "127.0.0.1:1"])
    err = capsys.readouterr().err
    assert rc == 2 and "127.0.0.1:1" in err and "Traceback" not in err


def test_ray_address_that_does_not_answer_times_out(monkeypatch):
    from r360gpu.pipeline.distributed import probe_cluster

    seen = {}

    def silent(address, timeout):
        seen["timeout"] = timeout
        raise socket.timeout("timed out")

    monkeypatch.setattr(socket, "create_connection", silent)
    with pytest.raises(InputError, match=r"no answer within 0\.5 s"):
        probe_cluster("10.1.2.3:6379", 0.5)
    assert seen["timeout"] == 0.5


@pytest.mark.parametrize("address,endpoint", [("local", None), ("h:6379", ("h", 6379)),
                                               ("ray://h:10001", ("h", 10001)), ("[::1]:6379", ("::1", 6379))])
def test_cluster_endpoint(address, endpoint, monkeypatch):
    from r360gpu.pipeline.distributed import cluster_endpoint

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    assert cluster_endpoint(address) == endpoint
    assert cluster_endpoint("auto") is None


@pytest.mark.parametrize("timeout", ["0", "-1", "nan"])
def test_ray_timeout_must_be_positive(timeout, tmp_path, capsys):
    pytest.importorskip("ray")
    rc = cli.main(["score", str(renders_bundle(tmp_path / "b")), "--out", str(tmp_path / "o"),
                   "--ray", "local", "--ray-timeout", timeout])
    assert rc == 2 and "--ray-timeout" in capsys.readouterr().err


def test_ray_timeout_needs_ray(tmp_path, capsys):
    rc = cli.main(["score", str(renders_bundle(tmp_path / "b")), "--out", str(tmp_path / "o"),
                   "--ray-timeout", "5"])
    assert rc == 2 and "--ray-timeout" in capsys.readouterr().err
