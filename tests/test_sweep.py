"""Sweeps (`taimill sweep`): planning and validation, sweep points bit-identical to `taimill run`
on local spawned processes and on a real dask LocalCluster, resuming, replicas' bands,
the replicas' regimes (a K whose replicas disagree flagged in the table, the JSON, the
figures and scripts/reproduce_thesis.py), refinement of a maximum, sweep figures and
the measured-data overlay."""

import contextlib
import importlib.util
import io
import json
import math
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from helpers import numbers_without_unit
from taimill import cli
from taimill.errors import ConfigError
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink
from taimill.runs.sweep import auto_batch, chunks, parse_values, refine
from taimill.runs.executors import Job, PointResult
from taimill.figures.sweep import band, mark_mixed, read_overlay, report_sweep
from taimill.analysis.sweep import REGIMES, mean_band, parabolic_peak, regime_fractions, seen_classes, t_quantile
from taimill.store.sweep import SweepStore, is_sweep, open_sweep

ROOT = Path(__file__).resolve().parent.parent
PRESET = "presets/p4-cy-steel.toml"
# 3 K x 2 replicas of 0.3 s, then one refinement round (up to 2 K x 2 replicas more):
# chunks of B = 2 mills with different automatic dt share one kernel, on 2 processes.
SWEEP = ("sweep", PRESET, "--ratio", "-2:-3:0.5", "--replicas", 2, "--duration", 0.3, "--batch", 2,
         "--refine", "--refine-metric", "mean_se", "--refine-rounds", 1)
TIMING = {"wall_seconds", "realtime_factor", "batch", "compute"}  # compute: a sweep's workers run one thread each


