"""The backend choice (taimill.physics.backend; docs/performance.md, backends): `--backend`
on the command line, else TAIMILL_BACKEND, else cpu. A name that is none and cuda where
no device is found are refused in one line, exit 2, before anything runs; Taichi's own
silent fall-back to the CPU is caught; every run records what computed it (the
summary's `compute`, in the store and in --json); and naming the default changes no
bit. The cases that need a machine without a CUDA device skip where one is found."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from taimill.physics import backend
from taimill.schema import MACHINE_KEYS
from taimill.store.run import open_run

ROOT = Path(__file__).resolve().parent.parent
PRESET = str(ROOT / "presets" / "p4-cy-steel.toml")
SHORT = ("--duration", "0.3", "--seed", "3")
NO_DEVICE = pytest.mark.skipif(bool(backend.cuda_devices()), reason="a CUDA device is found here")


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, env: dict | None = None, timeout=600) -> subprocess.CompletedProcess:
    environ = {k: v for k, v in os.environ.items() if k != backend.ENV} | (env or {})
    return subprocess.run(command(*args), cwd=ROOT, capture_output=True, text=True, timeout=timeout, env=environ)


def one_line(res) -> str:
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2, res.stderr
    assert len(lines) == 1 and lines[0].startswith("taimill: error: "), res.stderr
    assert res.stdout == ""
    return lines[0]


@NO_DEVICE
def test_cuda_without_a_device_is_one_line_naming_the_way_out(tmp_path):
    out = tmp_path / "run.zarr"
    line = one_line(taimill("run", PRESET, *SHORT, "--backend", "cuda", "--out", out))
    assert "command line: --backend = 'cuda'" in line and "no CUDA device was found" in line
    assert "--backend cpu or auto" in line
    assert not out.exists()  # refused before anything was written
    line = one_line(taimill("sweep", PRESET, "--ratio", "-2", "--duration", "0.1", env={backend.ENV: "cuda"}))
    assert "environment: TAIMILL_BACKEND = 'cuda'" in line and "no CUDA device was found" in line


def test_a_backend_that_is_none_is_one_line_from_either_source():
    line = one_line(taimill("run", PRESET, *SHORT, env={backend.ENV: "bogus"}))
    assert "environment: TAIMILL_BACKEND = 'bogus'" in line and "one of cpu" in line and "cuda" in line and "auto" in line
    line = one_line(taimill("tui", PRESET, "--backend", "gpu"))
    assert "command line: --backend = 'gpu'" in line and "one of cpu" in line


@NO_DEVICE
def test_auto_runs_on_the_cpu_and_the_run_says_what_computed_it(tmp_path):
    out = tmp_path / "auto.zarr"
    res = taimill("run", PRESET, *SHORT, "--backend", "auto", "--out", out, "--json",
                  env={"TI_CPU_MAX_NUM_THREADS": "1"})
    assert res.returncode == 0, res.stderr
    said = json.loads(res.stdout)["compute"]
    assert said == {"backend": "cpu", "device": backend.cpu_model(), "threads": 1}
    assert open_run(out).summary["compute"] == said  # the store keeps it with the summary


def test_the_command_line_wins_and_reaches_a_sweeps_workers(tmp_path):
    # the environment names no backend, the command line cpu: a worker that read the
    # environment instead of its parent's choice would refuse to start
    out = tmp_path / "sweep.zarr"
    res = taimill("sweep", PRESET, "--ratio", "-2", "--duration", "0.1", "--workers", 1, "--backend", "cpu", "--out", out,
                  env={backend.ENV: "bogus"})
    assert res.returncode == 0, res.stderr
    from taimill.store.sweep import open_sweep

    assert open_sweep(out).point(0).summary["compute"] == {"backend": "cpu", "device": backend.cpu_model(), "threads": 1}


def test_naming_the_default_changes_no_bit(tmp_path):
    stores = []
    for name, extra in (("plain", ()), ("cpu", ("--backend", "cpu"))):
        out = tmp_path / f"{name}.zarr"
        res = taimill("run", PRESET, *SHORT, *extra, "--out", out, "--json")
        assert res.returncode == 0, res.stderr
        stores.append(open_run(out))
    a, b = stores
    assert a.summary["compute"]["backend"] == b.summary["compute"]["backend"] == "cpu"
    assert len(a.events["t_start"]) > 50
    for col in a.events:
        np.testing.assert_array_equal(a.events[col], b.events[col], err_msg=col)
    np.testing.assert_array_equal(a.frames["position"], b.frames["position"])
    keep = lambda s: {k: v for k, v in s.items() if k not in MACHINE_KEYS}  # noqa: E731
    assert keep(a.summary) == keep(b.summary)


FALLBACK = """
import os, sys
from taimill.physics import backend, ti
if backend.cuda_devices():
    print("a device")  # Taichi would start on it
    sys.exit(0)
