"""Parallel mode keeps ball rows in grid order (physics/reorder.py): what a user sees —
events, frames, the energy ledger, the final state, the faulting ball — is the same, to
the bit, as with the rows in the spec's order."""

import numpy as np
import pytest

from taimill.errors import SimulationUnstable
from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.physics.runner import Runner
from taimill.store.sinks import MemorySink


def _mixing_mill(n=300, duration=0.02):
    """n small balls in random places and random order, thrown about from the first
    step: the lists are rebuilt (and the rows reordered) many times."""
    p = load_preset("presets/p4-cy-steel.toml", {"ratio": -2.6, "balls.count": n, "balls.radius_mm": 2.0})
    spec = from_preset(p, duration)
    v0 = np.random.default_rng(1).normal(0.0, 1.0, (spec.n, 3))
    return spec.replace(velocity=v0)


def _run(spec, reorder):
    sink = MemorySink()
    runner = Runner([spec], mode="parallel", reorder=reorder)
    builds = []
    launch = runner.launch

    def counting(sinks):  # how often the rows were put in grid order
        out = launch(sinks)
        builds.append(runner.engine.own_order(0).copy())
        return out

    runner.launch = counting
    runner.run([sink])
    return sink, runner.final_state(0), builds


def test_reordered_rows_give_bit_identical_events_frames_and_ledger():
    spec = _mixing_mill()
    plain, plain_state, _ = _run(spec, False)
    mixed, mixed_state, orders = _run(spec, True)
    assert len(plain.event_table["t_start"]) > 200 and (plain.event_table["kind"] == 0).sum() > 100
    # the rows really moved, more than once
    assert any((o != np.arange(spec.n)).any() for o in orders)
    assert len({o.tobytes() for o in orders}) > 2
    for table in ("event_table", "frame_table", "energy_table"):
        want, got = getattr(plain, table), getattr(mixed, table)
        assert want.keys() == got.keys()
        for k in want:
            np.testing.assert_array_equal(want[k], got[k], err_msg=f"{table}[{k}]")
    for k in plain_state:
        np.testing.assert_array_equal(plain_state[k], mixed_state[k])


def test_neighbour_lists_and_a_fault_name_the_balls_own_index():
    spec = _mixing_mill(duration=1e-3)
    runner = Runner([spec], mode="parallel")
    runner.engine.build_lists()
    order = runner.engine.own_order(0)
    assert (order != np.arange(spec.n)).any()
    plain = Runner([spec], mode="parallel", reorder=False)
    plain.engine.build_lists()
    assert runner.engine.neighbour_lists(0) == plain.engine.neighbour_lists(0)
    np.testing.assert_array_equal(runner.engine.ball_rows(0, "x")[: spec.n], spec.position)
    # a ball far outside the jar: the fault names it by its own index
    x = spec.position.copy()
    x[123] = (5e3, 0.0, 0.0)
    with pytest.raises(SimulationUnstable, match="ball 123 "):
        Runner([spec.replace(position=x)], mode="parallel").run([MemorySink()])