def taimill(*args):
    return subprocess.run([sys.executable, "-m", "taimill.cli", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "local.zarr"
    res = taimill(*SWEEP, "--workers", 2, "--out", out, "--json")
    assert res.returncode == 0, res.stderr
    return out, json.loads(res.stdout)


# ---------------------------------------------------------------- planning
def test_parse_values_ranges_lists_and_rounding():
    assert parse_values("0:-1:0.25", "--ratio") == [0.0, -0.25, -0.5, -0.75, -1.0]
    assert parse_values("0:-1:-0.25", "--ratio") == parse_values("0:-1:0.25", "--ratio")  # sign from A → B
    assert parse_values("0:-4:0.2", "--ratio")[13] == -2.6  # exactly the typed -2.6 (same run)
    assert len(parse_values("0:-4:0.2", "--ratio")) == 21
    assert parse_values("-2.6", "--ratio") == [-2.6]
    assert parse_values("6,12,24", "--balls", int) == [6, 12, 24]
    assert parse_values("steel-steel, steel-fluorite", "--pair", str) == ["steel-steel", "steel-fluorite"]


@pytest.mark.parametrize("text, kind, why", [
    ("0:-4:0", float, "STEP ≠ 0"), ("0:-4", float, "A:B:STEP"), ("a:b:c", float, "numbers"),
    ("1,1", float, "repeated"), ("6,x", int, "integers"), ("0:-1e9:1e-4", float, "at most"),
    ("steel-steel,", str, "no empty entry"), ("nan", float, "finite"),
])
def test_parse_values_rejects_bad_input(text, kind, why):
    with pytest.raises(ConfigError, match=why) as err:
        parse_values(text, "--ratio", kind)
    assert err.value.source == "command line" and err.value.key == "--ratio"


def test_a_range_too_long_to_count_is_refused_after_a_taichi_run_too():
    """A Taichi run leaves the CPU flushing subnormals to zero in this process, so
    float("1e-308") then reads 0: the count is checked before STEP = 0 and gives the
    same answer either way (make test's workers run files in any order)."""
    from taimill.model.preset import load_preset
    from taimill.runs.simulation import run
    from taimill.store.sinks import NullSink

    run(load_preset(ROOT / "presets" / "p4-cy-steel.toml", {"duration": 0.002, "analysis_start": 0.0, "outputs.trajectory_rate": 1000}), NullSink(), duration=0.002)
    with pytest.raises(ConfigError, match="at most 10000"):
        parse_values("0:1e308:1e-308", "--ratio")


def test_chunks_group_engines_and_put_the_costliest_first():
    def job(i, n, dt, jar="CY"):
        jar = SimpleNamespace(name=jar.removesuffix(".toml"), source=jar if jar.endswith(".toml") else f"jars/{jar}.toml")
        return Job(i, SimpleNamespace(balls=SimpleNamespace(count=n), jar=jar, duration=1.0, dt=dt))

    jobs = [job(0, 12, 2e-6), job(1, 12, 1e-6), job(2, 24, 2e-6), job(3, 12, 1.5e-6), job(4, 12, 3e-6, "HM"),
            job(5, 12, 4e-6, "mine/CY.toml")]
    got = [[j.index for j in c] for c in chunks(jobs, 2)]
    # one ball count and jar file per chunk (a user's CY.toml is not the built-in CY);
    # costs 20e6, 12e6, 6e6, 4e6, 3e6 ball-steps
    assert got == [[1, 3], [2], [0], [4], [5]]
    assert auto_batch(21, 2) == 1 and auto_batch(160, 2) == 10 and auto_batch(10**4, 2) == 16


def test_sweep_rejects_bad_input_before_running_anything(tmp_path):
    out = tmp_path / "s.zarr"
    for args, key in ((("--ratio", "0:-4:0"), "--ratio"), (("--replicas", 0), "--replicas"),
                      (("--ratio", "-1,-2", "--refine", "--refine-metric", "mean_se"), "--ratio"),
                      # the figure to maximise is the user's: impacts or dissipation, never a default
                      (("--ratio", "-1:-3:0.5", "--refine"), "--refine-metric"),
                      (("--workers", 2, "--scheduler", "tcp://x:1"), "--workers"),
                      (("--ball-material", "gold"), "balls.material"), (("--batch", 0), "--batch")):
        res = taimill("sweep", PRESET, *args, "--out", out)
        assert res.returncode == 2, (args, res.stderr)
        assert key in res.stderr and len(res.stderr.strip().splitlines()) == 1
        assert not out.exists()


# ---------------------------------------------------------------- bit identity
def _run_alone(tmp_path, k, seed):
    out = tmp_path / f"run{k}_{seed}.zarr"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli.main(["run", PRESET, "--ratio", str(k), "--seed", str(seed), "--duration", "0.3", "--out", str(out), "--json"])
    assert code == 0
    return json.loads(buf.getvalue()), open_run(out)


def _assert_same_run(a, b):
    assert a.events and len(a.events["t_start"]) > 50
    for col in b.events:
        np.testing.assert_array_equal(a.events[col], b.events[col], err_msg=col)
    for col in b.frames:
        np.testing.assert_array_equal(a.frames[col], b.frames[col], err_msg=col)
    assert {k: v for k, v in a.summary.items() if k not in TIMING} == {k: v for k, v in b.summary.items() if k not in TIMING}


def test_sweep_points_equal_taimill_run_bit_for_bit(local_sweep, tmp_path):
    # Acceptance: every point equals the same run alone (same seed): event and frame
    # tables compared exactly, summaries except timings. K = -2 and -2.5 shared a kernel.
    path, rows = local_sweep
    assert [(r["ratio"], r["seed"], r["replica"]) for r in rows[:6]] == [
        (-2.0, 1, 0), (-2.0, 2, 1), (-2.5, 1, 0), (-2.5, 2, 1), (-3.0, 1, 0), (-3.0, 2, 1)]
    assert all(r["status"] == "complete" for r in rows)
    store = open_sweep(path)
    # the refinement round split the gaps next to the best grid K (replicate mean SE)
    grid = {k: np.mean([r["mean_se"] for r in rows[:6] if r["ratio"] == k]) for k in (-2.0, -2.5, -3.0)}
    best = max(grid, key=grid.get)
    expected = sorted({round((best + k) / 2, 10) for k in grid if abs(k - best) == 0.5})
    assert sorted({r["ratio"] for r in rows[6:]}) == expected and len(rows) == 6 + 2 * len(expected)
    assert store.refine["peaks"][0]["metric"] == "mean_se"
    assert store.table()["batch"].max() == 2
    for point, k, seed in ((0, -2.0, 1), (3, -2.5, 2)):
        summary, alone = _run_alone(tmp_path, k, seed)
        _assert_same_run(store.point(point), alone)
        assert rows[point]["mean_se"] == summary["mean_se"] and rows[point]["events"] == summary["events"]


def test_dask_local_cluster_gives_the_local_results(local_sweep, tmp_path):
    # Acceptance: the same sweep on a real dask LocalCluster (2 worker processes, one
    # thread each) equals the local processes' run bit for bit.
    from distributed import LocalCluster

    path, rows = local_sweep
    out = tmp_path / "dask.zarr"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        res = taimill(*SWEEP, "--scheduler", cluster.scheduler_address, "--out", out, "--json")
    assert res.returncode == 0, res.stderr
    dask_rows = json.loads(res.stdout)
    local, remote = open_sweep(path), open_sweep(out)
    for i in range(len(rows)):
        _assert_same_run(remote.point(i), local.point(i))
    assert [r["mean_se"] for r in dask_rows] == [r["mean_se"] for r in rows]


def test_rerun_resumes_and_a_different_sweep_is_refused(local_sweep):
    path, rows = local_sweep
    res = taimill(*SWEEP, "--out", path, "--json")  # every point done: nothing runs
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout) == rows and "Starting on arch" not in res.stderr
    res = taimill("sweep", PRESET, "--ratio", "-2:-3:0.25", "--duration", 0.3, "--out", path)
    assert res.returncode == 2 and "different sweep" in res.stderr and "--overwrite" in res.stderr


def test_store_survives_a_killed_sweep(tmp_path):
    # A point killed mid-run (group 'running') is not done; a point whose group
    # finished before its table row was marked is re-indexed from the group.
    store = SweepStore.create(tmp_path / "s.zarr", {"preset": "x"})
    pts = [{"overrides": {"ratio": k}, "values": {"ratio": k, "jar": "CY", "balls": 12, "pair": "steel-steel",
                                                   "plate_rpm": 200.0}} for k in (-1.0, -2.0, -3.0)]
    assert store.add_points(pts) == [0, 1, 2] and store.add_points(pts[1:]) == [1, 2]
    radii = np.full(2, 0.006)

    def result(i):
        return PointResult(i, {"mean_se": -float(i), "events": 10 * i, "regime": "cataracting"}, "complete", {}, 2, radii, None)

    store.write_point(result(0))
    ZarrSink(store.root["points"].require_group("p00001")).start({}, 2, radii)  # killed while running
    sink = ZarrSink(store.root["points"].require_group("p00002"))
    sink.start({}, 2, radii)
    sink.finish(result(2).summary, "complete")  # killed before its row
    again = open_sweep(tmp_path / "s.zarr", mode="r+")
    assert again.done() == {0, 2}
    t = again.table()
    assert list(t["point"]) == [0, 2] and list(t["events"]) == [0, 20] and list(t["regime"]) == ["cataracting"] * 2
    assert is_sweep(tmp_path / "s.zarr") and not is_sweep(tmp_path / "nothing.zarr")


# ---------------------------------------------------------------- statistics
def test_student_t_quantiles_and_band():
    # Tabulated two-sided 95 % quantiles (to the 4 decimals of the tables).
    for nu, t in ((1, 12.7062), (2, 4.3027), (4, 2.7764), (10, 2.2281), (30, 2.0423)):
        assert t_quantile(nu) == pytest.approx(t, abs=1e-4)
    mean, half, n = mean_band([1.0, 2.0, 3.0, math.nan])
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    assert math.isnan(mean_band([5.0])[1])


def test_replicas_give_a_band_in_the_real_sweep(local_sweep):
    path, rows = local_sweep
    table = open_sweep(path).table()
    ks, mean, half = band(table, np.arange(len(table["point"])), "mean_se")
    assert {-3.0, -2.5, -2.0} <= set(ks)
    for k, m, h in zip(ks, mean, half):
        pair = [r["mean_se"] for r in rows if r["ratio"] == k]
        assert m == pytest.approx(np.mean(pair)) and h == pytest.approx(12.7062 * abs(pair[0] - pair[1]) / 2, rel=1e-4)


def test_refine_locates_a_skewed_maximum():
    # A skewed synthetic peak between grid points; 3 rounds halve the 0.5 spacing to
    # 0.0625; the parabola through the best three points then lands within 0.01 of the
    # true maximum (a smooth peak is locally quadratic: error ~ skew x spacing²).
    k0 = -2.63

    def f(k):
        return math.exp(-((k - k0) ** 2) / 0.8) * (1.0 - 0.1 * (k - k0))

    dense = np.linspace(-4.0, 0.0, 400_001)
    true_peak = dense[np.argmax([f(k) for k in dense])]

    def rows_for(ks, start):
        return {start + i: {"ratio": k, "jar": "CY", "balls": 12, "pair": "p", "plate_rpm": 200.0, "m": f(k)}
                for i, k in enumerate(ks)}

    asked = []

    def evaluate(extra):
        (ks,) = extra.values()
        asked.append(ks)
        return rows_for(ks, 100 * len(asked))

    grid = rows_for([0.5 * -i for i in range(9)], 0)
    rows, peaks = refine(grid, "m", 3, evaluate)
    assert asked[0] == [-2.75, -2.25] and len(asked) == 3
    assert all(-4 <= k <= 0 for ks in asked for k in ks)
    (peak,) = peaks
    assert peak["method"] == "parabola" and peak["ratio"] == pytest.approx(true_peak, abs=0.01)
    assert parabolic_peak([0, -1, -2], [3, 2, 1])["method"] == "edge"


# ---------------------------------------------------------------- regimes of the replicas
def _bistable_table():
    """A hand-made sweep table, two curves (Ω = 200, 300 rpm), one row per point x
    replica, each with its regime (the thesis' three) and class (the summary's). At
    Ω = 200, K = -2.4 the replicas disagree (2 cataracting, 1 pinned to the wall); at
    300 rpm one replica is not classified ("" is the store's fill)."""
    rows = [(200.0, -2.4, "cataracting", "cataracting", 5e-3), (200.0, -2.4, "rolling", "pinned ring", 1e-3),
            (200.0, -2.4, "cataracting", "cataracting", 6e-3), (200.0, -2.6, "rolling", "pinned ring", 1e-3),
            (200.0, -2.6, "rolling", "pinned ring", 2e-3), (200.0, -2.6, "rolling", "pinned ring", 1.5e-3),
            (300.0, -2.4, "cataracting", "cataracting", 9e-3), (300.0, -2.4, "", "", 8e-3)]
    rpm, k, regime, cls, se = (np.array(c) for c in zip(*rows))
    n = len(rows)
    return {"point": np.arange(n), "jar": np.array(["CY"] * n), "balls": np.full(n, 12), "pair": np.array(["steel-steel"] * n),
            "plate_rpm": rpm, "ratio": k, "regime": regime, "regime_class": cls, "mean_se": se}


def test_regime_fractions_flag_a_k_whose_replicas_disagree():
    got = regime_fractions(_bistable_table())
    assert [(g["plate_rpm"], g["ratio"], g["replicas"], g["bistable"]) for g in got] == [
        (200.0, -2.6, 3, False), (200.0, -2.4, 3, True), (300.0, -2.4, 2, False)]
    zero = dict.fromkeys(REGIMES, 0.0)  # every class of the summary's vocabulary, those seen with their share
    assert got[0]["regime_fractions"] == zero | {"pinned ring": 1.0}
    assert got[1]["regime_fractions"] == zero | {"cataracting": pytest.approx(2 / 3), "pinned ring": pytest.approx(1 / 3)}
    assert got[2]["regime_fractions"] == zero | {"cataracting": 0.5, "unknown": 0.5}
    assert seen_classes(got) == ["cataracting", "pinned ring", "unknown"]
    assert {k: got[1][k] for k in ("jar", "balls", "pair")} == {"jar": "CY", "balls": 12, "pair": "steel-steel"}


def test_sweep_figure_rings_a_mixed_mean_and_draws_its_replicas():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = _bistable_table()
    fig, ax = plt.subplots()
    assert mark_mixed(ax, table, np.arange(6), "mean_se", 1e3, "C0") == {"cataracting", "pinned ring"}
    drawn = {(float(x), round(float(y), 9), line.get_marker())
             for line in ax.get_lines() for x, y in zip(line.get_xdata(), line.get_ydata())}
    assert drawn == {(-2.4, 4.0, "o"), (-2.4, 5.0, "^"), (-2.4, 6.0, "^"), (-2.4, 1.0, "o")}  # only K = -2.4, in mJ
    assert mark_mixed(ax, table, np.arange(6, 8), "mean_se", 1e3, "C1") == set()  # "unknown" is no disagreement
    plt.close(fig)


def test_the_regime_figure_speaks_the_summarys_classes():
    """regimes.png once drew the thesis' three regimes beside a table and summary that
    give the regime classes: one panel per class a replica ends in, nothing else."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from taimill.figures.sweep import _regime_figure

    n = len(_bistable_table()["point"])
    geometry = {"plate_radius": np.full(n, 0.05), "jar_radius": np.full(n, 0.0325), "ball_radius": np.full(n, 0.006)}
    fig = _regime_figure(_bistable_table() | geometry)
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    plt.close(fig)
    assert titles == ["cataracting", "pinned ring", "unknown"]


def test_sweep_json_and_table_give_the_regimes_of_the_replicas(local_sweep):
    # End to end (2 replicas of 0.3 s per K): every row carries its K's shares, which
    # are the counts of the replicas' own regimes; the printed table lists each K once.
    path, rows = local_sweep
    for r in rows:
        same = [s["regime_class"] for s in rows if s["ratio"] == r["ratio"]]  # one curve: the summary's classes
        assert len(same) == 2 and set(REGIMES) <= set(r["regime_fractions"])
        assert r["regime_fractions"] == {lab: same.count(lab) / 2 for lab in r["regime_fractions"]}
        assert r["bistable"] == (len(set(same) - {"unknown"}) > 1)
        assert numbers_without_unit(r) == [] and r["units"]["mean_se"] == "J"  # each row with its units
        assert r["units"]["plate_radius"] == "m" and r["units"]["regime_fractions"] == "1"
    res = taimill(*SWEEP, "--out", path)  # resumes a finished sweep: nothing runs
    assert res.returncode == 0, res.stderr
    header, *lines = res.stdout.split("regimes of the replicas")[1].splitlines()[1:]
    labels = seen_classes(rows)  # K replicas <classes some replica ends in…> bistable: only K varies
    assert re.fullmatch(r"\s*K\s+replicas\s+" + r"\s+".join(map(re.escape, labels)) + r"\s+bistable", header), header
    printed = {float(f[0]): (int(f[1]), dict(zip(labels, map(float, f[2:-1]))), f[-1])
               for f in map(str.split, lines) if len(f) == len(labels) + 3}
    assert sorted(printed) == sorted({r["ratio"] for r in rows})
    for r in rows:
        n, shares, bistable = printed[r["ratio"]]
        assert n == 2 and bistable == ("yes" if r["bistable"] else "no")
        assert shares == {lab: pytest.approx(f, abs=0.005) for lab, f in r["regime_fractions"].items() if lab in labels}
        assert not any(f for lab, f in r["regime_fractions"].items() if lab not in labels)


def test_reproduce_thesis_replicates_the_collapse_and_reports_regimes(local_sweep):
    spec = importlib.util.spec_from_file_location("reproduce_thesis", ROOT / "scripts" / "reproduce_thesis.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    grid = parse_values("0:-4:0.2", "--ratio")
    assert script.in_window(grid, script.REPLICATED["cy-steel"]) == [-2.2, -2.4, -2.6, -2.8, -3.0]
    path, rows = local_sweep
    regimes = script.regime_rows(script.Metrics({"cy-steel": path}, "event", 0.0), ["cy-steel"])
    assert [(g["ratio"], g["replicas"]) for g in regimes] == [(k, 2) for k in sorted({r["ratio"] for r in rows})]
    lines = script.regime_lines(regimes)
    assert len(lines) == 2 + len(regimes) and all(f"| {g['ratio']:g} | 2 |" in ln for g, ln in zip(regimes, lines[2:]))


# ---------------------------------------------------------------- figures
def test_report_writes_figures_and_overlay_via_the_cli(local_sweep, tmp_path):
    path, _ = local_sweep
    csv = tmp_path / "xrd.csv"
    csv.write_text("# fluorite\nratio,inv_sqrt_D [1/sqrt(nm)],inv_sqrt_D_err\n-2.0,0.12,0.01\n-2.6,0.15,\n")
    res = taimill("report", path, "--out", tmp_path / "fig", "--overlay", csv)
    assert res.returncode == 0, res.stderr
    names = sorted(Path(p).name for p in res.stdout.split())
    assert names == ["dissipation.png", "energy_spectra.png", "impact_power.png", "mean_se.png", "mean_se_components.png",
                     "normal_fraction.png", "overlay.png", "randomness.png", "regimes.png", "shear.png"]
    for p in res.stdout.split():
        assert Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and Path(p).stat().st_size > 10_000
    svg = report_sweep(path, tmp_path / "svg", "svg")
    assert all(p.suffix == ".svg" and p.stat().st_size > 10_000 for p in svg)


@pytest.mark.parametrize("text, where, why", [
    ("", "header", "no header"),
    ("K,x\n-1,2\n", "line 1", "'ratio'"),
    ("ratio,x\n", "data", "no data line"),
    ("ratio,x\n-1,2\n-2,abc\n", "line 3, column x", "must be a number"),
    ("ratio,x\n-1,2,3\n", "line 2", "3 cells"),
    ("ratio,x,y_err\n-1,2,3\n", "header", "NAME and NAME_err"),
    ("ratio,x\n,2\n", "line 2, column ratio", "needs a ratio"),
])
def test_overlay_csv_errors_name_file_line_and_column(tmp_path, text, where, why):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(ConfigError, match=why) as err:
        read_overlay(p)
    assert err.value.source == str(p) and err.value.key == where


def test_overlay_reads_series_with_errors_and_missing_cells(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("ratio,a [u],a_err,b\n-1,1,0.1,\n-2,2,,5\n")
    s = read_overlay(p)
    assert list(s) == ["a [u]", "b"]
    k, a, err = s["a [u]"]
    assert list(k) == [-1, -2] and list(a) == [1, 2] and err[0] == 0.1 and math.isnan(err[1])
    assert math.isnan(s["b"][1][0]) and s["b"][2] is None
    with pytest.raises(ConfigError, match="cannot read"):
        read_overlay(tmp_path / "missing.csv")


# ---------------------------------------------------------------- against the swept variable
# Ω swept at one K: the table and the figures run against Ω, not five dots stacked at K.
OMEGA_SWEEP = ("sweep", PRESET, "--plate-rpm", "100,150,200", "--ratio", -1, "--duration", 0.1, "--workers", 2)


@pytest.fixture(scope="module")
def omega_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("omega") / "omega.zarr"
    res = taimill(*OMEGA_SWEEP, "--out", out)
    assert res.returncode == 0, res.stderr
    again = taimill(*OMEGA_SWEEP, "--out", out, "--json")  # resumes: every point done
    assert again.returncode == 0, again.stderr
    return out, res.stdout, json.loads(again.stdout)


def test_a_plate_speed_sweep_is_tabled_and_drawn_against_omega(omega_sweep):
    from taimill.analysis.sweep import axis_label
    from taimill.figures.sweep import FIGURES, figure_stems, store_axes, sweep_figure

    path, text, rows = omega_sweep
    lines = text.splitlines()
    assert lines[0].startswith("every point:") and "K = -1" in lines[0]  # the fixed K, said once
    header = lines[1].split()
    assert header[:3] == ["point", "Ω", "rpm"] and "K" not in header  # Ω is the axis column
    assert [float(ln.split()[1]) for ln in lines[2:5]] == [100.0, 150.0, 200.0]
    store = open_sweep(path)
    table = store.table()
    axes = store_axes(store, table)
    assert (axes.x, axes.y, axes.curves) == ("plate_rpm", None, ())
    _, title, panels, ylabel, scale = FIGURES[2]
    fig = sweep_figure(table, title, panels, ylabel, scale, axes=axes)
    ax = fig.axes[0]
    assert ax.get_xlabel() == axis_label("plate_rpm") and "Ω" in ax.get_xlabel()
    (line,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == 3]
    assert list(line.get_xdata()) == [100.0, 150.0, 200.0]
    assert list(line.get_ydata()) == pytest.approx([r["impact_power"] for r in rows])
    assert "map_impact_power" not in figure_stems(table)
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_sweep_rows_and_table_carry_regime_class_wall_lag_and_power(omega_sweep):
    from taimill.analysis.regime import MAP_REGIMES

    path, text, rows = omega_sweep
    header = text.splitlines()[1]
    for h in ("wall lag", "regime", "class", "P_I W", "P_diss W"):
        assert h in header
    assert "P_I mill W" in header and "P_diss mill W" in header  # the default mill, the P 4: two stations
    table = open_sweep(path).table()
    for r in rows:
        assert r["regime_class"] in (*MAP_REGIMES, "unknown") and "wall_lag" in r and "slip_ratio" in r
        assert r["units"]["wall_lag"] == "1" and r["stations"] == 2
        assert r["impact_power_mill"] == 2 * r["impact_power"]
        assert numbers_without_unit(r) == []
    assert {"regime_class", "wall_lag", "slip_ratio", "dissipated_power"} <= set(table)


def test_a_plate_speed_by_k_sweep_is_drawn_as_a_map(tmp_path):
    from matplotlib.collections import QuadMesh

    from taimill.figures.sweep import figure_stems, store_axes
    from taimill.figures.sweep_map import map_figure

    out = tmp_path / "map.zarr"
    res = taimill("sweep", PRESET, "--plate-rpm", "100,200", "--ratio", "-1,-2.5", "--duration", 0.1, "--workers", 2,
                  "--out", out)
    assert res.returncode == 0, res.stderr
    header = res.stdout.splitlines()[1].split()
    assert header[:4] == ["point", "Ω", "rpm", "K"]  # both axes vary: both are columns
    store = open_sweep(out)
    table = store.table()
    axes = store_axes(store, table)
    assert (axes.x, axes.y, axes.curves) == ("ratio", "plate_rpm", ("plate_rpm",))  # equal counts: K across, Ω up
    assert {"map_impact_power", "map_dissipated_power"} <= set(figure_stems(table))
    fig = map_figure(table, "impact_power", "impact power (W)", 1.0, axes)
    ax = fig.axes[0]
    assert "K" in ax.get_xlabel() and "Ω" in ax.get_ylabel()
    (mesh,) = [c for c in ax.collections if isinstance(c, QuadMesh)]
    assert mesh.get_array().size == 4  # 2 × 2 cells, the replicas' mean each
    assert np.nanmax(mesh.get_array()) == pytest.approx(max(table["impact_power"]))
    assert any(ln.get_marker() in ("s", "^", "o", ">", "D", "x") for ln in ax.get_lines())  # regime class markers
    import matplotlib.pyplot as plt

    plt.close(fig)
    names = sorted(p.name for p in report_sweep(out, tmp_path / "fig"))
    assert "map_impact_power.png" in names and "regimes.png" in names


def test_sweep_axes_are_derived_from_the_points():
    from taimill.analysis.sweep import sweep_axes, varying_axes

    n = 6
    base = {"point": np.arange(n), "seed": np.arange(n), "replica": np.zeros(n, int), "jar": np.array(["CY"] * n),
            "balls": np.full(n, 12), "plate_rpm": np.full(n, 200.0), "ratio": np.full(n, -2.0)}
    # a pair sweep: its coefficients vary with it, one axis named by the pair
    t = base | {"pair_name": np.array(["steel-steel", "steel-fluorite"] * 3), "mu": np.array([0.5, 0.2] * 3),
                "pair": np.array(["steel-steel", "steel-fluorite"] * 3), "ratio": np.repeat([-1.0, -2.0, -3.0], 2)}
    ax = sweep_axes(t)
    assert (ax.x, ax.curves) == ("ratio", ("pair_name",)) and "jar" in ax.fixed
    # a μ sweep: the pair's label changes with μ, the axis is μ; ball count × K: the longer is x
    t = base | {"mu": np.linspace(0.1, 0.6, n), "pair": np.array([f"steel-steel, μ {m:g}" for m in np.linspace(0.1, 0.6, n)])}
    assert varying_axes(t) == ["mu"] and sweep_axes(t).x == "mu"
    t = base | {"balls": np.repeat([6, 12], 3), "ratio": np.tile([-1.0, -2.0, -3.0], 2)}
    ax = sweep_axes(t)
    assert (ax.x, ax.y) == ("ratio", "balls")
    # an unknown text axis (a mill): one curve per value; only text axes: the first is x
    t = base | {"mill": np.repeat(["P 4", "PM 100"], 3), "ratio": np.tile([-1.0, -2.0, -3.0], 2)}
    assert sweep_axes(t).curves == ("mill",)
    t = base | {"maker_model": np.array(["a", "b", "c"] * 2)}
    ax = sweep_axes(t, ["maker_model"])
    assert ax.x == "maker_model" and ax.text_x


def test_sweep_prints_every_distinct_warning_once_before_running(monkeypatch):
    import dataclasses

    import inprocess
    import taimill.runs.sweep as sweep

    real_plan = sweep.plan

    def plan(req, ratios_for=None):
        points = real_plan(req, ratios_for)
        for n, p in enumerate(points):
            p["preset"] = dataclasses.replace(p["preset"], warnings=("plate radius is an estimate", f"odd point {n % 2}"))
        return points

    def run_sweep(*a, **k):
        raise KeyboardInterrupt("stopped by the test")

    monkeypatch.setattr(sweep, "plan", plan)
    monkeypatch.setattr(sweep, "run_sweep", run_sweep)
    code, out, err = inprocess.main("sweep", ROOT / PRESET, "--ratio", "-1,-2,-3", "--duration", 0.1)
    assert code == 130
    lines = err.splitlines()
    warned = [ln for ln in lines if ln.startswith("taimill: warning:")]
    assert warned == ["taimill: warning: plate radius is an estimate", "taimill: warning: odd point 0",
                      "taimill: warning: odd point 1"]
    assert lines.index(warned[-1]) < lines.index("taimill: stopped by the test")


def test_sweep_table_adds_the_whole_mill_where_the_points_name_their_stations():
    from taimill.cli.sweep import sweep_table

    rows = [{"point": i, "jar": "CY", "balls": 12, "pair": "steel-steel", "plate_rpm": rpm, "ratio": -1.0, "seed": 1,
             "impact_power": 0.1 * i, "dissipated_power": 0.02, "regime": "cataracting", "regime_class": "cataracting",
             "wall_lag": 0.5} for i, rpm in enumerate((100.0, 200.0))]
    alone = sweep_table(rows)
    assert "mill" not in alone and "Ω rpm" in alone.splitlines()[1]
    milled = sweep_table([r | {"stations": 4, "impact_power_mill": 4 * r["impact_power"],
                               "dissipated_power_mill": 0.08} for r in rows])
    header = milled.splitlines()[1]
    assert "P_I mill W" in header and "P_diss mill W" in header and "(4 stations)" in milled.splitlines()[-1]


def test_text_axes_are_curves_with_one_legend_entry_each_or_categories_on_x():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from taimill.figures.sweep import FIGURES, sweep_figure

    n = 6
    geometry = {"plate_radius": np.full(n, 0.125), "ball_radius": np.full(n, 0.006), "regime": np.array(["cataracting"] * n),
                "point": np.arange(n), "balls": np.full(n, 12), "plate_rpm": np.full(n, 200.0), "mean_se": np.linspace(1e-3, 2e-3, n)}
    # jars × K: K across, one curve per jar, each once in the legend
    t = geometry | {"jar": np.repeat(["CY", "HM"], 3), "jar_radius": np.repeat([0.0325, 0.034], 3),
                    "ratio": np.tile([-1.0, -2.0, -3.0], 2)}
    _, title, panels, ylabel, scale = FIGURES[0]
    fig = sweep_figure(t, title, panels, ylabel, scale)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert [lab for lab in labels if lab in ("CY", "HM")] == ["CY", "HM"] and "K" in fig.axes[0].get_xlabel()
    plt.close(fig)
    # jars alone at one K: the jars are the x axis, as categories
    t = geometry | {"jar": np.array(["CY", "HM", "T"] * 2), "jar_radius": np.array([0.0325, 0.034, 0.03] * 2),
                    "ratio": np.full(n, -2.0)}
    fig = sweep_figure(t, title, panels, ylabel, scale)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "jar" and [tk.get_text() for tk in ax.get_xticklabels()] == ["CY", "HM", "T"]
    plt.close(fig)


def test_the_shared_line_lists_only_what_every_point_shares():
    # a filling gives each bowl volume its own ball count: the line said "23 balls" while
    # the 250 ml points had 72; a column that varies with an axis is shown per row
    from taimill.cli.sweep import sweep_table

    rows = [{"point": i, "jar": j, "balls": b, "pair": "dry-ceramic-powder", "ratio": -1.0, "plate_rpm": 400.0,
             "seed": 1, "dissipated_power": 1.0 + i, "regime": "rolling", "regime_class": "sliding bed"}
            for i, (j, b) in enumerate([("retsch-80ml", 23), ("retsch-250ml", 72)])]
    first, head, *lines = sweep_table(rows).splitlines()
    assert first == "every point: dry-ceramic-powder, Ω = 400 rpm, K = -1"
    assert "balls" in head and lines[0].split()[2] == "23" and lines[1].split()[2] == "72"
