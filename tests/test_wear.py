"""Wear as mass (docs/wear.md): Archard's volume on the engine's friction work, the
hardness in the material table, and `taimill wear fit` / `taimill wear predict`
through the real CLI, with one-line errors for malformed measurement files."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import steel

ROOT = Path(__file__).resolve().parent.parent
G = 9.81


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(command(*args), cwd=cwd, capture_output=True, text=True, timeout=600, check=False,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines()
             if ln.strip() and not ln.startswith(("[Taichi]", "taimill: warning: ", "taimill: compiling"))]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def test_a_ball_sliding_on_the_floor_wears_archards_volume():
    # One steel ball resting on the floor (Hertz overlap δ of its weight: F_n = m g) set
    # sliding at s0 without spin, μ constant above the regularisation speed. Rigid-body
    # theory: friction decelerates the centre and spins the ball up about its contact
    # point's lever r_c = r − δ/2 (centre to mid-overlap), so the slip falls as s0 − a t,
    # a = μ g (1 + m r_c²/I) = μ g (1 + 2.5 (r_c/r)²) (3.5 μ g for r_c = r), and the
    # friction work is W(t) = F_n μ ∫ slip dt = μ m g (s0 t − a t²/2). The ledger's
    # friction work of the floor between two rows matches it to 10⁻⁹ (measured 5·10⁻¹³;
    # a ledger row stamped t holds the step that starts at t, hence t + dt; with r_c = r
    # the theory is off by 9·10⁻⁷, the lever's δ/r), and the wear model turns it into
    # Archard's volume k W / H for the ball and the floor to 10⁻⁶.
    from taimill.analysis.summary import mechanism_powers
    from taimill.calibration.runs import impact_spec
    from taimill.model.materials import Friction
    from taimill.outcome.wear import HV_PA, Body, WearCondition, archard_volume, volume_rates
    from taimill.physics.runner import Runner
    from taimill.schema import MECHANISM_COLUMNS
    from taimill.store.sinks import MemorySink

    ball, jar, bb, bw, _ = steel()
    mu, s0, dt, T = 0.2, 1.0, 2e-6, 0.05
    z0 = ball.radius - (ball.mass * G / bw.k) ** (2 / 3)
    spec = impact_spec(ball, jar, bb, bw, Friction("t", mu, mu, 1e-3, 1e-2), [[0, 0, z0]], [[s0, 0, 0]],
                       gravity=G, dt=dt, steps=int(round(T / dt)))
    sink = MemorySink()
    Runner([spec.replace(frame_every=int(1e-3 / dt))]).run([sink])
    e = sink.energy_table
    a, b = 5, len(e["time"]) - 1
    tau = e["time"][b] - e["time"][a]
    powers = mechanism_powers(np.array([(e[c][b] - e[c][a]) / tau for c in MECHANISM_COLUMNS]))
    floor = powers["dissipation_by_mechanism"]["floor"]
    work = (floor["impact"]["friction"] + floor["persistent"]["friction"]) * tau

    r_c = ball.radius - (ball.radius - z0) / 2
    decel = mu * G * (1 + 2.5 * (r_c / ball.radius) ** 2)

    def theory(t):
        t = t + dt
        return mu * ball.mass * G * (s0 * t - decel * t ** 2 / 2)

    expected = theory(e["time"][b]) - theory(e["time"][a])
    assert work == pytest.approx(expected, rel=1e-9)
    assert floor["impact"]["normal"] + floor["persistent"]["normal"] == pytest.approx(0.0, abs=1e-9 * work / tau)

    k, hv_ball, hv_wall = 3e-4, 126.0, 210.0
    cond = WearCondition("slide", {"ball_ball": 0.0, "side": 0.0, "floor": work / tau, "lid": 0.0},
                         {"ball_ball": 0.0, "side": 0.0, "floor": 0.0, "lid": 0.0}, 0.0,
                         Body("steel-c1020", 7850.0, hv_ball), Body("aisi-304", 8030.0, hv_wall), 2.1)
    rates = volume_rates(cond, k)
    assert rates["floor"] * tau == pytest.approx(k * expected / (hv_wall * HV_PA), rel=1e-6)
    assert rates["balls"] * tau == pytest.approx(k * expected / (hv_ball * HV_PA), rel=1e-6)
    assert rates["side"] == rates["lid"] == 0.0
    assert archard_volume(expected, k, hv_wall * HV_PA) == pytest.approx(k * expected / (hv_wall * HV_PA), rel=1e-12)


def test_ball_ball_contacts_wear_two_ball_surfaces_and_contamination_is_a_fraction_of_the_powder():
    from taimill.outcome.wear import HV_PA, Body, WearCondition, contamination, mass_rates

    steel_ = Body("s", 8000.0, 200.0)
    cond = WearCondition("c", {"ball_ball": 1.0, "side": 0.0, "floor": 0.0, "lid": 0.0}, None, 0.0, steel_, steel_, 2.0)
    g_per_h = mass_rates(cond, 1e-4)["balls"]
    assert g_per_h == pytest.approx(2 * 1e-4 * 1.0 / (200 * HV_PA) * 8000 * 1e3 * 3600, rel=1e-12)
    c = contamination(cond, 1e-4, 0.0, [0.0, 3600.0])
    assert c[0] == 0.0 and c[1] == pytest.approx(g_per_h / (g_per_h + 2.0), rel=1e-12)


def test_every_material_states_its_hardness_with_a_source_or_says_it_has_none():
    from taimill.model.materials import material_data, material_names

    for name in material_names():
        d = material_data(name)
        if math.isnan(d.hardness_hv):
            assert name == "agate"  # no Vickers figure found (Mohs 6.5-7 only): not invented
            continue
        assert 100 <= d.hardness_hv <= 3000, name
        assert d.sources["hardness_hv"], name
    assert material_data("steel-c1020").hardness_hv == 126.0
    assert "hardness_hv" in material_data("aisi-304").estimates()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two short HM fluorite runs with powder (K = −1.0 and −2.6) and a measured CSV."""
    d = tmp_path_factory.mktemp("wear")
    for k in ("1.0", "2.6"):
        res = taimill("run", "p4-hm-fluorite", f"--ratio=-{k}", "--duration", "1.4", "--analysis-start", "0.4",
                      "--powder-mass", "2.1", "--out", d / f"hm-{k}.zarr")
        assert res.returncode == 0, res.stderr
    return d


