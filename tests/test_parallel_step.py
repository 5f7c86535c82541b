"""Parallel mode's step is one launch of a few steps whose every phase runs on all
threads (physics/engine.py step_parallel): the cell prefix sum in blocks, the frame's
energy ledger summed in blocks of balls. What it computes must equal the fused mode
(one thread, the same functions) to the bit, also for mills of several blocks."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.physics import state as S
from taimill.physics.runner import Runner
from taimill.store.sinks import MemorySink

ROOT = Path(__file__).resolve().parent.parent


def _thrown(n, duration, seed=1, radius_mm=1.5):
    """n small balls of the CY jar thrown about from the first step."""
    p = load_preset("presets/p4-cy-steel.toml", {"ratio": -2.6, "balls.count": n, "balls.radius_mm": radius_mm,
                                                 "analysis_start": 0.0})
    spec = from_preset(p, duration)
    return spec.replace(velocity=np.random.default_rng(seed).normal(0.0, 1.0, (spec.n, 3)))


def _blocks_mill(duration):
    """A mill of three blocks of the ledger's sums, a frame every 0.25 ms."""
    spec = _thrown(2 * S.LEDGER_BLOCK + 300, duration)
    return spec.replace(frame_every=max(1, round(0.00025 / spec.dt)))


def test_a_mill_of_several_ledger_blocks_gives_the_same_bits_in_both_modes():
    spec = _blocks_mill(0.002)
    sinks = {}
    for mode in ("fused", "parallel"):
        sinks[mode] = MemorySink()
        Runner([spec], mode=mode).run([sinks[mode]])
    fused, parallel = sinks["fused"], sinks["parallel"]
    assert len(fused.frame_table["time"]) >= 3 and len(fused.event_table["t_start"]) > 100
    assert fused.energy_table["kinetic"][-1] > 0.0
    for table in ("event_table", "frame_table", "energy_table"):
        want, got = getattr(fused, table), getattr(parallel, table)
        assert want.keys() == got.keys()
        for k in want:
            np.testing.assert_array_equal(want[k], got[k], err_msg=f"{table}[{k}]")


def test_the_blocked_prefix_sum_gives_every_cell_its_start():
    spec = _thrown(12_000, 0.001, seed=4, radius_mm=0.5)  # 88 412 cells
    runner = Runner([spec], mode="parallel", reorder=False)
    runner.engine.build_lists()
    F = runner.engine.F
    dim = F.spatial.grid_dim.to_numpy()[0]
    cells = int(np.prod(dim))
    # several groups of blocks, the last group and block short
    assert cells > S.SCAN_BLOCK**2 and cells % S.SCAN_BLOCK != 0 and (cells // S.SCAN_BLOCK) % S.SCAN_BLOCK != 0
    lo, h = F.spatial.grid_lo.to_numpy()[0], F.spatial.grid_h.to_numpy()[0]
    x = F.state.x.to_numpy()[0, : spec.n]
    c = np.clip(np.floor((x - lo) / h).astype(int), 0, dim - 1)
    index = (c[:, 2] * dim[1] + c[:, 1]) * dim[0] + c[:, 0]
    count = np.bincount(index, minlength=cells)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    np.testing.assert_array_equal(F.spatial.cell_start.to_numpy()[0, :cells], start)
    np.testing.assert_array_equal(F.spatial.cell_count.to_numpy()[0, :cells], count)


def test_advance_takes_exactly_the_steps_asked_for():
    spec = _blocks_mill(0.01)  # the engine of the test above: no kernels to compile
    runner = Runner([spec], mode="parallel")
    assert runner.engine.steps_per_kernel > 1  # else this says nothing
    for n in (1, 3, 2, 5):
        before = int(runner.engine.F.state.step[0])
        runner.engine.advance(n)
        runner.engine.drain(0)
        assert int(runner.engine.F.state.step[0]) == before + n


MEMORY_SCRIPT = """
import json
from taimill.physics.engine import Engine
from taimill.physics.ti import init_taichi
init_taichi(1)
n = 1_000_000
# the most cells a mill's grid gets: 8 per ball (model.spec.grid_for), rounded up to a power of two (Runner)
engine = Engine(1, n, mode="parallel", grid_cells=1 << (8 * n).bit_length())
print(json.dumps(dict(mode=engine.mode, bytes=engine.F.nbytes())))
"""


def test_a_mill_of_a_million_balls_fits_in_two_gigabytes_of_device_memory():
    # declared, never allocated: a subprocess, since Taichi would allocate every declared
    # field at this process's next kernel
    env = os.environ | {"PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", MEMORY_SCRIPT], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["mode"] == "parallel"
    assert 1.0e9 < r["bytes"] <= 2.0e9  # 1.37 GB when written; 1 GB would mean a field was missed


def test_the_launch_mode_follows_where_the_kernels_run(monkeypatch):
    from taimill.physics import runner as R

    assert R.parallel_above("cpu", 1) == R.parallel_above("cpu", 2) == R.PARALLEL_ABOVE
    assert R.parallel_above("cpu", 16) == R.PARALLEL_ABOVE_MANY_THREADS < R.PARALLEL_ABOVE
    assert R.parallel_above("cuda", 1) == R.PARALLEL_ABOVE_ON_GPU < R.PARALLEL_ABOVE_MANY_THREADS
    spec = _thrown(200, 0.001)
    monkeypatch.setattr(R, "PARALLEL_ABOVE_ON_GPU", 100)  # a mill of 200 balls is then "large" on a GPU
    for where, mode in ((("cpu", 2), "fused"), (("cuda", 1), "parallel")):
        monkeypatch.setattr(R, "where", lambda w=where: w)
        assert R._runner_shape([spec])[2] == mode, where
