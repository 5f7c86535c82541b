"""`taimill sizes fit` and `taimill sizes predict --fit` (taimill.outcome.sizes_fit):
the population balance fitted to synthetic distributions of known parameters covers
them and predicts a third condition; the fit file's round trip and refusals; the size
figure's panels."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import tmpfs

from taimill.outcome import sizes_fit as sf
from taimill.outcome.condition import read_file
from taimill.outcome.grinding import SizeClasses, evolve, feed, passing
from taimill.outcome.sizes import Distribution, read_distributions

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples" / "outcome"
CONDS = {c: read_file(EXAMPLES / f"condition-{c}.json") for c in "abc"}
#: the truth: fine fragments φ 0.4, γ 0.9 (β 3.5 and capture 1 mg held at the fit's defaults)
TRUE = {"f_mat": 0.02, "xw_min": 0.05, "phi": 0.4, "gamma": 0.9}
CLASSES = SizeClasses.spanning(2e-6, 800e-6)  # 18 classes √2 apart: 800 µm down to 1.6 µm
FEED = feed(CLASSES, 200e-6, 0.5)
HOURS = (0.25, 1.0, 4.0)
TARGET = 20e-6  # x90
TRIALS_FULL, TRIALS = 50, 10


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, cwd=ROOT, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run(command(*args), cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith(("[Taichi]", "taimill: warning: "))]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def truth():
    return sf.grinding(TRUE, "dissipated_normal", True)


def synthetic(seed: int, conditions="ab", noise: float = 0.02) -> list[Distribution]:
    """Distributions of the truth at HOURS on CLASSES' edges, each passing share times
    (1 + noise · N(0, 1)); the feed (time 0) measured exactly, so that the fit's classes
    are the truth's."""
    rng = np.random.default_rng(seed)
    x = CLASSES.edges[::-1]
    out = []
    for c in conditions:
        out.append(Distribution(c, 0.0, x, passing(CLASSES, FEED)[0][::-1], 1))
        q = passing(CLASSES, evolve(sf.rates(truth(), CLASSES, CONDS[c]), FEED, [h * 3600 for h in HOURS]))
        for h, row in zip(HOURS, q):
            row = row[::-1]
            keep = (row > 0.005) & (row < 0.995)  # what a laser diffraction resolves
            out.append(Distribution(c, h * 3600, x[keep], row[keep] * (1 + noise * rng.standard_normal(keep.sum())), 1))
    return out


def csv_text(dists: list[Distribution], names: dict) -> str:
    """The distributions as a measured CSV: each made cumulative as a laser diffraction
    reports it (never falling, at most 100 %)."""
    lines = ["condition,time_h,size_um,passing_pct"]
    for d in dists:
        q = np.minimum(np.maximum.accumulate(d.passing), 1.0)
        lines += [f"{names[d.condition]},{d.time / 3600:g},{x * 1e6:.9g},{qi * 100:.9g}" for x, qi in zip(d.sizes, q)]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- the solver the fit uses
def test_the_solvers_taylor_step_is_scipys_matrix_exponential():
    # the population balance's solver (a Taylor series, scaled and squared) against
    # scipy's Padé expm where that one is accurate (‖A t‖ moderate): the same masses
    from scipy.linalg import expm

    a = sf.rates(sf.grinding(TRUE | {"k_att": 0.01}, "dissipated_normal", True), CLASSES, CONDS["b"])
    norm = np.abs(a).sum(axis=0).max()
    t = np.array([0.0, 0.3, 3.0, 20.0]) / norm
    want = np.array([expm(a * ti) @ FEED for ti in t])
    assert np.max(np.abs(evolve(a, FEED, t) - want)) < 1e-12


