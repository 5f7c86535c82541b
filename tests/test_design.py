"""The jar designer (`taimill design`, docs/designer.md): families make valid jars, the
maker's constraints name their values, bad input is one line, the same seed gives the
same designs, a study killed with SIGKILL resumes to the same designs, and a designed
jar passes the jar checks, draws, and exports to LIGGGHTS. Studies here are tiny (4
designs, 1.2 s runs); the acceptance study is scripts/design_cy_steel.py."""

from __future__ import annotations

import json
import math
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from inprocess import main
from taimill.design import constraints, families
from taimill.design.report import pareto
from taimill.model.jars import load_jar

ROOT = Path(__file__).resolve().parent.parent
TINY = ("design", "presets/p4-cy-steel.toml", "--trials", 4, "--batch", 2, "--replicas", 2, "--duration", 1.2,
        "--analysis-start", 1.0, "--ratio=-3:-2", "--references", "CY,HM", "--reference-ratios=-2.6", "--workers", 2,
        "--seed", 7, "--json")


def cy_limits(min_wall=1e-3, tolerance=0.3):
    cy = load_jar("CY")
    return constraints.Limits(cy.radius, cy.volume, tolerance, 6e-3, min_wall)


def jar_of(tmp_path, params, name="j"):
    path = tmp_path / f"{name}.toml"
    path.write_text(families.jar_text(params, 32.5, 24.1, "aisi-304", "test"))
    return load_jar(str(path), "test")


# ------------------------------------------------------------------ families and constraints
def test_the_thesis_jars_meet_the_constraints_of_the_cy_station():
    for name in ("CY", "HM", "1L", "3L", "T"):
        assert constraints.violations(load_jar(name), cy_limits()) == [], name


def test_every_family_makes_jar_files_the_loader_takes(tmp_path):
    rng = np.random.default_rng(3)
    for fam in families.FAMILIES.values():
        valid = 0
        for i in range(12):
            params = {p.name: int(rng.integers(p.lo, p.hi + 1)) if p.integer else float(rng.uniform(p.lo, p.hi))
                      for p in fam.params(32.5, 6.0)}
            try:
                jar = jar_of(tmp_path, params, f"{fam.name}{i}")
            except Exception as err:  # a shape the geometry refuses is pruned, by this one-line error
                assert "cannot build the cross-section" in str(err) or "allowed range" in str(err), err
                continue
            valid += 1
            assert abs(next(v["radius"] for k, v in jar.primitives if k == "circle") - 32.5e-3) < 1e-12
        assert valid >= 3, fam.name


def test_family_parameters_map_to_the_primitives(tmp_path):
    jar = jar_of(tmp_path, {"n_lifters": 3, "lifter_radius_mm": 4.85, "lifter_protrusion_mm": 4.85,
                            "lifter_spread": 1.0, "fillet_mm": 8.0})
    ref = load_jar("3L")  # the thesis' 3L: r = 4.85 mm discs centred on the wall at 120°
    assert jar.primitives == ref.primitives and jar.fillet == ref.fillet
    assert abs(jar.volume - ref.volume) < 1e-12


def test_each_violation_names_its_value(tmp_path):
    lim = cy_limits(min_wall=2e-3, tolerance=0.1)
    small_fillet = jar_of(tmp_path, {"n_flats": 1, "flat_depth_mm": 3.0, "flat_spread": 1.0, "fillet_mm": 4.0}, "a")
    bad = constraints.violations(small_fillet, lim)
    assert any(v.startswith("fillet_mm = 4: must be ≥ the ball radius 6 mm") for v in bad), bad
    deep = jar_of(tmp_path, {"n_flats": 3, "flat_depth_mm": 12.0, "flat_spread": 1.0, "fillet_mm": 8.0}, "b")
    (vol,) = constraints.violations(deep, lim)
    assert vol.startswith("volume = ") and "allowed range [" in vol and "] ml" in vol
    shallow = jar_of(tmp_path, {"n_lifters": 1, "lifter_radius_mm": 5.0, "lifter_protrusion_mm": 1.5,
                                "lifter_spread": 1.0, "fillet_mm": 6.0}, "c")
    (thin,) = constraints.violations(shallow, lim)
    assert thin.startswith("thinnest insert = ") and "must be ≥ 2 mm" in thin
    assert abs(float(thin.split()[3]) - 1.5) <= constraints.GRID_MM  # the lifter reaches 1.5 mm in
    wide = jar_of(tmp_path, {}, "d")
    assert constraints.violations(wide, constraints.Limits(30e-3, wide.volume, 0.1, 6e-3, 1e-3))[0].startswith(
        "curved wall radius = 32.5 mm: must be the station's 30 mm")


