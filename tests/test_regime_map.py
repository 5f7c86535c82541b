"""Regime maps (docs/regimes.md): the wall lag and the slip ratio that split a riding
charge into a pinned ring, a sliding bed and a rolling bed, and the (K, μ) figure with
its analytic boundaries."""

import math

import numpy as np
import pytest

from taimill.analysis.regime import MAP_REGIMES, PINNED_LAG, SLIDING_SLIP, map_regime, slip_ratio
from taimill.analysis.theory import critical_ratio, pinning_friction, pinning_ratio
from taimill.figures.regime_map import COLOURS, map_cells, regime_map

GEOMETRY = {"plate_radius": 0.125, "jar_radius": 0.0325, "ball_radius": 0.006, "balls": 12, "ball_mass": 7.1e-3,
            "plate_rpm": 200.0}


def _ref(K, mu_d):
    om = 200 * math.pi / 30
    return mu_d * 12 * 7.1e-3 * om**3 * 0.125 * 0.0325 * abs(K - 1)


def test_slip_ratio_is_the_share_of_full_sliding_friction_power():
    row = GEOMETRY | {"ratio": -3.0, "mu_d_wall": 0.2, "dissipated_power_side_persistent_friction": 0.5 * _ref(-3.0, 0.2)}
    assert slip_ratio(row) == pytest.approx(0.5)
    assert map_regime("rolling", 0.5) == "sliding bed"
    assert map_regime("rolling", 0.1 * SLIDING_SLIP) == "pinned ring"
    assert map_regime("cataracting", 0.5) == "cataracting"
    assert math.isinf(slip_ratio(row | {"mu_d_wall": 0.0}))  # nothing holds a frictionless charge
    assert map_regime("rolling", math.inf) == "sliding bed"


def test_map_regime_splits_a_riding_charge_three_ways_by_wall_lag_and_slip():
    # wall_lag < PINNED_LAG: turns with the jar, whatever the slip; near rest in the plate
    # frame: sliding with slip, rolling in place without it
    assert map_regime("rolling", 0.1 * SLIDING_SLIP, 0.0) == "pinned ring"
    assert map_regime("rolling", 5 * SLIDING_SLIP, 0.9 * PINNED_LAG) == "pinned ring"
    assert map_regime("rolling", SLIDING_SLIP, 1.0) == "sliding bed"
    assert map_regime("rolling", 0.1 * SLIDING_SLIP, 1.0) == "rolling bed"
    assert map_regime("rolling", 0.1 * SLIDING_SLIP, PINNED_LAG) == "rolling bed"
    assert map_regime("rolling", math.inf, 1.0) == "sliding bed"
    assert map_regime("cataracting", 0.0, 1.0) == "cataracting"
    # rows of sweep stores older than wall_lag (NaN column, or None): the two-way rule
    assert map_regime("rolling", 0.1 * SLIDING_SLIP, math.nan) == "pinned ring"
    assert map_regime("rolling", 0.1 * SLIDING_SLIP, None) == "pinned ring"
    assert map_regime("rolling", 0.5, math.nan) == "sliding bed"
    assert "rolling bed" in MAP_REGIMES and all(r in COLOURS for r in MAP_REGIMES)
    assert len({COLOURS[r] for r in MAP_REGIMES}) == len(MAP_REGIMES)


def test_pinning_ratio_inverts_pinning_friction():
    for mu in (0.05, 0.25, 1.0):
        k = pinning_ratio(mu, 0.125, 0.0325, 0.006)
        assert k < critical_ratio(0.125, 0.0325, 0.006)
        assert pinning_friction(k, 0.125, 0.0325, 0.006) == pytest.approx(mu)


