"""CUDA against the CPU (docs/performance.md, backends): the golden runs' small mills
and a 10⁴-ball simple-cubic lattice run through the real command line with
`--backend cuda` and with `--backend cpu`, each in its own process, must give every
summary key within 10⁻⁹ relative (a GPU may contract multiply-adds; the kernels and
their order of summation are the same) and equal event counts. Marked `gpu`; where no
CUDA device is found (CI has none) every test skips, saying so. The device is looked
for with the driver alone: this process never starts Taichi."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from taimill.physics.backend import cuda_devices
from test_golden import CASES

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))

import bench  # noqa: E402  (dense_case, DENSE_DT)
from device_check import TOLERANCE, summary_difference  # noqa: E402

pytestmark = [pytest.mark.gpu,
              pytest.mark.skipif(not cuda_devices(), reason="no CUDA device found (the driver, libcuda, shows none)")]
LATTICE_BALLS, LATTICE_STEPS = 10_000, 300


def run_on(backend: str, args: list[str], out: Path) -> tuple[dict, object]:
    """`taimill run ARGS --backend BACKEND --json --out OUT` in a subprocess of this checkout."""
    from taimill.store.run import open_run

    res = subprocess.run([sys.executable, "-m", "taimill", "run", *args, "--backend", backend, "--json", "--out", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=1800)
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads(res.stdout)
    assert summary["compute"]["backend"] == backend  # no silent fall-back
    return summary, open_run(out)


def assert_agree(args: list[str], tmp_path: Path):
    (gpu, gpu_store), (cpu, cpu_store) = (run_on(b, args, tmp_path / f"{b}.zarr") for b in ("cuda", "cpu"))
    d = summary_difference(gpu, cpu)
    assert not d["unequal"], d["unequal"]
    assert d["max_rel"] <= TOLERANCE, f"{d['worst_key']} differs by {d['max_rel']:.2e} relative"
    assert d["events_equal"] and d["event_counts"] > 0
    assert len(gpu_store.events["t_start"]) == len(cpu_store.events["t_start"])  # the stored rows too
    assert gpu["steps"] == cpu["steps"]


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_golden_runs_agree_on_cuda_and_the_cpu(name, tmp_path):
    preset, extra = CASES[name]
    assert_agree([preset, *extra], tmp_path)


def test_a_dense_lattice_agrees_on_cuda_and_the_cpu(tmp_path):
    preset = bench.dense_case(tmp_path / "beds", LATTICE_BALLS, False, "sc")
    every = LATTICE_STEPS // 3
    cli = preset.with_name("gpu.toml")  # beside the preset: its jar and start are relative paths
    cli.write_text(preset.read_text().split("[outputs]")[0]
                   + f'[outputs]\ntrajectory_rate = {float(f"{1 / (every * bench.DENSE_DT):.9g}")!r}\n')
    assert_agree([str(cli), "--duration", repr((LATTICE_STEPS + 0.25) * bench.DENSE_DT)], tmp_path)
