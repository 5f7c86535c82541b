"""Prediction bands of `taimill kinetics predict` that one can bet on (docs/outcome.md,
prediction bands): where the data leave a parameter loose the band holds what the
profile allows, up to "never"; a flat JᵀJ never gives a zero-width band; the
simulation's own scatter (counting, or a sweep point's replicas) widens the band; the
fit's warnings are repeated by every prediction. No simulation: conditions are built
from synthetic event rows as in tests/test_outcome.py, and each profile is checked
against a brute-force one (E* on a grid, κ refitted at each)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import optimize, stats

from inprocess import main
from taimill.outcome import fit as fitting, predict
from taimill.outcome.condition import Condition, write_file
from taimill.outcome.files import read_points
from taimill.outcome.models import CriticalCollisions
from test_outcome import A, A_SCALED, B, C, MEASURE, TRUTH, condition, measured, write_points

ROOT = Path(__file__).resolve().parent.parent
MODEL = CriticalCollisions(MEASURE)
A_NEAR = condition("A-near", 1.5e-3, 0.45, 1500.0)  #: A's spectrum a little shifted and narrowed: nearly its shape
NARROW = condition("N", 1e-3, 0.1, 2000.0)  #: no event above 3.2 mJ: below the true E* of 5 mJ


def quick(*args, cwd) -> SimpleNamespace:
    """The CLI in this process (inprocess.main), with the paths taken from `cwd`."""
    here = os.getcwd()
    os.chdir(cwd)
    try:
        code, out, err = main(*args)
    finally:
        os.chdir(here)
    return SimpleNamespace(returncode=code, stdout=out, stderr=err)


def taimill(*args, cwd) -> subprocess.CompletedProcess:
    """The real CLI in a subprocess."""
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          timeout=300, check=False, env={**os.environ, "PYTHONPATH": str(ROOT)})


def profile_range(conds: dict, pts: fitting.Points, target, level: float = 0.95) -> tuple[float, float]:
    """(min, max) of the time to α = 0.9 at `target` along E*'s profile, by brute force:
    log10 E* on a grid of 60 points a decade, log10 κ_g refitted at each (a bounded 1-D
    search), the grid points whose best S stays within χ²₁(level) of the best of all."""
    groups = {c: np.asarray(pts.condition) == c for c in conds}

    def s(log_e, log_k):
        p = {"kappa_g": 10.0 ** log_k, "e_star_J": 10.0 ** log_e}
        r = np.concatenate([(MODEL.value(p, conds[c], pts.time[g]) - pts.value[g]) / pts.sigma[g] for c, g in groups.items()])
        return float(r @ r)

    rows = []
    for log_e in np.arange(-5.0, 0.0, 1 / 60):
        best = optimize.minimize_scalar(lambda k, e=log_e: s(e, k), bounds=(-12.0, 8.0), method="bounded",
                                        options={"xatol": 1e-7})
        rows.append((best.fun, log_e, best.x))
    s_min = min(r[0] for r in rows)
    times = [MODEL.time_to({"kappa_g": 10.0 ** k, "e_star_J": 10.0 ** e}, target, 0.9)
             for f, e, k in rows if f - s_min <= stats.chi2.ppf(level, 1)]
    times = [t if math.isfinite(t) else math.inf for t in times]
    return min(times), max(times)


def contains(band: tuple[float, float], inner: tuple[float, float], rel: float = 0.02) -> bool:
    """Whether `band` holds `inner`, up to `rel` (the brute-force grid against the fit's
    crossing of Δ); an infinite end is held only by an infinite one."""
    lo, hi = band
    return lo <= inner[0] * (1 + rel) and (hi == math.inf if inner[1] == math.inf else hi >= inner[1] * (1 - rel))


# ------------------------------------------------------------------ the two cases
def test_near_identical_spectra_give_a_band_that_holds_the_profile_range():
    """Two conditions of nearly one shape leave E* loose: the time at a third condition
    runs over an order of magnitude along E*'s profile, and the band must hold all of it
    (the best fit's covariance gave [191, 526] s against a profile from 37 s)."""
    pts = measured(MODEL, TRUTH, (A, A_NEAR), 0)
    conds = {"A": A, "A-near": A_NEAR}
    f = fitting.fit(MODEL, conds, pts)
    t, lo, hi = predict.time_to(f, C, 0.9)
    inner = profile_range(conds, pts, C)
    assert inner[1] / inner[0] > 10  # the case is what it says: a loose parameter
    assert lo <= t <= hi
    assert contains((lo, hi), inner), ((lo, hi), inner)


def test_a_threshold_above_one_conditions_events_gives_a_band_up_to_never(tmp_path):
    """True E* above every event of one condition (it never converts) and one condition
    that does: along E*'s profile the time at a third condition runs to never, which the
    band must say (the best fit's covariance gave [95, 113] s), in the table and in JSON."""
    for c in (NARROW, B, C):
        write_file(tmp_path / f"{c.name}.json", c.spectra, c.powder_g, "SYNTHETIC test condition")
    rng = np.random.default_rng(0)
    t = MODEL.time_to(TRUTH, B, 0.9) * np.array((0.05, 0.1, 0.2, 0.4, 0.7, 1.0, 1.5))
    names = ["N"] * len(t) + ["B"] * len(t)
    y = np.concatenate([MODEL.value(TRUTH, c, t) + rng.normal(0.0, 0.03, len(t)) for c in (NARROW, B)])
    write_points(tmp_path / "p.csv", fitting.Points(names, np.concatenate([t, t]), y, np.full(len(y), 0.03)))
    res = quick("kinetics", "fit", "p.csv", "--out", "fit.toml", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    res = quick("kinetics", "predict", "fit.toml", "C.json", "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    row = json.loads(res.stdout)["conditions"][0]
    pts = read_points(tmp_path / "p.csv")
    inner = profile_range({"N.json": NARROW, "B.json": B}, pts, C)
    assert inner[1] == math.inf and math.isfinite(inner[0])  # the profile runs to never
    assert row["never_in_band"] is True and row["upper_s"] is None  # JSON: ∞ is null, said by never_in_band
    assert contains((row["lower_s"], math.inf), inner), (row, inner)
    table = quick("kinetics", "predict", "fit.toml", "C.json", cwd=tmp_path).stdout
    assert "never]" in table, table


def test_a_flat_jacobian_never_gives_a_zero_width_band():
    """Points all at t = 0 tell nothing about κ_g or E* (α(0) = 0 whatever they are): JᵀJ
    is zero, and its pseudo-inverse, the covariance, too. The fit lists the flat
    directions; the band is unbounded, also without the profiles, and also from a fit
    file of an older taimill (a zero covariance and nothing else)."""
    pts = fitting.Points(["A"] * 3 + ["B"] * 3, np.zeros(6), np.array([0.01, -0.01, 0.0, 0.02, 0.0, -0.02]),
                         np.full(6, 0.03))
    f = fitting.fit(MODEL, {"A": A, "B": B}, pts)
    assert not np.any(f.covariance) and len(f.flat_directions) == 2
    linearised = dataclasses.replace(f, profiles={})
    older = dataclasses.replace(f, profiles={}, flat_directions=[])
    for g in (f, linearised, older):
        t, lo, hi = predict.time_to(g, C, 0.9)
        assert lo == 0.0 and hi == math.inf, (t, lo, hi)
        y, ylo, yhi = predict.curve(g, C, [60.0, 600.0])
        assert np.all(ylo == 0.0) and np.all(yhi == 1.0), (y, ylo, yhi)


def test_a_flat_direction_leaves_a_prediction_along_the_fitted_combination_bounded():
    # spectra of one shape fix κ_g ṅ(E*) at the measured conditions: a prediction there
    # moves only along that combination and keeps a finite band
    f = fitting.fit(MODEL, {"A": A, "A-scaled": A_SCALED}, measured(MODEL, TRUTH, (A, A_SCALED), 0))
    t, lo, hi = predict.time_to(f, A, 0.9)
    assert 0 < lo < t < hi < math.inf
    assert hi / lo < 3


# ------------------------------------------------------------------ the simulation's own scatter
def test_the_band_is_at_least_the_counting_error_of_the_condition():
    """A condition whose window holds few events above E* (about 160): its rate's
    Poisson error (1/√N ≈ 8 %) widens the band even where the parameters are fixed to
    a per cent (σ = 0.003)."""
    few = condition("few", 4e-3, 0.45, 1000.0, n=400)
    f = fitting.fit(MODEL, {"A": A, "B": B}, measured(MODEL, TRUTH, (A, B), 0, sigma=0.003))
    delta = predict.counting_error(f, few)
    n = few.rate(f.params["e_star_J"], MEASURE) * few.spectra.seconds * few.powder_g
    assert delta == pytest.approx(1 / math.sqrt(n), rel=1e-9) and 0.05 < delta < 0.15
    q = predict.quantile(f)
    t, lo, hi = predict.time_to(f, few, 0.9)
    assert hi >= t / (1 - q * delta) and lo <= t / (1 + q * delta), (t, lo, hi, delta)
    # the well-sampled condition keeps a narrow band: the counting error is its own
    assert predict.counting_error(f, C) < 0.02


def test_the_power_of_a_dose_model_has_its_compound_poisson_error():
    # weighted by energy: √(Σ e²) / Σ e, ≥ 1/√N (equal when every event has one energy)
    e = 3e-3
    n = A.rate(e, MEASURE) * A.spectra.seconds * A.powder_g
    weighted = A.counting_error(e, MEASURE, weighted=True)
    assert weighted > A.counting_error(e, MEASURE) == pytest.approx(1 / math.sqrt(n))
    assert weighted < 5 / math.sqrt(n)


# ------------------------------------------------------------------ the fit's warnings, repeated
def test_predict_repeats_the_fits_warnings_on_stderr_and_in_json(tmp_path):
    for c in (A, A_SCALED, C):
        write_file(tmp_path / f"{c.name}.json", c.spectra, c.powder_g, "SYNTHETIC test condition")
    write_points(tmp_path / "p.csv", measured(MODEL, TRUTH, (A, A_SCALED), 0))
    res = taimill("kinetics", "fit", "p.csv", "--out", "fit.toml", cwd=tmp_path)
    assert res.returncode == 0 and "e_star_J is not identifiable" in res.stderr, res.stderr
    warnings = tomllib.loads((tmp_path / "fit.toml").read_text())["warnings"]
    assert any("not identifiable" in w for w in warnings)
    res = taimill("kinetics", "predict", "fit.toml", "C.json", "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    for w in warnings:
        assert f"taimill: warning: fit.toml: {w}\n" in res.stderr, res.stderr
    doc = json.loads(res.stdout)
    assert doc["warnings"] == warnings and doc["band"] == "profile"


def test_a_fit_file_of_an_older_taimill_predicts_linearised_and_says_so(tmp_path):
    for c in (A, B, C):
        write_file(tmp_path / f"{c.name}.json", c.spectra, c.powder_g, "SYNTHETIC test condition")
    write_points(tmp_path / "p.csv", measured(MODEL, TRUTH, (A, B), 0))
    assert quick("kinetics", "fit", "p.csv", "--out", "fit.toml", cwd=tmp_path).returncode == 0
    text = (tmp_path / "fit.toml").read_text()
    assert "[profiles]" in text and "flat_directions = []" in text
    head = text.split("\n[profiles]")[0]
    (tmp_path / "old.toml").write_text(head.replace("flat_directions = []\n", "") + "\n")
    res = quick("kinetics", "predict", "old.toml", "C.json", "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("taimill: warning: old.toml: bands are linearised"), res.stderr
    doc = json.loads(res.stdout)
    assert doc["band"] == "linearised" and doc["warnings"] == [predict.LINEARISED]
    row = doc["conditions"][0]
    assert row["lower_s"] < row["time_to_target_s"] < row["upper_s"]
    # a damaged profile is refused in one line, like every other number of a fit file
    (tmp_path / "bad.toml").write_text(head + '\n[profiles]\n"kappa_g" = [[1.0, nan]]\n')
    res = quick("kinetics", "predict", "bad.toml", "A.json", cwd=tmp_path)
    assert res.returncode == 2 and res.stdout == "", res.stderr
    assert res.stderr.count("\n") == 1 and "bad.toml: profiles.kappa_g" in res.stderr, res.stderr


def sweep_store(path: Path, points: list[tuple[dict, Condition]]) -> Path:
    """A finished sweep store of the given (values, condition) points: each a run
    holding only a config and the condition's spectra (no simulation)."""
    from taimill.store.sweep import SweepStore

    store = SweepStore.create(path, {"preset": "synthetic"})
    config = {"balls": {"count": 2, "radius": 0.005}, "duration": 1.0, "dt": 1e-5, "trajectory_rate": 0,
              "powder": {"mass": 0.005, "ball_to_powder": 10.0}}
    for i, (values, cond) in enumerate(points):
        store.add_points([{"overrides": {"seed": values["seed"], "jar": values["jar"]}, "values": values}])
        store.write_point(SimpleNamespace(index=i, config=config, n_balls=2, radii=np.full(2, 0.005), tables=None,
                                          spectra=cond.spectra, summary={"dissipated_power": 3.5}, status="complete"))
    return path


def test_replicas_of_a_sweep_point_widen_the_band_by_their_spread(tmp_path):
    """Three replicas (seeds) of one condition whose rates differ by ±15 %, far more than
    counting allows: the band of each point is at least ±q times their spread; a point
    without replicas keeps the counting error."""
    reps = [condition(f"r{k}", 4e-3, 0.45, rate) for k, rate in enumerate((1000.0, 1150.0, 850.0))]
    points = [({"jar": "j", "seed": k, "replica": k}, c) for k, c in enumerate(reps)]
    points.append(({"jar": "other", "seed": 0, "replica": 0}, C))
    sweep_store(tmp_path / "s.zarr", points)
    for c in (A, B):
        write_file(tmp_path / f"{c.name}.json", c.spectra, c.powder_g, "SYNTHETIC test condition")
    write_points(tmp_path / "p.csv", measured(MODEL, TRUTH, (A, B), 0, sigma=0.003))
    assert quick("kinetics", "fit", "p.csv", "--out", "fit.toml", cwd=tmp_path).returncode == 0
    res = quick("kinetics", "predict", "fit.toml", "s.zarr", "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    rows = {r["condition"]: r for r in json.loads(res.stdout)["conditions"]}
    assert len(rows) == 4
    q = stats.norm.ppf(0.975)
    for k in range(3):
        r = rows[f"s.zarr#{k}"]
        assert r["scatter_from"] == "3 replicas" and r["scatter"] == pytest.approx(0.15, rel=1e-3)
        t = r["time_to_target_s"]
        assert r["upper_s"] >= t / (1 - q * 0.15) and r["lower_s"] <= t / (1 + q * 0.15), r
    assert rows["s.zarr#3"]["scatter_from"] == "counting" and rows["s.zarr#3"]["scatter"] < 0.02
