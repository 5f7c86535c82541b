"""Spatial hash and Verlet lists against all pairs (exact), and the modes agreeing."""

import numpy as np
import pytest

from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.model.spec import skin_for
from taimill.physics.runner import Runner
from taimill.store.sinks import MemorySink


def _packing(n, seed, jar_radius=0.05, height=0.05, r=0.006):
    """Random centres, overlaps allowed (a harder case than any real state)."""
    rng = np.random.default_rng(seed)
    rho = (jar_radius - r) * np.sqrt(rng.random(n))
    phi = 2 * np.pi * rng.random(n)
    return np.column_stack([rho * np.cos(phi), rho * np.sin(phi), rng.uniform(r, height - r, n)])


def _brute_force(x, reach):
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    return [list(np.flatnonzero(row < reach)) for row in d]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("mode,use_grid", [("fused", False), ("fused", True), ("parallel", True)])
def test_lists_equal_all_pairs_for_random_packings(seed, mode, use_grid):
    # Exact equality: same set and the same ascending order (summation order).
    p = load_preset("presets/p4-cy-steel.toml", {"jar": "CY"})
    spec = from_preset(p, 0.001)
    x = _packing(40, seed, p.jar.radius, p.jar.height)
    spec = spec.replace(position=x, velocity=np.zeros_like(x), spin=np.zeros_like(x),
                        radius=np.full(40, spec.radius[0]), mass=np.full(40, spec.mass[0]))
    runner = Runner([spec], mode=mode, use_grid=use_grid)
    runner.engine.build_lists()
    want = _brute_force(x, 2 * spec.radius[0] + skin_for(spec))
    assert runner.engine.neighbour_lists(0) == want


@pytest.mark.parametrize("over", [{}, {"friction.mu_r": 0.1}])
def test_launch_modes_give_bit_identical_events(over):
    # All-pairs vs hash, fused vs parallel: same contacts, same summation order. The
    # fused mode computes a ball-ball contact once (its owner leaves the partner's
    # force and torque, rolling resistance included); parallel mode computes both visits.
    p = load_preset("presets/p4-cy-steel.toml", {"ratio": -2.6, **over})
    spec = from_preset(p, 0.03)
    v0 = np.random.default_rng(0).normal(0.0, 0.7, (spec.n, 3))  # collide from the first step
    spec = spec.replace(velocity=v0)
    tables = []
    for mode, grid in (("fused", False), ("fused", True), ("parallel", True)):
        sink = MemorySink()
        Runner([spec], mode=mode, use_grid=grid).run([sink])
        tables.append(sink.event_table)
    assert len(tables[0]["t_start"]) > 20
    for other in tables[1:]:
        for k in tables[0]:
            np.testing.assert_array_equal(tables[0][k], other[k])