def test_the_pareto_set_keeps_the_feasible_undominated_designs():
    from taimill.design.protocol import Objective

    objs = [Objective("a", "maximize"), Objective("b", "minimize")]

    def row(a, b, ok=True):
        return {"figures": {"a": [a, 0, []], "b": [b, 0, []]}, "feasible": ok}

    rows = [row(1, 1), row(2, 2), row(1.5, 3), row(3, 0, ok=False), row(0.5, 0.5)]
    assert [(r["figures"]["a"][0], r["figures"]["b"][0]) for r in pareto(rows, objs)] == [(2, 2), (1, 1), (0.5, 0.5)]


@pytest.mark.parametrize("args, key", [
    (("--objective", "no_such_figure:max"), "--objective = no_such_figure:max"),
    (("--objective", "impact_power:up"), "--objective = impact_power:up"),
    (("--floor", "impact_power=lots"), "--floor = impact_power=lots"),
    (("--ratio", "a:b"), "--ratio = a:b"),
    (("--tolerance", 0), "--tolerance = 0"),
    (("--family", "spirals"), "--family = spirals"),
    (("--fix", "n_teeth=3"), "--fix = n_teeth"),
    (("--fix", "n_lifters=9"), "--fix = n_lifters=9: allowed range [1, 4], an integer"),
    (("--references", "NOPE"), "--references = NOPE"),
    (("--trials", 0), "--trials = 0"),
])
def test_bad_input_is_one_line_naming_the_option(tmp_path, args, key):
    code, out, err = main("design", "--out", tmp_path / "s", *args)
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert key in err.replace("'", ""), err
    assert not (tmp_path / "s").exists()  # refused before anything is written


def test_an_out_folder_of_other_files_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    code, _, err = main("design", "--out", tmp_path)
    assert code == 2 and "no study.db" in err and err.count("\n") == 1


# ------------------------------------------------------------------ studies (real runs)
def designs(out: Path) -> list:
    """Every live trial's (state, parameters, objective values, figures) from the study's
    SQLite file, in order (a trial abandoned by a kill during its ask is left out)."""
    import optuna

    study = optuna.load_study(study_name="design", storage=f"sqlite:///{out / 'study.db'}")
    return [(t.state.name, t.params, t.values, t.user_attrs.get("figures")) for t in study.trials
            if not t.user_attrs.get("abandoned")]


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("design") / "study"
    code, stdout, err = main(*TINY, "--out", out)
    assert code == 0, err
    return out, json.loads(stdout)


def test_a_study_writes_ready_jars_a_report_and_reference_points(tiny_study):
    out, res = tiny_study
    assert res["evaluated"] == 4 and set(res["references"]) == {"CY", "HM"}
    assert res["spread"].startswith("sample standard deviation")
    for name in ("report.png", "summary.json", "summary.md", "study.db"):
        assert (out / name).stat().st_size > 0, name
    best = sorted((out / "best").glob("*.toml"))
    assert best and len(best) == len(res["best"])
    text = best[0].read_text()
    m, s, values = res["best"][0]["figures"]["impact_power_normal"]
    assert f"impact_power_normal = {m:.5g} ± {s:.2g} W (mean ± sample s.d. of 2 replicas)" in text
    assert len(values) == 2 and math.isclose(s, float(np.std(values, ddof=1)), rel_tol=1e-9)
    assert "reference CY" in (out / "summary.md").read_text()


def test_the_same_seed_gives_the_same_designs(tiny_study, tmp_path):
    out, _ = tiny_study
    again = tmp_path / "again"
    code, _, err = main(*TINY, "--out", again)
    assert code == 0, err
    assert designs(again) == designs(out)
    assert any(state == "COMPLETE" for state, *_ in designs(out))


def test_a_study_resumed_with_other_settings_is_refused_naming_them(tiny_study):
    out, _ = tiny_study
    args = list(TINY)
    args[args.index("--replicas") + 1] = 3
    code, stdout, err = main(*args, "--out", out)
    assert code == 2 and stdout == "" and err.count("\n") == 1, err
    assert "settings = replicas" in err.replace("'", "") and "give the same options to resume it" in err


def _query(db: Path, sql: str) -> list:
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1) as c:
            return c.execute(sql).fetchall()
    except sqlite3.Error:
        return []


