"""Heat (issue 48, item 2): the lumped thermal model of balls, powder and jar
(taimill.outcome.thermal) against closed forms, its energy ledger, and `taimill heat
predict` / `taimill heat fit` through the real command line.

No published ball or jar temperature with its mill, speed, media and time could be
found in the reference texts at hand (docs/outcome.md, "Heat"): the validation case
here is analytic, a jar cooling and warming as Newton's law of cooling says."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from taimill.model.materials import material_names, thermal_data
from taimill.outcome import thermal

ROOT = Path(__file__).resolve().parent.parent


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, timeout=600) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(command(*args), cwd=ROOT, capture_output=True, text=True, timeout=timeout, env=env,
                          check=False)


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines()
             if ln.strip() and not ln.startswith(("[Taichi]", "taimill: warning: ", "taimill: compiling"))]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def one_node(C=50.0, g=0.2):
    return thermal.Network(("jar",), np.array([C]), np.zeros((1, 1)), np.array([g]))


def two_nodes(C1=40.0, C2=500.0, G=0.3, L=0.1):
    return thermal.Network(("balls", "jar"), np.array([C1, C2]), np.array([[0.0, G], [G, 0.0]]), np.array([0.0, L]))


# ------------------------------------------------------------------ the model's closed forms


def test_step_response_of_one_node_is_newtons_law():
    """C dx/dt = P − g x from x = 0: x = P/g (1 − e^{−g t/C}), exact at every time."""
    C, g, P = 50.0, 0.2, 3.0
    prog = thermal.Programme(3600.0, 0.0, 3600.0)
    h = thermal.simulate(one_node(C, g), [P], prog, samples=30)
    want = P / g * (1 - np.exp(-g * h.times / C))
    assert np.allclose(h.x[:, 0], want, rtol=1e-12, atol=1e-12)


def test_step_response_of_two_nodes_matches_the_quadratic():
    """Balls (C1) tied to a jar (C2) by G, the jar losing L to the air, power P into
    the balls: the rates are the roots of λ² − (a + d) λ + (ad − bc) with the matrix
    [[a, b], [c, d]] of dx/dt, the steady state x_jar = P/L, x_balls = P/L + P/G."""
    C1, C2, G, L, P = 40.0, 500.0, 0.3, 0.1, 2.0
    a, b, c, d = -G / C1, G / C1, G / C2, -(G + L) / C2
    tr, det = a + d, a * d - b * c
    lam = np.array([(tr + math.sqrt(tr * tr - 4 * det)) / 2, (tr - math.sqrt(tr * tr - 4 * det)) / 2])
    xs = np.array([P / L + P / G, P / L])
    vecs = np.array([[b, lm - a] for lm in lam]).T  # eigenvectors of [[a, b], [c, d]]
    coef = np.linalg.solve(vecs, -xs)  # x(0) = 0
    t = np.linspace(0, 20000, 50)
    want = xs[None, :] + (vecs[None, :, :] * (coef * np.exp(np.outer(t, lam)))[:, None, :]).sum(axis=2)
    got = thermal.temperatures_at(two_nodes(C1, C2, G, L), [P, 0.0], thermal.Programme(20000, 0, 20000), t)
    assert np.allclose(got, want, rtol=1e-10, atol=1e-10)
    assert np.allclose(thermal.steady(two_nodes(C1, C2, G, L), [P, 0.0]), xs, rtol=1e-12)


def test_on_off_programme_reaches_the_closed_form_periodic_state():
    """One node, run r, pause p: the peak of the periodic state is
    x_ss (1 − e^{−r/τ}) / (1 − e^{−(r+p)/τ}); the simulated cycles converge onto it."""
    C, g, P, r, p = 50.0, 0.2, 3.0, 600.0, 300.0
    tau, xs = C / g, P / g
    peak = xs * (1 - math.exp(-r / tau)) / (1 - math.exp(-(r + p) / tau))
    prog = thermal.Programme(r, p, 40 * (r + p))
    per = thermal.periodic(one_node(C, g), [P], prog)
    assert per["end_of_run"][0] == pytest.approx(peak, rel=1e-12)
    assert per["end_of_pause"][0] == pytest.approx(peak * math.exp(-p / tau), rel=1e-12)
    h = thermal.simulate(one_node(C, g), [P], prog, samples=5)
    assert h.x[:, 0].max() == pytest.approx(peak, rel=1e-9)


def test_first_crossing_of_a_limit_is_the_closed_form_time():
    C, g, P = 50.0, 0.2, 3.0
    prog = thermal.Programme(7200.0, 0.0, 7200.0)
    limit = 0.6 * P / g
    t = thermal.first_crossing(one_node(C, g), [P], prog, 0, limit)
    assert t == pytest.approx(-C / g * math.log(1 - limit / (P / g)), rel=1e-9)
    assert thermal.first_crossing(one_node(C, g), [P], prog, 0, 1.01 * P / g) is None


@pytest.mark.parametrize("seed", range(5))
def test_energy_ledger_closes_to_1e_9(seed):
    """Heat in = stored + lost, each integrated on its own (the loss in closed form),
    over a run/pause programme of random networks, from a warm start too."""
    rng = np.random.default_rng(seed)
    n = 3
    G = np.triu(rng.uniform(0.01, 2.0, (n, n)), 1)
    net = thermal.Network(thermal.NODES, rng.uniform(1.0, 800.0, n), G + G.T, np.array([0.0, 0.0, rng.uniform(0.01, 1.0)]))
    prog = thermal.Programme(rng.uniform(60, 1800), rng.uniform(0, 900), rng.uniform(3600, 86400))
    h = thermal.simulate(net, rng.uniform(0, 10, n), prog, x0=rng.uniform(0, 20, n))
    assert h.heat_in > 0 and h.lost > 0
    assert h.residual < 1e-9


def test_from_ambient_no_cycle_exceeds_the_periodic_one():
    """The shortcut the limit check takes: started cold, every sample of a long
    programme stays at or below the periodic cycle's highest temperature."""
    rng = np.random.default_rng(7)
    G = np.triu(rng.uniform(0.01, 2.0, (3, 3)), 1)
    net = thermal.Network(thermal.NODES, rng.uniform(5.0, 800.0, 3), G + G.T, np.array([0.0, 0.0, 0.3]))
    q = rng.uniform(0, 5, 3)
    prog = thermal.Programme(600.0, 300.0, 30 * 900.0)
    top = thermal.cycle_max(net, q, prog)
    h = thermal.simulate(net, q, prog, samples=30)
    assert np.all(h.x.max(axis=0) <= top * (1 + 1e-9))
    assert np.all(h.x.max(axis=0) >= 0.99 * top)  # and reaches it after 30 cycles
    assert thermal.first_crossing(net, q, prog, 1, 1.001 * top[1]) is None
    assert thermal.first_crossing(net, q, prog, 1, 0.98 * top[1]) is not None