def test_fit_and_predict_through_the_cli(runs):
    (runs / "measured.csv").write_text("# made-up contamination of the two runs\n"
                                       "condition,time_h,contamination_pct\n"
                                       "hm-1.0.zarr,1,0.3\nhm-1.0.zarr,16,4.1\nhm-2.6.zarr,16,3.0\nhm-2.6.zarr,64,11\n")
    res = taimill("wear", "fit", runs / "measured.csv", "--out", runs / "fit.toml", "--json")
    assert res.returncode == 0, res.stderr
    fit = json.loads(res.stdout)
    k = fit["params"]["k_friction"]
    lo, hi = fit["intervals"]["k_friction"]
    assert 0 < lo < k < hi and fit["fixed"] == {"k_impact": 0.0}
    assert (runs / "fit.toml").read_text().startswith("# taimill wear fit")

    res = taimill("wear", "predict", runs / "hm-1.0.zarr", runs / "hm-2.6.zarr", "--fit", runs / "fit.toml",
                  "--hours", "1", "32", "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    for r in out["runs"]:
        c = r["contamination"]
        assert c["percent"][0] < c["percent"][1]  # grows with milling time
        assert c["lower_percent"][1] < c["percent"][1] < c["upper_percent"][1]
        assert set(r["worn_g_per_h"]) == {"balls", "side", "floor", "lid"}
        assert r["worn_g_per_h_total"] == pytest.approx(sum(r["worn_g_per_h"].values()))
        assert set(r["wall_depth"]) == {"side", "floor", "lid"}
    # the same k given directly predicts the same, without a band
    direct = taimill("wear", "predict", runs / "hm-1.0.zarr", "--k-friction", k, "--hours", "1", "32", "--json")
    assert direct.returncode == 0, direct.stderr
    same = json.loads(direct.stdout)["runs"][0]["contamination"]
    assert same["percent"] == pytest.approx(out["runs"][0]["contamination"]["percent"], rel=1e-9)
    assert "lower_percent" not in same
    # the depth map of one run, drawn; of two runs refused in one line before anything is drawn
    res = taimill("wear", "predict", runs / "hm-1.0.zarr", "--fit", runs / "fit.toml", "--map", runs / "map.png",
                  "--figure", runs / "curves.svg")
    assert res.returncode == 0, res.stderr
    assert (runs / "map.png").read_bytes()[:4] == b"\x89PNG" and (runs / "curves.svg").stat().st_size > 0
    res = taimill("wear", "predict", runs / "hm-1.0.zarr", runs / "hm-2.6.zarr", "--fit", runs / "fit.toml",
                  "--map", runs / "two.png")
    assert res.returncode == 2 and "--map" in one_line(res.stderr) and not (runs / "two.png").exists()


def test_the_run_summary_carries_wear_per_unit_k_for_sweeps_and_the_designer(runs):
    # The summary key is the friction route of `taimill wear predict` at k = 1, so a sweep
    # table has it as a column and the designer can minimise it (at a floor on impact power).
    from taimill.design.protocol import parse_floor, parse_objective
    from taimill.store.run import open_run

    summary = open_run(runs / "hm-1.0.zarr").summary
    assert summary["units"]["wear_friction_g_per_h_per_k"] == "g/h"
    res = taimill("wear", "predict", runs / "hm-1.0.zarr", "--k-friction", "1", "--json")
    assert res.returncode == 0, res.stderr
    total = json.loads(res.stdout)["runs"][0]["worn_g_per_h_total"]
    assert summary["wear_friction_g_per_h_per_k"] == pytest.approx(total, rel=1e-9)
    assert summary["contamination_friction_per_h_per_k"] == pytest.approx(total / 2.1, rel=1e-9)
    assert summary["wear_impact_g_per_h_per_k"] > 0
    assert parse_objective("wear_friction_g_per_h_per_k:min").key == "wear_friction_g_per_h_per_k"
    assert parse_floor("impact_power=2.5") == ("impact_power", 2.5)


HEAD = "condition,time_h,contamination_pct\n"
BAD_MEASURED = {  # name -> (CSV text, words of the one line)
    "no time column": ("condition,contamination_pct\nhm-1.0.zarr,1\n", [":1", "header", "time_h"]),
    "two time columns": ("condition,time_h,time_s,contamination_pct\nhm-1.0.zarr,1,3600,1\n", [":1", "header"]),
    "unknown column": ("condition,time_h,contamination_pct,sigma\nhm-1.0.zarr,1,1,0.1\n", [":1", "column 4", "sigma"]),
    "percent above 100": (HEAD + "hm-1.0.zarr,1,120\n", [":2", "column 3 (contamination_pct)", "120", "[0, 100)"]),
    "percent as a fraction": ("condition,time_h,contamination_fraction\nhm-1.0.zarr,1,15\n",
                              [":2", "column 3 (contamination_fraction)", "15", "percent"]),
    "negative time": (HEAD + "hm-1.0.zarr,1,1\nhm-1.0.zarr,-2,1\n", [":3", "column 2 (time_h)", "-2", "≥ 0"]),
    "text time": (HEAD + "hm-1.0.zarr,soon,1\n", [":2", "column 2 (time_h)", "soon"]),
    "missing field": (HEAD + "hm-1.0.zarr,1\n", [":2", "fields"]),
    "empty condition": (HEAD + ",1,1\n", [":2", "column 1 (condition)"]),
    "not a run store": (HEAD + "nowhere.zarr,1,1\nhm-1.0.zarr,2,2\n", ["nowhere.zarr"]),
    "no measurements": (HEAD, ["measured.csv", "no measurements"]),
}


@pytest.mark.parametrize("name", BAD_MEASURED)
def test_a_malformed_measurement_file_is_one_line_naming_file_line_and_column(runs, name):
    text, words = BAD_MEASURED[name]
    folder = runs / f"bad-{name.replace(' ', '-')}"
    folder.mkdir(exist_ok=True)
    os.symlink(runs / "hm-1.0.zarr", folder / "hm-1.0.zarr") if not (folder / "hm-1.0.zarr").exists() else None
    (folder / "measured.csv").write_text(text)
    res = taimill("wear", "fit", folder / "measured.csv", "--out", folder / "fit.toml")
    line = one_line(res.stderr)
    assert res.returncode == 2 and line.startswith("taimill: error: ") and "measured.csv" in line, line
    for w in words:
        assert w in line, (w, line)
    assert not (folder / "fit.toml").exists()


def test_predict_refuses_a_run_without_powder_and_a_missing_coefficient(runs, tmp_path):
    res = taimill("run", "p4-hm-fluorite", "--duration", "0.5", "--out", tmp_path / "dry.zarr")
    assert res.returncode == 0, res.stderr
    res = taimill("wear", "predict", tmp_path / "dry.zarr", "--k-friction", "1e-4")
    assert res.returncode == 2 and "--powder-mass" in one_line(res.stderr)
    res = taimill("wear", "predict", runs / "hm-1.0.zarr")
    assert res.returncode == 2 and "--k-friction" in one_line(res.stderr)


def test_fit_outputs_replace_only_taimills_own_file_and_never_an_input(runs):
    folder = runs / "outputs"
    folder.mkdir(exist_ok=True)
    csv_text = "condition,time_h,contamination_pct\n../hm-1.0.zarr,1,0.3\n../hm-1.0.zarr,16,4.1\n"
    (folder / "measured.csv").write_text(csv_text)
    (folder / "notes.toml").write_text("# the user's own notes\n")
    res = taimill("wear", "fit", folder / "measured.csv", "--out", folder / "notes.toml", "--overwrite")
    assert res.returncode == 2 and "--out" in one_line(res.stderr)
    assert (folder / "notes.toml").read_text() == "# the user's own notes\n"
    res = taimill("wear", "fit", folder / "measured.csv", "--out", folder / "measured.csv", "--overwrite")
    assert res.returncode == 2 and "--out" in one_line(res.stderr)
    assert (folder / "measured.csv").read_text() == csv_text
    assert taimill("wear", "fit", folder / "measured.csv", "--out", folder / "fit.toml").returncode == 0
    res = taimill("wear", "fit", folder / "measured.csv", "--out", folder / "fit.toml")
    assert res.returncode == 2 and "--overwrite" in one_line(res.stderr)
    assert taimill("wear", "fit", folder / "measured.csv", "--out", folder / "fit.toml", "--overwrite").returncode == 0
    assert sorted(p.name for p in folder.iterdir()) == ["fit.toml", "measured.csv", "notes.toml"]
