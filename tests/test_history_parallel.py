"""Contact models with history in parallel mode (docs/model.md, friction with history):
a large mill with the LIGGGHTS-like contact set (Hertz–Mindlin, tangential spring with
history, EPSD2 rolling) spreads its balls over all cores like any other. Both balls of
a contact compute it, the partner with the owner's history read from the block of the
owner's pool row that no thread writes in that step (pool.history_block), so the run
equals the fused mode's (one thread, the owner computing each contact once) to the bit
and does not depend on the thread count. Taichi takes its thread count once per
process: each run here is its own interpreter."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from taimill.model.frame import Ramp
from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.physics import runner as R
from taimill.physics.mill import set_clock

ROOT = Path(__file__).resolve().parent.parent

LIGGGHTS_LIKE = {"law": "hertz-mindlin", "friction.tangential": "history", "friction.rolling": "epsd2",
                 "friction.mu_r": 0.05}


def bed_spec(steps: int = 3000):
    """A bed of 2 mm steel balls on the floor of the CY jar with the LIGGGHTS-like set:
    columns of two, 100 nm apart, each resting on the floor at its contacts' overlaps
    under gravity (contacts that hold, ball-ball and floor, loaded sideways as the jar
    speeds up and as the bed is hit), and a sparse layer above thrown about at random
    (impacts on the bed and on the side wall: contacts that open and close). Returns
    (spec, balls in the bed)."""
    p = load_preset("presets/p4-cy-steel.toml", LIGGGHTS_LIKE | {"balls.count": 100, "balls.diameter_mm": 2.0})
    spec = from_preset(p)
    r, mg = spec.radius[0], spec.mass[0] * spec.gravity
    jar = np.hypot(*spec.profile.outline.T).min()
    pitch = 2 * r + 1e-7
    m = int(jar / pitch)
    grid = np.array([(i, j) for i in range(-m, m + 1) for j in range(-m, m + 1)], dtype=float)
    bed = grid[np.hypot(*grid.T) * pitch <= jar - r] * pitch
    z0 = r - (2 * mg / spec.ball_wall.k) ** (2 / 3)
    z1 = z0 + 2 * r - (mg / spec.ball_ball.k) ** (2 / 3)
    x = [np.column_stack([bed, np.full(len(bed), z)]) for z in (z0, z1)]
    rng = np.random.default_rng(7)
    loose = grid[np.hypot(*grid.T) * 3 * pitch <= jar - 4 * r] * 3 * pitch
    loose = loose + rng.uniform(-0.05e-3, 0.05e-3, loose.shape)
    angle = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    ring = (jar - r - 0.05e-3) * np.column_stack([np.cos(angle), np.sin(angle)])  # by the side wall
    x.append(np.column_stack([np.vstack([loose, ring]), np.full(len(loose) + len(ring), z1 + pitch + 0.1e-3)]))
    x = np.vstack(x)
    n, nb = len(x), 2 * len(bed)
    v = rng.normal(0.0, 0.3, (n, 3)) - [0.0, 0.0, 0.3]
    v[:nb] = 0.0
    v[n - len(ring):, :2] += 0.3 * ring / np.hypot(*ring.T)[:, None]  # towards the side wall
    return spec.replace(position=x, velocity=v, spin=np.zeros((n, 3)), radius=np.full(n, r),
                        mass=np.full(n, spec.mass[0]), steps=steps, frame_every=500), nb


SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, "tests")
from test_history_parallel import bed_spec
from taimill.physics.runner import Runner
from taimill.physics.ti import init_taichi, ti
from taimill.store.sinks import MemorySink

init_taichi()
spec, nb = bed_spec()
n = spec.n
sink = MemorySink()
sink.start({}, spec.n, spec.radius)
runner = Runner([spec], mode=sys.argv[1])
moved = []
launch = runner.launch

def counting(sinks):  # whether the rows were put in grid order
    out = launch(sinks)
    moved.append(bool((runner.engine.own_order(0) != np.arange(n)).any()))
    return out

runner.launch = counting
runner.run([sink])
F = runner.engine.F
arrays = {"event_" + k: v for k, v in sink.event_table.items()}
arrays |= {"energy_" + k: v for k, v in sink.energy_table.items()}
arrays |= {"final_" + k: v for k, v in runner.final_state(0).items()}
arrays |= {"spectra_count": sink.last_spectra.count, "spectra_fixed": sink.last_spectra.fixed}
np.savez(sys.argv[2], **arrays)
print(json.dumps(dict(threads=ti.lang.impl.current_cfg().cpu_max_num_threads, mode=runner.engine.mode, dt=spec.dt,
                      reorder=F.reorder, moved=any(moved), balls=n, bed=nb, open=int(np.bitwise_count(
                          F.contacts.slot_mask.to_numpy()[0]).sum()))))
"""