# ---------------------------------------------------------------- synthetic truth
def coverage(trials: int) -> tuple[int, int, dict]:
    """(trials with every parameter inside its 95 % interval, trials whose time to the
    target x90 at the third condition is within 15 % of the truth's, per parameter)."""
    t_true = sf.time_to_x90(truth(), CLASSES, CONDS["c"], FEED, TARGET)
    covered = close = 0
    each = dict.fromkeys(TRUE, 0)
    for seed in range(trials):
        data = sf.prepare(synthetic(seed), "synthetic")
        assert data.classes == CLASSES and data.sigma == "2 % of each share"
        fit = sf.fit_sizes(data, {c: CONDS[c] for c in "ab"})
        assert sorted(fit.params) == sorted(TRUE)
        inside = {k: fit.intervals[k][0] <= v <= fit.intervals[k][1] for k, v in TRUE.items()}
        each = {k: each[k] + inside[k] for k in each}
        covered += all(inside.values())
        if seed == 0:
            t, lo, hi = sf.time_to_target(fit, CONDS["c"], data.feeds["a"], TARGET)
            assert lo < t < hi  # a band, never of zero width
        t = sf.time_to_x90(sf.grinding(fit.all_params(), fit.measure, fit.stress_only), fit.classes, CONDS["c"],
                           data.feeds["a"], TARGET)
        close += abs(t / t_true - 1) <= 0.15
    return covered, close, each


def test_synthetic_truth_is_covered_and_a_third_condition_predicted():
    covered, close, each = coverage(TRIALS)
    assert covered >= 0.9 * TRIALS and close >= 0.9 * TRIALS, (covered, close, each)


@pytest.mark.full
def test_synthetic_truth_is_covered_in_fifty_trials():
    covered, close, each = coverage(TRIALS_FULL)
    assert covered >= 0.9 * TRIALS_FULL and close >= 0.9 * TRIALS_FULL, (covered, close, each)


def test_a_fit_on_the_wrong_measure_misses_the_truth():
    # the coverage test can fail: the friction spectra put the breakage elsewhere
    data = sf.prepare(synthetic(0), "synthetic")
    fit = sf.fit_sizes(data, {c: CONDS[c] for c in "ab"}, measure="dissipated_friction")
    assert not all(fit.intervals[k][0] <= v <= fit.intervals[k][1] for k, v in TRUE.items())


def test_one_condition_and_a_parameter_the_data_do_not_fix_are_warned_about():
    data = sf.prepare(synthetic(1, conditions="a"), "synthetic")
    fit = sf.fit_sizes(data, {"a": CONDS["a"]}, free=["capture_g"])
    said = " ".join(fit.warnings)
    assert "one condition (a)" in said
    # capture enters with xw_min only as their product: its profile is flat and the two trade off
    assert "capture_g is not identifiable" in said and "xw_min and capture_g are correlated -1.000" in said, said


# ---------------------------------------------------------------- through the real CLI
@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """A folder with the synthetic CSV (conditions a, b), the conditions, and the fit
    and figure `taimill sizes fit` wrote."""
    d = tmp_path_factory.mktemp("sizes")
    for c in "abc":
        shutil.copy(EXAMPLES / f"condition-{c}.json", d / f"{c}.json")
    (d / "sizes.csv").write_text(csv_text(synthetic(3), {c: f"{c}.json" for c in "ab"}))
    res = taimill("sizes", "fit", d / "sizes.csv", "--out", d / "fit.toml", "--figure", d / "fit.svg", cwd=d)
    assert res.returncode == 0, res.stderr
    return d, res


def test_cli_fit_writes_a_fit_file_with_intervals_around_the_truth(fitted):
    d, res = fitted
    text = (d / "fit.toml").read_text()
    assert text.startswith(sf.MARK + "\n") and sf.is_fit_file(d / "fit.toml")
    fit = sf.read_fit(d / "fit.toml")
    assert fit.classes.n == CLASSES.n and fit.classes.top_m == pytest.approx(CLASSES.top_m, rel=1e-9)
    assert fit.conditions == ["a.json", "b.json"]
    for k, v in TRUE.items():
        lo, hi = fit.intervals[k]
        assert lo < fit.params[k] < hi and lo <= v <= hi, (k, lo, v, hi)
    assert fit.fixed == {"capture_g": 1e-3, "beta": 3.5, "k_att": 0.0}
    assert "f_mat" in res.stdout and "(held)" in res.stdout and "wrote" in res.stdout