def _states(db: Path) -> list[str]:
    return [s for (s,) in _query(db, "SELECT state FROM trials ORDER BY number")]


def _checked_running(db: Path) -> int:
    """RUNNING trials whose constraints passed: asked, written, about to run or running."""
    return len(_query(db, "SELECT t.number FROM trials t JOIN trial_user_attributes a ON a.trial_id = t.trial_id "
                          "WHERE t.state = 'RUNNING' AND a.key = 'violations' AND a.value_json = '[]'"))


# "evaluating": the second batch asked and running (its trials are re-run with their
# stored parameters); "asking": a trial just created, maybe without its parameters
# (it is abandoned and asked again)
@pytest.mark.parametrize("moment", ["evaluating", "asking"])
def test_kill_9_mid_study_then_the_same_command_ends_with_the_same_designs(tiny_study, tmp_path, moment):
    out, _ = tiny_study
    killed = tmp_path / "killed"
    db = killed / "study.db"
    # the references do not change the designs: left out here, the test runs in < 60 s
    cmd = [sys.executable, "-m", "taimill", *map(str, TINY), "--references", "none", "--out", str(killed)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    ready = {"evaluating": lambda: _states(db).count("COMPLETE") >= 2 and _checked_running(db) == 2,
             "asking": lambda: _states(db).count("COMPLETE") >= 2 and "RUNNING" in _states(db)
             and _checked_running(db) == 0}[moment]
    while not ready():
        assert proc.poll() is None, proc.stderr.read()
        assert time.monotonic() - t0 < 120, "the study never reached its second batch"
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert "RUNNING" in _states(db)
    unchecked = len(_query(db, "SELECT trial_id FROM trials WHERE state = 'RUNNING' AND trial_id NOT IN "
                              "(SELECT trial_id FROM trial_user_attributes WHERE key = 'violations')"))  # caught while asked
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert designs(killed) == designs(out)
    abandoned = _query(db, "SELECT COUNT(*) FROM trial_user_attributes WHERE key = 'abandoned'")[0][0]
    assert abandoned == unchecked


def test_every_designed_jar_passes_the_checks_draws_and_exports_to_liggghts(tiny_study, tmp_path):
    out, res = tiny_study
    import optuna

    study = optuna.load_study(study_name="design", storage=f"sqlite:///{out / 'study.db'}")
    for t in study.trials:  # every design that ran is a valid jar within the constraints
        if t.state.name == "COMPLETE":
            jar = load_jar(str(out / "jars" / f"trial-{t.number:05d}.toml"), "test")
            assert constraints.violations(jar, cy_limits()) == [], t.number
            assert t.user_attrs["status"] == ["complete"]  # and it ran: every replica to its end
    for i, best in enumerate(res["best"]):
        jar_file = Path(best["file"])
        assert constraints.violations(load_jar(str(jar_file), "test"), cy_limits()) == []
        code, _, err = main("jars", "show", jar_file, "--out", tmp_path / f"jar{i}.png")
        assert code == 0 and (tmp_path / f"jar{i}.png").stat().st_size > 0, err
        case = tmp_path / f"case{i}"
        code, _, err = main("export", "liggghts", "p4-cy-steel", "--jar", jar_file, "--ratio", best["ratio"], "--out", case)
        assert code == 0, err
        files = {p.name for p in case.rglob("*") if p.is_file() and p.stat().st_size > 0}
        assert {"in.taimill", "run.sh", "jar.stl", "start.data"} <= files, files
        assert (case / "jar.stl").read_text().count("facet normal") > 100  # the designed profile, not a primitive


def test_several_objectives_give_a_pareto_set_and_a_floor_is_a_constraint(tmp_path):
    out = tmp_path / "pareto"
    code, stdout, err = main("design", "presets/p4-cy-steel.toml", "--out", out, "--family", "flats",
                             "--objective", "impact_power_normal:max", "--objective", "normal_fraction:max",
                             "--floor", "impact_power=0", "--trials", 4, "--batch", 2, "--replicas", 2,
                             "--duration", 1.2, "--analysis-start", 1.0, "--ratio=-2.6", "--references", "none",
                             "--workers", 2, "--json")
    assert code == 0, err
    res = json.loads(stdout)
    front = res["best"]
    assert front and len(list((out / "best").glob("design-*.toml"))) == len(front)
    for a in front:  # no design of the set is dominated by another
        for b in front:
            fa, fb = a["figures"], b["figures"]
            assert not (fb["impact_power_normal"][0] > fa["impact_power_normal"][0]
                        and fb["normal_fraction"][0] > fa["normal_fraction"][0])
    import optuna

    study = optuna.load_study(study_name="design", storage=f"sqlite:///{out / 'study.db'}")
    done = [t for t in study.trials if t.state.name == "COMPLETE"]
    assert done and all("floor impact_power" in t.constraints for t in done)
    assert (out / "report.png").stat().st_size > 0


def test_a_study_on_a_dask_cluster_gives_the_same_designs(tiny_study, tmp_path):
    from distributed import LocalCluster

    out, _ = tiny_study
    args = [str(a) for a in TINY]
    args[args.index("--workers"):args.index("--workers") + 2] = []  # the cluster's workers run the runs
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        res = subprocess.run([sys.executable, "-m", "taimill", *args, "--references", "none", "--out", str(tmp_path / "d"),
                              "--scheduler", cluster.scheduler_address], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert designs(tmp_path / "d") == designs(out)


def test_a_study_whose_every_design_breaks_a_constraint_stops_with_one_line(tmp_path):
    # three flats 19 mm deep leave too little volume (or no valid profile): nothing runs
    code, out, err = main("design", "--out", tmp_path / "s", "--family", "flats", "--fix", "n_flats=3",
                          "--fix", "flat_depth_mm=19", "--trials", 2, "--batch", 1, "--references", "none")
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "constraints = 50 designs in a row: every one broke a constraint" in err.replace("'", "")


# ------------------------------------------------------------------ other mills, the charge, the run line
def taimill(*args, cwd):
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env={**__import__("os").environ, "PYTHONPATH": str(ROOT)})


def test_a_fixed_gear_mill_is_designed_at_its_gear_with_the_charge_options_and_a_pastable_run_line(tmp_path):
    # a preset file of the user's own, named relative to the folder the study is run from
    (tmp_path / "mine.toml").write_text((ROOT / "presets/p4-cy-steel.toml").read_text())
    res = taimill("design", "mine.toml", "--out", "study", "--mill", "retsch-pm100", "--jar-volume", 80,
                  "--jar-material", "zirconia", "--powder-mass", 10, "--objective", "specific_power_W_per_g:max",
                  "--floor", "specific_power_W_per_g=0", "--references", "retsch-80ml", "--trials", 1, "--batch", 1,
                  "--replicas", 1, "--duration", 0.3, "--analysis-start", 0.1, "--workers", 1, "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    s = out["settings"]
    assert s["ratio"] == [-1, -1] and "ratio" not in out["searched"]  # the PM 100's gear 1:-2, not searched
    assert s["overrides"]["jar_volume_ml"] == 80 and s["overrides"]["jar_material"] == "zirconia"
    assert s["overrides"]["powder.mass_g"] == 10
    assert set(out["references"]) == {"retsch-80ml"}
    assert math.isfinite(out["best"][0]["figures"]["specific_power_W_per_g"][0])
    design = tmp_path / "study" / "best" / "design-1.toml"
    jar = load_jar(str(design), "test")
    bowl = load_jar("retsch-80ml")
    assert jar.wall_material == "zirconia" and jar.height == bowl.height
    assert math.isclose(next(v["radius"] for k, v in jar.primitives if k == "circle"), bowl.radius)  # the bowl's size
    (line,) = [x for x in design.read_text().splitlines() if "Run it" in x]
    command = line.partition("): ")[2]
    assert command.startswith("taimill run ") and str(tmp_path) not in line and " /" not in command, line
    assert "--mill retsch-pm100" in command and "--ratio" not in command, line  # K is the gear's
    import shlex

    pasted = taimill(*shlex.split(command)[1:], "--dry-run", cwd=tmp_path / "study")  # from the study folder
    assert pasted.returncode == 0, pasted.stderr


def test_a_ratio_on_a_fixed_gear_mill_is_refused_in_one_line_naming_the_gear(tmp_path):
    res = taimill("design", "--mill", "retsch-pm100", "--ratio=-3:-2", "--out", "s", cwd=tmp_path)
    assert res.returncode == 2 and res.stdout == "" and res.stderr.count("\n") == 1, res.stderr
    assert "--ratio" in res.stderr and "retsch-pm100 has a fixed gear 1:-2 (K = -1)" in res.stderr, res.stderr
    assert not (tmp_path / "s").exists()
