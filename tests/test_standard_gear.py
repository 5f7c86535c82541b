"""Standard-gear mills (gear 1:−2, K = −1: PM 100, P 7, PM 400) as they are: a crescent
that hops in place is a hopping bed, not cataracting (docs/regimes.md); a charge whose
power friction takes is said to be friction-led, its dissipated power first; a bed's
class holds over seeds and its start dependence is said; the sweep shows the dissipated
power beside the impact power and names the friction-led points.

The criteria below are those measured on the runs docs/regimes.md lists (5 s runs,
window 2–5 s; the PM 100 zirconia run 4 s, window 2–4 s)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from taimill.analysis.regime import (CATARACT_CHORD, SLIDING_SLIP, class_note, classify, hopping, map_regime)
from taimill.analysis.summary import FRICTION_LED, power_lead

ROOT = Path(__file__).resolve().parent.parent
PM100 = ["--mill", "retsch-pm100", "--jar-volume", "80", "--jar-material", "zirconia", "--ball-material", "zirconia",
         "--ball-diameter", "5", "--balls", "25", "--plate-rpm", "400"]

# (wall_fraction, flight_fraction, impact_chord, wall_lag) -> (regime, class)
MEASURED = {
    "PM 100 zirconia, 400 rpm": ((0.036, 0.905, 0.091, 0.911), ("cascading", "hopping bed")),
    "CY steel K = -1.0": ((0.180, 0.513, 0.282, 0.754), ("cascading", "cascading")),
    "CY steel K = -1.4": ((0.143, 0.567, 0.354, 0.752), ("cataracting", "cataracting")),
    "CY steel K = -2.6": ((0.049, 0.786, 0.547, 0.552), ("cataracting", "cataracting")),
    "HM steel K = -2.2": ((0.117, 0.678, 0.579, 0.117), ("cataracting", "cataracting")),
}


@pytest.mark.parametrize("case", sorted(MEASURED))
def test_a_hop_in_place_is_not_a_flight_and_the_p4_regimes_stay(case):
    (wall, flight, chord, lag), (regime, label) = MEASURED[case]
    assert classify(wall, flight, math.nan, chord) == regime
    assert map_regime(regime, 0.0, lag, flight, chord) == label
    # by flight fraction alone (no chord: stores written before it) every one of them flew
    assert classify(wall, flight) == ("cataracting" if flight >= 0.55 else "cascading")


def test_the_chord_threshold_lies_between_hopping_and_thrown_balls():
    assert 0.091 < CATARACT_CHORD < 0.282
    assert hopping(0.905, 0.091) and not hopping(0.905, 0.282) and not hopping(0.5, 0.05)
    assert not hopping(0.905, math.nan)  # no repeated impacts: not taken as hopping


@pytest.mark.parametrize("slip", [0.0964, 0.22, 0.59, 0.62])
def test_the_pm100_powder_beds_of_seeds_1_to_4_are_one_class(slip):
    # slip ratios of seeds 4, 3, 1, 2 (6 s, window 2–6 s); the old threshold 0.1 split them
    assert map_regime("rolling", slip, 1.0) == "sliding bed" and class_note("sliding bed", {}, slip) is None
    assert map_regime("rolling", 0.015, 1.0) == "rolling bed"  # graphite-6 rolling in place
    assert 0.015 < SLIDING_SLIP < 0.074


def test_a_class_near_its_threshold_says_so():
    note = class_note("sliding bed", {}, 1.2 * SLIDING_SLIP)
    assert note and "slip ratio" in note and "rolling bed" in note
    note = class_note("hopping bed", {"flight_fraction": 0.9, "impact_chord": 1.1 * CATARACT_CHORD}, 0.0)
    assert note and "impact chord" in note and "cataracting" in note
    assert class_note("cataracting", {"flight_fraction": 0.786, "impact_chord": 0.547}, 0.0) is None
    assert "flight fraction" in class_note("cataracting", {"flight_fraction": 0.567, "impact_chord": 0.354}, 0.0)


@pytest.mark.parametrize("share, led", [(0.976, "friction-led"), (1.0, "friction-led"), (0.94, "friction-led"),
                                        (0.901, "friction-led"), (0.886, "impact-led"), (0.789, "impact-led"),
                                        (0.649, "impact-led")])
def test_what_carries_the_power(share, led):
    # measured friction shares: PM 100 zirconia, beds, P 7 at 300 rpm, CY K = −1.0;
    # CY K = −1.4 and −2.6, HM −2.2 (taimill.analysis.summary.FRICTION_LED)
    got = power_lead({"dissipated_power": 2.0, "dissipated_power_friction": 2.0 * share})
    assert got["power_led"] == led and got["friction_share"] == pytest.approx(share)
    assert FRICTION_LED == 0.9


def test_no_dissipation_leads_nothing_and_rounding_stays_a_share():
    assert power_lead({"dissipated_power": 0.0, "dissipated_power_friction": 0.0})["power_led"] is None
    assert power_lead({"dissipated_power": 1.0, "dissipated_power_friction": 1.0 + 1e-12})["friction_share"] == 1.0


def test_a_friction_led_summary_leads_with_the_dissipated_power():
    from taimill.cli.common import summary_table

    s = {"events": 100, "impact_power": 3.9, "dissipated_power": 0.92, "dissipated_power_friction": 0.9,
         "friction_share": 0.976, "power_led": "friction-led", "regime": "cascading", "regime_class": "hopping bed"}
    text = summary_table(s)
    assert text.startswith("friction-led: friction takes 97.6% of the 0.92 W dissipated")
    assert text.index("dissipated power, one jar") < text.index("impact power E_I/τ")
    s |= {"friction_share": 0.79, "power_led": "impact-led"}
    text = summary_table(s)
    assert text.startswith("impact-led") and text.index("impact power E_I/τ") < text.index("dissipated power, one jar")


def test_a_bed_summary_recommends_replicas():
    from taimill.cli.common import summary_table

    base = {"events": 0, "dissipated_power": 0.5, "friction_share": 1.0, "power_led": "friction-led"}
    assert "replicas" in summary_table(base | {"regime_class": "sliding bed"})
    assert "replicas" not in summary_table(base | {"regime_class": "hopping bed"})


def _rows(values):
    return [{"point": i, "plate_rpm": rpm, "replica": rep, "dissipated_power": p, "power_led": led,
             "regime_class": cls} for i, (rpm, rep, p, led, cls) in enumerate(values)]


def test_the_sweep_names_friction_led_points_and_spread_replicas():
    from taimill.analysis.sweep import sweep_axes
    from taimill.cli.sweep import columns_of, friction_led_line, spread_line

    rows = _rows([(300, 0, 0.66, "impact-led", "rolling bed"), (300, 1, 0.67, "impact-led", "rolling bed"),
                  (1100, 0, 28.0, "friction-led", "sliding bed"), (1100, 1, 20.0, "friction-led", "sliding bed")])
    assert friction_led_line(rows).startswith("\nfriction-led: points 2, 3")
    axes = sweep_axes(columns_of(rows))
    line = spread_line(rows, axes)
    assert "1100: 20–28 W" in line and "300" not in line.split("spreads")[1]
    single = _rows([(300, 0, 0.66, "impact-led", "rolling bed"), (700, 0, 7.8, "friction-led", "hopping bed")])
    assert "beds at 300" in spread_line(single, sweep_axes(columns_of(single)))


def _taimill(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def test_the_pm100_zirconia_crescent_is_a_friction_led_hopping_bed(tmp_path):
    # the measured zirconia contact set, 2.5 s, window 1.5–2.5 s (≈ 3 s CPU): the crescent
    # hops in place (impact chord 0.085, flight fraction 0.90) and friction takes 97 %
    out = tmp_path / "pm100.zarr"
    res = _taimill("run", *PM100, "--pair", "zirconia-zirconia", "--duration", 2.5, "--analysis-start", 1.5, "--json",
                   "--out", out)
    assert res.returncode == 0, res.stderr
    s = json.loads(res.stdout)
    assert s["regime_class"] == "hopping bed" and s["regime"] != "cataracting"
    assert s["regime_criteria"]["impact_chord"] < CATARACT_CHORD < 0.2 and s["regime_criteria"]["flight_fraction"] > 0.8
    assert s["power_led"] == "friction-led" and s["friction_share"] > 0.95
    told = _taimill("analyse", out)  # the analysis of the store leads the same way
    assert told.returncode == 0 and told.stdout.splitlines()[1].startswith("friction-led: friction takes 9")


def test_the_p7_sweep_shows_dissipated_beside_impact_power_and_says_friction_led(tmp_path):
    # the P 7 premium line, 45 ml silicon nitride bowl, 15 × 10 mm silicon nitride balls,
    # the powder set, at its lowest and highest speeds (2.5 s per point, ≈ 15 s CPU):
    # impact power 15 W at 300 rpm, none at 1100 rpm while the dissipated power is 28 W
    out = tmp_path / "p7.zarr"
    res = _taimill("sweep", "--mill", "fritsch-p7-premium", "--jar-volume", 45, "--jar-material", "silicon-nitride",
                   "--ball-material", "silicon-nitride", "--ball-diameter", 10, "--balls", 15, "--pair", "dry-ceramic-powder",
                   "--plate-rpm", "300,1100", "--duration", 2.5, "--analysis-start", 1.5, "--out", out)
    assert res.returncode == 0, res.stderr
    head, *lines = res.stdout.splitlines()[1:]
    assert "P_I W" in head and "P_diss W" in head and "friction" in head
    led = next(line for line in lines if line.startswith("friction-led:"))
    assert "every point" in led or "point 1" in led  # 1100 rpm (300 rpm: a bed, friction 94 %)
    from taimill.analysis.sweep import sweep_axes
    from taimill.figures.sweep import FIGURES, friction_led_text
    from taimill.store.sweep import open_sweep

    table = open_sweep(out).table()
    at = {float(rpm): i for i, rpm in enumerate(table["plate_rpm"])}
    fast, slow = at[1100.0], at[300.0]
    assert table["power_led"][fast] == "friction-led" and table["impact_power"][fast] < 0.1 * table["impact_power"][slow]
    assert table["dissipated_power"][fast] > 10 * table["dissipated_power"][slow]
    said = friction_led_text(table, sweep_axes(table))  # the figures' titles
    assert "friction-led at every point" in said or ("friction-led at" in said and "1100" in said)
    panels = dict((f[0], f[2]) for f in FIGURES)["impact_power"]
    assert [c for c, _ in panels] == ["impact_power", "dissipated_power"]
    figs = tmp_path / "figs"
    res = _taimill("report", out, "--out", figs)
    assert res.returncode == 0, res.stderr
    assert (figs / "impact_power.png").exists()


def test_the_pm100_powder_bed_of_seed_4_is_a_sliding_bed_like_seeds_1_to_3():
    # the seed whose slip ratio (0.096) the old threshold 0.1 called a rolling bed; its
    # bed is frozen by 2 s (2.5 s, window 2–2.5 s: the same slip ratio as over 2–6 s;
    # ≈ 17 s CPU). All four seeds end to end: the `full` test below
    res = _taimill("run", *PM100, "--pair", "dry-ceramic-powder", "--duration", 2.5, "--analysis-start", 2, "--seed", 4,
                   "--json")
    assert res.returncode == 0, res.stderr
    s = json.loads(res.stdout)
    assert s["regime_class"] == "sliding bed" and s["regime_class_note"] is None
    assert s["slip_ratio"] == pytest.approx(0.096, abs=0.01)
    assert s["power_led"] == "friction-led" and s["events"] == 0


@pytest.mark.full
def test_the_pm100_powder_bed_keeps_one_class_over_seeds_1_to_4():
    # the walkthrough's run (6 s, window 2–6 s) from seeds 1–4: ≈ 5 min CPU
    res = _taimill("sweep", *PM100, "--pair", "dry-ceramic-powder", "--duration", 6, "--analysis-start", 2,
                   "--replicas", 4, "--seed", 1, "--json", timeout=3600)
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)
    assert len(rows) == 4 and {r["regime_class"] for r in rows} == {"sliding bed"}
    assert all(r["power_led"] == "friction-led" and r["events"] == 0 for r in rows)


def test_power_per_gram_is_where_users_look_sweep_table_figure_and_analyse(tmp_path):
    # it was in run's summary and sweep --json only; sweep had no --powder-mass
    # (2 points of 1.5 s, ≈ 6 s CPU, then a run of 1.5 s)
    out = tmp_path / "s.zarr"
    res = _taimill("sweep", *PM100[:-2], "--plate-rpm", "300,500", "--pair", "zirconia-zirconia", "--duration", 1.5,
                   "--analysis-start", 1, "--powder-mass", 10, "--out", out)
    assert res.returncode == 0, res.stderr
    head = res.stdout.splitlines()[1]
    assert "P_diss/g W/g" in head
    from taimill.store.sweep import open_sweep

    table = open_sweep(out).table()
    assert table["specific_power_W_per_g"] == pytest.approx(table["dissipated_power"] / 10.0)
    figs = tmp_path / "figs"
    assert _taimill("report", out, "--out", figs).returncode == 0 and (figs / "specific_power.png").exists()
    run = tmp_path / "r.zarr"
    assert _taimill("run", *PM100, "--pair", "zirconia-zirconia", "--duration", 1.5, "--analysis-start", 1,
                    "--powder-mass", 10, "--out", run).returncode == 0
    text = _taimill("analyse", run).stdout
    assert "per g of powder (10 g): dissipated" in text
    q = json.loads(_taimill("analyse", run, "--json").stdout)
    assert q["specific_power_W_per_g"] == pytest.approx(q["dissipated_power"] / 10.0)
    assert q["units"]["specific_power_W_per_g"] == "W/g"