def _run(folder: Path, mode: str, threads: int) -> tuple[dict, dict]:
    """(what the run says of itself, its arrays) of the bed run in `mode` on `threads`."""
    out = folder / f"{mode}-{threads}.npz"
    env = os.environ | {"TI_CPU_MAX_NUM_THREADS": str(threads), "PYTHONPATH": str(ROOT)}
    res = subprocess.run([sys.executable, "-c", SCRIPT, mode, str(out)], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    with np.load(out) as f:
        return json.loads(res.stdout.strip().splitlines()[-1]), dict(f)


@pytest.fixture(scope="module")
def bed_run(tmp_path_factory):
    """The bed run in a mode on a thread count, each made once in this module."""
    folder, done = tmp_path_factory.mktemp("history-bed"), {}

    def run(mode: str, threads: int):
        if (mode, threads) not in done:
            done[mode, threads] = _run(folder, mode, threads)
        return done[mode, threads]

    return run


def _assert_same(want: dict, got: dict):
    assert want.keys() == got.keys()
    for k in want:
        np.testing.assert_array_equal(want[k], got[k], err_msg=k)


def test_a_history_mill_in_parallel_mode_equals_the_fused_mode_to_the_bit(bed_run):
    fused, fused_arrays = bed_run("fused", 1)
    par, par_arrays = bed_run("parallel", 2)
    assert fused["mode"] == "fused" and par["mode"] == "parallel" and par["reorder"] and par["moved"]
    assert fused["bed"] > 1500 and fused["balls"] > 1600
    # contacts that held for most of the run (the bed's, ball-ball and floor: of those
    # that closed, hundreds lasted more than 1000 steps, and half the bed's were still
    # open at the end), impacts that opened and closed, on balls and walls
    steps = fused_arrays["event_duration"] / fused["dt"]
    ball, body_j = fused_arrays["event_kind"] == 0, fused_arrays["event_body_j"]
    floor, side = body_j == -2, body_j == -1
    assert fused["open"] > 0.5 * fused["bed"]
    assert (ball & (steps > 1000)).sum() > 300 and (floor & (steps > 1000)).sum() > 300
    assert (ball & (steps < 200)).sum() > 1000 and (floor & (steps < 200)).sum() > 100 and side.sum() > 10
    _assert_same(fused_arrays, par_arrays)


def test_a_history_mill_gives_the_same_bits_on_one_and_two_threads(bed_run):
    one, one_arrays = bed_run("parallel", 1)
    two, two_arrays = bed_run("parallel", 2)
    assert one["threads"] == 1 and two["threads"] == 2  # the setting took
    assert one["mode"] == two["mode"] == "parallel"
    _assert_same(one_arrays, two_arrays)


def test_a_large_history_mill_runs_in_parallel_mode(monkeypatch):
    # above PARALLEL_ABOVE balls one mill runs on every core, whatever its contact model
    p = load_preset("presets/p4-cy-steel.toml", LIGGGHTS_LIKE | {"balls.count": 200, "balls.diameter_mm": 2.0})
    spec = from_preset(p)
    monkeypatch.setattr(R, "PARALLEL_ABOVE", 100)
    assert spec.contact_models[0].tangential.history and spec.contact_models[1].rolling.history
    shape = R._runner_shape([spec])  # _engine_key's: (batch, balls, mode, use_grid, cells, pool, reorder, …)
    assert shape[2] == "parallel" and shape[6] is None  # the engine's default: rows in grid order
    assert R._runner_shape([spec, spec])[2] == "fused"  # a batch: one mill per thread
    few = spec.replace(radius=spec.radius[:50], mass=spec.mass[:50], position=spec.position[:50],
                       velocity=spec.velocity[:50], spin=spec.spin[:50])
    assert R._runner_shape([few])[2] == "fused"


def _steps(runner, n: int):
    """Advance the runner's mill by n steps, draining its buffers as a launch does."""
    F = runner.engine.F
    target = int(F.state.step[0]) + n
    while int(F.state.step[0]) < target:
        runner.engine.advance(target - int(F.state.step[0]))
        runner.engine.drain(0)


def test_a_clock_set_anew_keeps_the_history_the_contacts_read():
    # A live change of dt sets the step counter (mill.set_clock), whose parity picks the
    # history block a step reads: a counter moved by one must not hand the contacts the
    # history of the step before last. With the drive at rest nothing else reads the
    # clock, so the bed advanced after its clock was set one step on equals the bed left
    # alone, to the bit. The bed's balls spin at random from the start: every contact's
    # springs load from the first step.
    spec, _ = bed_spec(steps=10**6)
    spin = np.random.default_rng(5).normal(0.0, 20.0, (spec.n, 3))
    spec = spec.replace(plate=Ramp(0.0, 0.0, 0.0, 1.0), jar=Ramp(0.0, 0.0, 0.0, 1.0), spin=spin)
    final = []
    for jump in (0, 1):
        runner = R.Runner([spec], mode="parallel")
        _steps(runner, 300)
        F = runner.engine.F
        if jump:
            set_clock(F, 0, spec.dt, int(F.state.step[0]) + jump, spec.frame_every)
        _steps(runner, 300)
        final.append(runner.final_state(0) | {"elastic": runner.engine.ball_rows(0, "elastic")[: spec.n]})
    assert (final[0]["elastic"] > 0.0).sum() > 700  # the springs hold energy (the bed's lower balls own its contacts)
    for k in final[0]:
        np.testing.assert_array_equal(final[0][k], final[1][k], err_msg=k)