def test_cli_round_trip_fit_then_predict_with_bands_and_a_ranking(fitted):
    d, _ = fitted
    res = taimill("sizes", "predict", "--fit", "fit.toml", "c.json", "a.json", "b.json", "--hours", "0,1,4",
                  "--target-x90", TARGET * 1e6, "--rank", "--json", cwd=d)
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)["conditions"]
    times = [r["time_to_target_x90_s"] for r in rows]
    assert times == sorted(times) and [r["condition"] for r in rows] == ["b.json", "c.json", "a.json"]
    for r in rows:
        assert r["lower_s"] < r["time_to_target_x90_s"] < r["upper_s"]
        for k in ("x10", "x50", "x90"):
            v, lo, hi = (np.array(r[f"{k}{s}_m"], dtype=float) for s in ("", "_lower", "_upper"))
            assert v[0] == lo[0] == hi[0]  # time 0: the feed
            ok = np.isfinite(v[1:])
            assert np.all((lo[1:] < v[1:]) & (v[1:] < hi[1:]) | ~ok)  # after it, never a band of zero width
    # the third condition, never fitted: its time to target near the truth's
    t_true = sf.time_to_x90(truth(), CLASSES, CONDS["c"], FEED, TARGET)
    c = next(r for r in rows if r["condition"] == "c.json")
    assert abs(c["time_to_target_x90_s"] / t_true - 1) < 0.15
    # the fitted conditions' x90 where they were measured
    measured = {(x.condition, x.time): x for x in read_distributions(d / "sizes.csv")}
    a = next(r for r in rows if r["condition"] == "a.json")
    m = measured[("a.json", 4 * 3600.0)]
    assert a["x90_m"][2] == pytest.approx(math.exp(np.interp(0.9, m.passing, np.log(m.sizes))), rel=0.05)


def test_cli_predict_table_gives_bands_and_marks_the_feed(fitted):
    d, _ = fitted
    res = taimill("sizes", "predict", "--fit", "fit.toml", "c.json", "--hours", "0,2", "--target-x90", 20, cwd=d)
    assert res.returncode == 0, res.stderr
    assert "(feed)" in res.stdout and re.search(r"\d \[\d[\d.]*, \d[\d.]*\]", res.stdout)
    assert "time until x90 ≤ 20 µm" in res.stdout


def _edited(d: Path, name: str, old: str, new: str) -> Path:
    text = (d / "fit.toml").read_text()
    assert re.search(old, text, flags=re.M), old
    (d / name).write_text(re.sub(old, new, text, count=1, flags=re.M))
    return d / name


@pytest.mark.parametrize("old, new, key", [
    (r'^model = "population-balance"', 'model = "critical-collisions"', "model"),
    (r'^"f_mat" = [^\n]+', '"f_mat" = nan', "parameters.f_mat"),
    (r'^"phi" = [^\n]+', '"phi" = 1.5', "parameters.phi"),
    (r'^"xw_min" = \[[^\n]+', '"xw_min" = [1.0, 2.0]', "intervals.xw_min"),
    (r'^covariance = \[\[[-0-9.e]+', "covariance = [[-1.0", "covariance[0][0]"),
    (r'^"n" = \d+', '"n" = 30', "classes.feed"),
    (r'^"k_att" = 0\.0', '"k_att" = -1.0', "fixed.k_att"),
    (r'^measure = "dissipated_normal"', 'measure = "dissipated_total"', "measure"),
    (r'^"f_mat" = \[\[[-0-9.e]+', '"f_mat" = [[99.0', "profile_ends.f_mat"),
])
def test_a_damaged_fit_file_is_refused_in_one_line(fitted, old, new, key):
    d, _ = fitted
    bad = _edited(d, f"bad-{key}.toml", old, new)
    res = taimill("sizes", "predict", "--fit", bad.name, "c.json", "--target-x90", 20, cwd=d)
    assert res.returncode == 2, res.stderr
    line = one_line(res.stderr)
    assert line.startswith(f"taimill: error: {bad.name}: {key} = "), line