backend.cuda_devices = lambda: ("Pretend GPU",)
os.environ[backend.ENV] = sys.argv[1]
try:
    ti.init_taichi()
except ValueError as err:
    print(err)
    sys.exit(2)
print("started on", ti.compute()["backend"])
"""


def _pretend_a_device(tmp_path, name: str) -> subprocess.CompletedProcess:
    """init_taichi asked for `name` in a process whose driver check is told a device
    exists, so that Taichi's own fall-back to the CPU is what happens."""
    script = tmp_path / "fallback.py"
    script.write_text(FALLBACK)
    res = subprocess.run([sys.executable, str(script), name], cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env=os.environ | {"PYTHONPATH": str(ROOT)})
    if res.stdout.strip() == "a device":
        pytest.skip("a CUDA device is found here")
    return res


def test_taichis_silent_fall_back_to_the_cpu_is_refused_for_cuda_and_taken_for_auto(tmp_path):
    res = _pretend_a_device(tmp_path, "cuda")
    assert res.returncode == 2, res.stderr
    assert "did not start on the CUDA device Pretend GPU" in res.stdout and "--backend cpu" in res.stdout
    res = _pretend_a_device(tmp_path, "auto")
    assert res.returncode == 0 and res.stdout.strip() == "started on cpu", res.stdout + res.stderr
    assert res.stderr == ""  # quietly


def test_the_choice_resolves_in_order(monkeypatch):
    monkeypatch.setattr(backend, "_told", None)
    monkeypatch.delenv(backend.ENV, raising=False)
    assert backend.requested() == ("cpu", "environment", backend.ENV)
    monkeypatch.setenv(backend.ENV, " CUDA ")
    assert backend.requested()[0] == "cuda"
    monkeypatch.setattr(backend, "cuda_devices", lambda: ())
    assert backend.select("auto") == "auto" and os.environ[backend.ENV] == "auto"  # handed on to spawned workers
    assert backend.arch() == "cpu"
    monkeypatch.setattr(backend, "cuda_devices", lambda: ("Pretend GPU",))
    assert backend.arch() == "cuda"
    with pytest.raises(ValueError, match=r"command line: --backend = 'opencl': one of cpu"):
        backend.select("opencl")


def test_the_summary_comparison_of_the_gpu_tests_sees_every_key():
    """tests/test_gpu.py and the device check compare a CUDA run's summary with the CPU's
    by scripts/device_check.summary_difference: nested numbers, text and event counts
    count, the machine's keys do not."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from device_check import TOLERANCE, agrees, summary_difference

    a = {"events": 10, "mean_se": 1.0, "all_contacts": {"events": 12, "mean_se": 2.0}, "regime": "cascading",
         "analysis_window": [0.5, 2.0], "wall_seconds": 3.0, "compute": {"backend": "cuda"}, "nothing": None}
    same = json.loads(json.dumps(a)) | {"wall_seconds": 9.0, "compute": {"backend": "cpu"}}
    assert summary_difference(a, same) | {"events": None} == dict(
        max_rel=0.0, worst_key=None, unequal=[], events_equal=True, event_counts=2, events=None)
    near = json.loads(json.dumps(a))
    near["all_contacts"]["mean_se"] = 2.0 * (1 + 3e-10)
    d = summary_difference(a, near)
    assert d["worst_key"] == "all_contacts.mean_se" and d["max_rel"] == pytest.approx(3e-10, rel=1e-3) and agrees(d)
    near["analysis_window"][1] = 2.0 * (1 + 10 * TOLERANCE)
    d = summary_difference(a, near)
    assert d["worst_key"] == "analysis_window.1" and not agrees(d)
    counted = json.loads(json.dumps(a))
    counted["all_contacts"]["events"] = 13
    assert not summary_difference(a, counted)["events_equal"]
    worded = json.loads(json.dumps(a)) | {"regime": "cataracting"}
    missing = {k: v for k, v in a.items() if k != "mean_se"}
    assert summary_difference(a, worded)["unequal"] == ["regime"]
    assert summary_difference(a, missing)["unequal"] == ["mean_se"] and not agrees(summary_difference(a, missing))