def test_regime_map_colours_cells_and_draws_the_boundaries():
    rows = []
    for K in (0.0, -2.0, -3.0, -4.0):
        for mu in (0.05, 0.25, 1.0):
            pinned = mu >= pinning_friction(K, 0.125, 0.0325, 0.006)
            regime = "cascading" if K == 0 else "cataracting" if K == -2.0 else "rolling"
            for rep in range(2):
                rows.append(GEOMETRY | {"ratio": K, "mu": mu, "mu_wall": mu, "mu_d_wall": mu, "mu_r": 0.0, "regime": regime,
                                        "impact_power": 1.0 + abs(K) * mu, "dissipated_power_ball_ball_persistent_friction": 0.1,
                                        "dissipated_power_side_persistent_friction": (0.001 if pinned else 0.5) * _ref(K, mu)})
    cells = map_cells(rows)
    assert len(cells) == 12
    assert cells[(0.0, -4.0, 1.0)]["regime"] == "pinned ring"  # rows without wall_lag: old rule
    assert cells[(0.0, -3.0, 0.05)]["regime"] == "sliding bed"
    assert cells[(0.0, -2.0, 0.25)]["regime"] == "cataracting"
    # with wall_lag: pinned cells lag 0, sliding ones 1; the sliding cell (−4, 0.25) made
    # slip-free, at rest in the plate frame, is a rolling bed (without wall_lag: pinned)
    rolled = [r | {"wall_lag": 0.0 if r["dissipated_power_side_persistent_friction"] < 0.01 * _ref(r["ratio"], r["mu"]) else 1.0}
              for r in rows]
    for r in rolled:
        if (r["ratio"], r["mu"]) == (-4.0, 0.25):
            r["dissipated_power_side_persistent_friction"] = 0.001 * _ref(-4.0, 0.25)
    cells = map_cells(rolled)
    assert cells[(0.0, -4.0, 0.25)]["regime"] == "rolling bed" and cells[(0.0, -4.0, 1.0)]["regime"] == "pinned ring"
    assert cells[(0.0, -3.0, 0.05)]["regime"] == "sliding bed" and cells[(0.0, -4.0, 0.25)]["wall_lag"] == 1.0
    assert map_cells([{k: v for k, v in r.items() if k != "wall_lag"} for r in rolled])[(0.0, -4.0, 0.25)]["regime"] == "pinned ring"
    fig = regime_map(rolled, "test")
    ax = fig.axes[0]
    labels = [line.get_label() for line in ax.get_lines()]
    assert any(lab.startswith("μ_pin") for lab in labels) and any(lab.startswith("K_c") for lab in labels)
    kc = [line for line in ax.get_lines() if line.get_label().startswith("K_c")][0]
    assert kc.get_xdata()[0] == pytest.approx(critical_ratio(0.125, 0.0325, 0.006))
    mu_line = [line for line in ax.get_lines() if line.get_label().startswith("μ_pin")][0]
    k, mu = mu_line.get_xdata(), mu_line.get_ydata()
    np.testing.assert_allclose(mu, [pinning_friction(x, 0.125, 0.0325, 0.006) for x in k])
    assert ax.get_xlim()[0] > ax.get_xlim()[1]  # K falls to the right
    # --mu sets every contact's friction: the axis says so; a coated jar's sweep
    # (--pair-ball-wall, ball-ball friction fixed) names the wall only
    assert ax.get_ylabel().startswith("friction μ of every contact")
    coated = [r | {"mu": 1.0, "mu_d": 0.8} for r in rolled]
    assert regime_map(coated, "test").axes[0].get_ylabel().startswith("ball-wall friction μ")


def test_graphite_bed_rolling_in_place_is_a_rolling_bed_not_a_pinned_ring(tmp_path):
    # 6 graphite-coated balls at K = −2.2 roll in place on the wall without slipping: at
    # rest in the plate frame (wall_lag 1.00 from 1 s on in an 8 s run, 0.9999 over 4–8 s)
    # with a side-wall slip ratio of 0.012–0.015, which alone called them a pinned ring.
    # 3 s run, window 2–3 s (≈ 8 s CPU); run by the CLI, this module must not start Taichi.
    # Rolling in place is one of two states this bed reaches by 2 s, by seed: the other
    # slides on the wall (slip ratio 0.43-0.49). Seed 6 rolls in place both before and
    # after the stored-1/m change of the last bits (seed 1 did before only). Of seeds
    # 1-35, 20 rolled before and 15 after: no significant shift (Fisher's exact p = 0.34).
    import subprocess
    import sys

    from taimill.model.files import ROOT
    from taimill.model.preset import load_preset
    from taimill.runs.sweep import point_values
    from taimill.store.run import open_run
    from taimill.store.sweep import scalars

    out, preset = tmp_path / "g6.zarr", "presets/p4-cy-graphite-6.toml"
    subprocess.run([sys.executable, "-m", "taimill", "run", preset, "--ratio", "-2.2", "--duration", "3",
                    "--analysis-start", "2", "--seed", "6", "--out", str(out)], cwd=ROOT, check=True, capture_output=True, timeout=600)
    summary = open_run(out).summary
    row = point_values(load_preset(ROOT / preset, {"ratio": -2.2}), 0) | scalars(summary)  # a sweep-table row
    assert summary["regime"] == "rolling" and summary["regime_confidence"] == 1.0
    assert row["wall_lag"] == pytest.approx(1.0, abs=0.05)
    assert slip_ratio(row) < SLIDING_SLIP
    assert map_regime(row["regime"], slip_ratio(row)) == "pinned ring"  # the old rule's mistake
    assert map_regime(row["regime"], slip_ratio(row), row["wall_lag"]) == "rolling bed"
    assert map_cells([row])[(0.0, -2.2, 0.1)]["regime"] == "rolling bed"