def test_a_kinetics_fit_and_a_parameter_file_are_not_sizes_fits(fitted, tmp_path):
    d, _ = fitted
    res = taimill("sizes", "predict", "--fit", EXAMPLES / "fit.toml", "c.json", cwd=d)
    assert res.returncode == 2 and "model = " in one_line(res.stderr) and "population-balance" in res.stderr


def test_outputs_follow_the_house_rules(fitted):
    d, _ = fitted
    # the CSV itself, a user's file and an existing fit without --overwrite are refused before any work
    for out, extra, what in (("sizes.csv", ["--overwrite"], "--out"), ("notes.toml", ["--overwrite"], "--out"),
                             ("fit.toml", [], "--out")):
        (d / "notes.toml").write_text("# mine\n")
        before = (d / out).read_bytes()
        res = taimill("sizes", "fit", "sizes.csv", "--out", out, *extra, cwd=d)
        assert res.returncode == 2 and one_line(res.stderr).startswith(f"taimill: error: command line: {what} = "), res.stderr
        assert (d / out).read_bytes() == before
    res = taimill("sizes", "fit", "sizes.csv", "--out", "new.toml", "--figure", "fit.txt", cwd=d)
    assert res.returncode == 2 and "--figure" in one_line(res.stderr) and not (d / "new.toml").exists()


def test_sigterm_during_the_fit_keeps_the_old_fit_and_leaves_nothing_that_blocks_the_rerun(fitted, tmp_path):
    d, _ = fitted
    for name in ("sizes.csv", "a.json", "b.json", "fit.toml", "fit.svg"):
        shutil.copy(d / name, tmp_path / name)
    old = {n: (tmp_path / n).read_bytes() for n in ("fit.toml", "fit.svg")}
    argv = command("sizes", "fit", "sizes.csv", "--out", "fit.toml", "--figure", "fit.svg", "--overwrite")
    proc = subprocess.Popen(argv, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    lock = tmp_path / "fit.toml.lock"  # taken once the outputs are checked, before the fit
    end = time.monotonic() + 120
    while not lock.exists() and proc.poll() is None and time.monotonic() < end:
        time.sleep(0.002)
    assert lock.exists(), "the fit never held its output"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    line = one_line(err)
    assert line.startswith("taimill: terminated (SIGTERM)") and "fit.toml is unchanged" in line, line
    assert {n: (tmp_path / n).read_bytes() for n in old} == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json", "fit.svg", "fit.toml", "sizes.csv"]


@pytest.fixture
def full_disk(tmp_path):
    """A 2 MB tmpfs filled but for about 12 kB: room for a fit file, not for a figure."""
    with tmpfs(tmp_path / "disk", "size=2m", free_bytes=12 * 1024) as mnt:
        yield mnt


def test_a_full_disk_is_exit_5_one_line_and_leaves_nothing_half_written(fitted, full_disk):
    d, _ = fitted
    argv = ["sizes", "fit", "sizes.csv", "--out", full_disk / "fit.toml", "--figure", full_disk / "fit.png"]
    res = taimill(*argv, cwd=d)
    assert res.returncode == 5, res.stderr
    line = one_line(res.stderr)
    assert "No space left on device" in line and (str(full_disk / "fit.png") in line or str(full_disk / "fit.toml") in line)
    assert sorted(p.name for p in full_disk.iterdir()) == ["filler"]  # no fit without its figure, no partial, no lock
    (full_disk / "filler").unlink()
    res = taimill(*argv, cwd=d)  # the same command, once there is room
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in full_disk.iterdir()) == ["fit.png", "fit.toml"]


def test_the_feed_is_needed(tmp_path):
    shutil.copy(EXAMPLES / "condition-a.json", tmp_path / "a.json")
    dists = [x for x in synthetic(0, conditions="a") if x.time > 0]
    (tmp_path / "s.csv").write_text(csv_text(dists, {"a": "a.json"}))
    res = taimill("sizes", "fit", "s.csv", "--out", "f.toml", cwd=tmp_path)
    assert res.returncode == 2
    assert re.match(r"taimill: error: s\.csv: line 2: condition = 'a\.json': has no distribution at time 0 .*--feed-x50",
                    one_line(res.stderr))
    assert not (tmp_path / "f.toml").exists()