def test_a_network_without_a_path_to_ambient_is_refused():
    net = thermal.Network(("a",), np.array([1.0]), np.zeros((1, 1)), np.array([0.0]))
    with pytest.raises(ValueError, match="no path to ambient"):
        thermal.modes(net)


def test_heat_partition_and_correlations():
    """Blok's partition gives equal bodies half each and a steel wall most of the
    heat next to a zirconia ball; the blended jar coefficient is at least the larger of
    its two flows' and a sphere in still gas keeps Nu = 2."""
    steel, zr = thermal_data("aisi-304"), thermal_data("zirconia")
    e_s = thermal.effusivity(steel.conductivity, 8030, steel.cp)
    assert thermal.wall_share(e_s, e_s) == pytest.approx(0.5)
    assert thermal.wall_share(thermal.effusivity(zr.conductivity, 5700, zr.cp), e_s) > 0.6
    h = thermal.h_jar(0.08, 50.0, 2.6)
    assert h["h"] * 0.08 / thermal.AIR_K >= max(h["nu_spin"], h["nu_orbit"])
    assert thermal.nu_sphere(0.0) == 2.0


def test_every_catalogue_material_has_sourced_thermal_numbers():
    for name in material_names():
        t = thermal_data(name)
        assert 100 < t.cp < 2000 and 0.5 < t.conductivity < 500
        assert set(t.sources) == {"cp_J_per_kgK", "conductivity_W_per_mK"}
        assert all(len(v) > 10 for v in t.sources.values())