def test_a_sigma_column_weights_the_fit_and_is_checked(tmp_path):
    text = "condition,time_h,size_um,passing_pct,sigma_pct\na.json,1,10,20,0.5\na.json,1,20,40,0.8\n"
    (tmp_path / "s.csv").write_text(text)
    d = read_distributions(tmp_path / "s.csv")
    assert np.allclose(d[0].sigma, [0.005, 0.008])
    (tmp_path / "bad.csv").write_text(text.replace("0.8", "-1"))
    res = taimill("sizes", "check", tmp_path / "bad.csv")
    assert res.returncode == 2
    assert re.search(r"bad\.csv: line 3: column 5 \(sigma_pct\) = '-1': an uncertainty in \(0, 100\]", one_line(res.stderr))
    (tmp_path / "bare.csv").write_text(text.replace("sigma_pct", "sigma"))
    res = taimill("sizes", "check", tmp_path / "bare.csv")
    assert res.returncode == 2 and "'sigma' has no unit" in one_line(res.stderr)


def test_a_feed_measured_from_a_coarse_size_up_keeps_its_fine_tail_out_of_the_sink():
    # a log-normal feed (x50 200 µm) measured only where it passes more than 0.05 %: the
    # share below the smallest measured size follows the tail, not the finest class
    q = passing(CLASSES, FEED)[0][::-1]
    x = CLASSES.edges[::-1]
    keep = q > 0.0005
    m = sf.measured_feed(CLASSES, x[keep], q[keep])
    assert m.sum() == pytest.approx(1.0) and m[-1] < 1e-6 < q[keep][0]
    assert np.abs(m - FEED).max() < 2e-3


def test_the_shipped_size_example_is_what_its_script_makes(tmp_path):
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import make_sizes_example
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    make_sizes_example.generate(tmp_path)
    made = (tmp_path / "sizes.csv").read_text()
    assert made == (EXAMPLES / "sizes.csv").read_text() and made.startswith("# SYNTHETIC")
    assert sf.read_fit(EXAMPLES / "sizes-fit.toml").conditions == ["condition-a.json", "condition-b.json"]


# ---------------------------------------------------------------- figures
def test_the_fit_figure_has_a_panel_per_condition_and_the_two_summaries(fitted):
    d, _ = fitted
    from taimill.figures import is_figure

    svg = (d / "fit.svg").read_text()
    assert is_figure(d / "fit.svg") and len(re.findall(r'<g id="axes_\d+"', svg)) == 2 + 2


def test_the_predict_figure_and_its_panels(fitted, tmp_path):
    d, _ = fitted
    from taimill.figures import is_figure
    from taimill.figures.sizes import PANELS, sizes_figure

    res = taimill("sizes", "predict", "--fit", "fit.toml", "a.json", "b.json", "c.json", "--target-x90", 20,
                  "--figure", tmp_path / "p.png", cwd=d)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "p.png").read_bytes().startswith(b"\x89PNG") and is_figure(tmp_path / "p.png")
    fit = sf.read_fit(d / "fit.toml")
    m0 = np.asarray(fit.feed)
    rows = []
    for c in "ab":
        q = sf.quantiles(fit, CONDS[c], m0, [0.0, 3600.0], (0.5, 0.9))
        s = sf.selection_rates(fit, CONDS[c])
        rows.append({"label": c, "edges_m": fit.classes.edges, "times_s": [0.0, 3600.0],
                     "passing": sf.distribution(fit, CONDS[c], m0, [0.0, 3600.0]),
                     "curve": {"time_s": [0.0, 3600.0], "x50": q[0.5], "x90": q[0.9]}, "impact": s["impact"],
                     "attrition": s["attrition"], "sizes_m": fit.classes.sizes})
    titles = sizes_figure(tmp_path / "q.svg", rows, {"a": [(3600.0, CLASSES.edges[::-1][5:], np.linspace(0.1, 0.9, CLASSES.n - 4))]},
                          TARGET)
    assert titles == [f"a: {PANELS[0]}", f"b: {PANELS[0]}", PANELS[1], PANELS[2]]