# ------------------------------------------------------------------ through the command line


def test_materials_shows_the_thermal_numbers_with_their_sources():
    r = taimill("materials", "zirconia")
    assert r.returncode == 0, r.stderr
    assert "c_p J/kgK" in r.stdout and "Callister" in r.stdout and "k W/mK" in r.stdout
    rows = json.loads(taimill("materials", "--json").stdout)
    agate = next(x for x in rows if x["name"] == "agate")
    assert agate["cp_J_per_kgK"] == 740 and "cp_J_per_kgK" in agate["estimates"]


@pytest.fixture(scope="module")
def run_store(tmp_path_factory):
    out = tmp_path_factory.mktemp("heat") / "run.zarr"
    r = taimill("run", "p4-cy-steel", "--duration", "1.5", "--powder-mass", "10", "--out", out)
    assert r.returncode == 0, r.stderr
    return out


def predict(run_store, *extra):
    return taimill("heat", "predict", run_store, "--powder-cp", "1200", *extra)


def test_predict_closes_the_ledger_and_warns_at_the_limit(run_store, tmp_path):
    fig = tmp_path / "heat.png"
    r = predict(run_store, "--programme", "15:5", "--hours", "4", "--ambient", "22", "--limit", "30",
                "--figure", fig, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["ledger_J"]["residual"] < 1e-9
    assert out["ledger_J"]["heat_in"] == pytest.approx(sum(out["power_W"].values()) * 3 * 3600, rel=1e-12)
    assert out["limit_reached_s"] is not None and out["limit_reached_s"] < 4 * 3600
    assert "the powder reaches the limit 30 °C" in r.stderr
    assert "jar mass" in r.stderr and "estimate" in r.stderr  # the bowl's wall is an estimate, said so
    assert out["steady_continuous_C"]["powder"] > out["periodic_peak_C"]["powder"] > 22
    assert fig.read_bytes().startswith(b"\x89PNG")
    again = predict(run_store, "--figure", fig)
    assert again.returncode == 2 and "--figure" in one_line(again.stderr)


def test_the_runs_dissipated_power_goes_where_it_is_made(run_store):
    """Every watt the run dissipated heats a body: ball–ball contacts the balls, the
    side, floor and lid shared between ball and jar by Blok's partition."""
    from taimill.store.run import open_run

    summary = open_run(run_store).summary
    by = summary["dissipation_by_mechanism"]
    wall = sum(v for k in ("side", "floor", "lid") for c in by[k].values() for v in c.values())
    out = json.loads(predict(run_store, "--json").stdout)
    assert sum(out["power_W"].values()) == pytest.approx(summary["dissipated_power"], rel=1e-9)
    assert out["power_W"]["jar"] == pytest.approx(out["wall_share"] * wall, rel=1e-12)
    b, j = thermal_data("steel-c1020"), thermal_data("aisi-304")  # C1020 balls conduct better than the 304 jar
    assert out["wall_share"] == pytest.approx(thermal.wall_share(thermal.effusivity(b.conductivity, 7850, b.cp),
                                                                 thermal.effusivity(j.conductivity, 8030, j.cp)))
    assert 0.3 < out["wall_share"] < 0.4


def test_predict_without_the_powder_cp_or_with_a_bad_programme_is_one_line(run_store):
    r = taimill("heat", "predict", run_store)
    assert r.returncode == 2 and "--powder-cp" in one_line(r.stderr)
    r = predict("summary.json")
    assert r.returncode == 2 and "a summary JSON does not hold" in one_line(r.stderr)
    for bad in ("15", "15:x", "0:5", "-3:1"):
        r = predict(run_store, "--programme", bad)
        assert r.returncode == 2 and "--programme" in one_line(r.stderr), bad


def test_fit_recovers_the_coefficient_a_prediction_was_made_with(run_store, tmp_path):
    """Measured temperatures made by the model itself at h = 12 W/(m² K): the fit
    finds 12 and its interval holds it."""
    r = predict(run_store, "--programme", "10:5", "--hours", "2", "--h-conv", "12", "--ambient", "20", "--json")
    out = json.loads(r.stdout)
    t, jar = np.array(out["time_s"]), np.array(out["temperature_C"]["jar"])
    pick = [10, 40, 90, len(t) - 1]
    csv = tmp_path / "measured.csv"
    csv.write_text("time_min,temperature_C,what\n" + "".join(f"{t[i] / 60:.10g},{jar[i]:.10g},jar\n" for i in pick))
    f = taimill("heat", "fit", run_store, "--measured", csv, "--powder-cp", "1200", "--programme", "10:5",
                "--ambient", "20", "--json")
    assert f.returncode == 0, f.stderr
    res = json.loads(f.stdout)
    assert res["value"] == pytest.approx(12.0, rel=1e-3)
    assert res["interval"][0] < 12.0 < res["interval"][1]


MALFORMED = [
    ("", "header"),
    ("when,temperature_C,what\n1,30,jar\n", "time_s|time_min|time_h"),
    ("time_s,temperature_C,what\n", "no measured temperatures"),
    ("time_s,temperature_C,what\n60,hot,jar\n", "line 2: column 2 (temperature_C) = 'hot': not a number"),
    ("time_s,temperature_C,what\n-5,30,jar\n", "line 2: column 1 (time_s) = '-5': allowed range"),
    ("time_s,temperature_C,what\n60,30,lid\n", "line 2: column 3 (what) = 'lid': one of jar, ball, powder"),
    ("time_s,temperature_C,what\n60,30\n", "line 2: line"),
    ("time_s,temperature_C,what\n60,nan,jar\n", "allowed range"),
]


@pytest.mark.parametrize("text,expected", MALFORMED)
def test_malformed_measurement_files_are_one_line(run_store, tmp_path, text, expected):
    csv = tmp_path / "m.csv"
    csv.write_text(text)
    r = taimill("heat", "fit", run_store, "--measured", csv, "--powder-cp", "1200")
    assert r.returncode == 2
    line = one_line(r.stderr)
    assert str(csv) in line and expected in line, line


def test_missing_or_binary_measurement_file_is_one_line(run_store, tmp_path):
    r = taimill("heat", "fit", run_store, "--measured", tmp_path / "none.csv", "--powder-cp", "1200")
    assert r.returncode == 2 and "--measured" in one_line(r.stderr)
    bad = tmp_path / "bin.csv"
    bad.write_bytes(b"\xff\xfe\x00time")
    r = taimill("heat", "fit", run_store, "--measured", bad, "--powder-cp", "1200")
    assert r.returncode == 2 and "UTF-8" in one_line(r.stderr)


def test_sigterm_during_a_long_prediction_leaves_nothing(run_store, tmp_path):
    """SIGTERM while a long programme is computed: exit 143 in one line, and neither the
    figure nor a part of it is left to block the rerun."""
    import signal
    import time

    fig = tmp_path / "long.png"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen(command("heat", "predict", run_store, "--powder-cp", "1200", "--programme", "0.5:0.5",
                                 "--hours", "1000", "--limit", "1000", "--figure", fig),
                         cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    time.sleep(2.5)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143, err
    assert "SIGTERM" in one_line(err)
    assert list(tmp_path.iterdir()) == []
