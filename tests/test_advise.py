"""`taimill advise`: the friction levels it sweeps (a measured pair as it is, an estimate
at 0.1, its μ_d and 0.8), the plate speeds it spreads over a mill's range, the "hinges on
μ" flag and the recommendation (pure functions on synthetic sweep rows: a best speed
that moves with μ and one that does not), and the real command in a subprocess on a
tiny PM 100 charge: every speed and μ level in the table, the JSON, the figure, the
store resumed, and bad input refused in one line."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from taimill.analysis.advise import (SPREAD_FACTOR, across_mu, best_speeds, default_measure, hinges, recommendation,
                                     speed_rows, with_best)
from taimill.errors import ConfigError

ROOT = Path(__file__).resolve().parent.parent


def taimill(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT)})


def row(rpm, mu, power, cls="hopping bed", led="friction-led", seed=0, impact=0.01, **extra):
    """One sweep row (a point × replica) as run_sweep returns it, with what advise reads."""
    return {"plate_rpm": float(rpm), "mu": mu, "mu_d": mu, "seed": seed, "dissipated_power": power,
            "impact_power": impact, "regime_class": cls, "power_led": led, **extra}


def table(rows, measure="dissipated_power"):
    return with_best(speed_rows(rows, measure))


# ---------------------------------------------------------------- the flag
def by_mu(*levels):
    """by_mu entries of one speed: (μ, classes, power-led labels, mean power)."""
    return [{"mu": mu, "regime_classes": list(c), "power_led": list(led), "power_mean": p} for mu, c, led, p in levels]


def test_the_flag_is_up_where_the_class_changes_across_mu():
    assert hinges(by_mu((0.1, ["sliding bed"], ["friction-led"], 1.0), (0.8, ["hopping bed"], ["friction-led"], 1.1))) \
        == ["class"]


def test_the_flag_is_up_where_the_power_led_verdict_changes_across_mu():
    assert hinges(by_mu((0.1, ["cataracting"], ["impact-led"], 1.0), (0.8, ["cataracting"], ["friction-led"], 1.2))) \
        == ["power-led verdict"]


def test_the_flag_is_up_where_the_power_spreads_beyond_the_factor_and_down_below_it():
    assert SPREAD_FACTOR == 1.5
    same = (["hopping bed"], ["friction-led"])
    assert hinges(by_mu((0.1, *same, 1.0), (0.2, *same, 1.2), (0.8, *same, 1.6))) == ["power ×1.6"]
    assert hinges(by_mu((0.1, *same, 1.0), (0.8, *same, 1.45))) == []
    assert hinges(by_mu((0.1, *same, 0.0), (0.8, *same, 0.3))) == ["power 0 to 0.3"]
    assert hinges(by_mu((0.1, *same, 0.0), (0.8, *same, 0.0))) == []  # nothing dissipated anywhere: nothing spreads


def test_every_reason_is_named_and_one_mu_never_hinges():
    assert hinges(by_mu((0.1, ["sliding bed"], ["friction-led"], 0.1), (0.8, ["cataracting"], ["impact-led"], 1.0))) \
        == ["class", "power-led verdict", "power ×10"]
    assert hinges(by_mu((0.67, ["cataracting"], ["impact-led"], 1.0))) == []


def test_a_mu_without_dissipation_has_no_verdict_to_change():
    assert hinges(by_mu((0.1, ["sliding bed"], [], math.nan), (0.8, ["sliding bed"], ["friction-led"], 1.0))) == []


def test_the_classes_across_mu_read_as_a_sequence():
    levels = [{"mu": 0.1, "c": ["sliding bed"]}, {"mu": 0.2, "c": ["sliding bed"]}, {"mu": 0.8, "c": ["hopping bed"]}]
    assert across_mu(levels, "c") == "sliding bed (μ 0.1, 0.2) → hopping bed (μ 0.8)"
    assert across_mu(levels[:2], "c") == "sliding bed"
    levels[1]["c"] = ["sliding bed", "rolling bed"]  # the replicas at μ 0.2 disagree
    assert across_mu(levels, "c") == "sliding bed (μ 0.1) → sliding bed / rolling bed (μ 0.2) → hopping bed (μ 0.8)"


def test_speed_rows_hold_every_speed_and_mu_with_the_replicas_range():
    rows = [row(300, mu, p, seed=s) for mu, ps in ((0.1, (1.0, 3.0)), (0.8, (2.0, 2.0))) for s, p in enumerate(ps)]
    rows += [row(600, 0.1, 5.0, cls="sliding bed"), row(600, 0.8, 6.0)]
    t = table(rows)
    assert [r["plate_rpm"] for r in t] == [300.0, 600.0]
    first = t[0]
    assert [m["mu"] for m in first["by_mu"]] == [0.1, 0.8] and first["by_mu"][0]["replicas"] == 2
    assert (first["power_mean"], first["power_min"], first["power_max"]) == (2.0, 1.0, 3.0)  # over replicas and μ
    assert first["hinges_on_mu"] is False and first["classes_across_mu"] == "hopping bed"
    assert t[1]["hinges_on_mu"] is True and t[1]["hinges_why"] == ["class"]
    assert t[1]["best_at_mu"] == [0.1, 0.8] and t[0]["best_at_mu"] == []


# ---------------------------------------------------------------- the recommendation
def test_one_best_speed_at_every_mu():
    rows = [row(rpm, mu, p) for mu in (0.1, 0.2, 0.8) for rpm, p in ((300, 1.0 + mu), (650, 4.0 + mu))]
    assert recommendation(table(rows), "dissipated_power") == "highest dissipated power at 650 rpm in every μ tried (0.1, 0.2, 0.8)"


def test_a_best_speed_that_depends_on_mu_names_each_and_the_closest_to_all():
    # μ 0.1: a slow bed takes most; μ 0.4: the fast crescent; 450 rpm is ≥ 80 % of both bests
    values = {0.1: {300: 1.0, 450: 0.9, 650: 0.5}, 0.4: {300: 0.5, 450: 1.6, 650: 2.0}}
    rows = [row(rpm, mu, p) for mu, ps in values.items() for rpm, p in ps.items()]
    line = recommendation(table(rows), "dissipated_power")
    assert line.startswith("the best speed depends on μ: 300 rpm at μ 0.1; 650 rpm at μ 0.4")
    assert "closest to every μ's best: 450 rpm (at least 80% of the best at each μ)" in line


def test_the_recommendation_follows_the_chosen_measure():
    rows = [row(300, 0.2, 1.0, mean_se=0.004), row(650, 0.2, 3.0, mean_se=0.002)]
    assert recommendation(table(rows, "mean_se"), "mean_se") == "highest mean stress energy at 300 rpm at μ 0.2"
    assert recommendation(table(rows), "dissipated_power") == "highest dissipated power at 650 rpm at μ 0.2"


def test_a_runner_up_within_the_replicas_spread_and_a_hinging_speed_are_said():
    rows = [row(300, 0.2, p, seed=s) for s, p in enumerate((0.9, 1.3))] + \
           [row(650, 0.2, p, seed=s) for s, p in enumerate((1.0, 1.4))] + \
           [row(300, 0.8, 0.5), row(650, 0.8, 2.0, cls="cataracting")]
    line = recommendation(table(rows), "dissipated_power")
    assert "highest dissipated power at 650 rpm in every μ tried (0.2, 0.8)" in line
    assert "within the replicas' spread of the best: 300 rpm at μ 0.2" in line
    assert "at 650 rpm the answer hinges on μ (class, power ×1.67)" in line


def test_mu_levels_with_nothing_to_maximise_are_named():
    rows = [row(rpm, mu, 1.0, impact=imp) for mu, imps in ((0.1, (0.0, 0.0)), (0.8, (0.1, 0.3)))
            for rpm, imp in zip((300, 650), imps)]
    t = table(rows, "impact_power")
    assert best_speeds(t)[0.1] is None
    assert recommendation(t, "impact_power") == ("highest impact power (kinematic stress energy) at 650 rpm at every μ "
                                                "that gives any (0.8); no impact power (kinematic stress energy) at μ 0.1 "
                                                "at any speed")
    none = table([row(300, 0.1, 1.0, impact=0.0)], "impact_power")
    assert recommendation(none, "impact_power").startswith("no speed gives any impact power")


def test_the_default_measure_is_the_dissipated_power_never_impacts():
    assert default_measure(False) == "dissipated_power"
    assert default_measure(True) == "specific_power_W_per_g"


def test_the_figure_draws_one_curve_per_mu_with_the_classes_and_its_legend_off_the_data():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from taimill.figures.advise import advise_figure

    rows = [row(rpm, mu, p * (1 + mu), seed=s, cls="sliding bed" if mu < 0.5 else "hopping bed")
            for mu in (0.1, 0.8) for rpm, p in ((300, 1.0), (650, 3.0)) for s in (0, 1)]
    rows[1]["dissipated_power"] *= 1.2  # a replica band at 300 rpm, μ 0.1
    fig = advise_figure(table(rows), "a charge")
    ax = fig.axes[0]
    labels = ax.get_legend_handles_labels()[1]
    assert labels[:2] == ["μ 0.1", "μ 0.8"] and {"sliding bed", "hopping bed", "best speed at that μ"} <= set(labels)
    fig.canvas.draw()
    assert not ax.get_legend().get_window_extent().overlaps(ax.get_window_extent())
    plt.close(fig)


# ---------------------------------------------------------------- levels and speeds
def test_an_estimated_pair_runs_at_the_span_of_coated_to_bare_media_a_measured_one_as_it_is():
    from taimill.model.preset import load_preset
    from taimill.runs.advise import mu_levels

    levels, why = mu_levels(load_preset("p4-cy-steel", {"pair": "dry-ceramic-powder"}))
    assert levels == [0.1, 0.2, 0.8] and "estimate" in why
    levels, why = mu_levels(load_preset("p4-cy-steel", {"pair": "steel-steel"}))
    assert levels is None and "measured" in why
    levels, why = mu_levels(load_preset("p4-cy-steel", {"friction.mu_s": 0.5, "friction.mu_d": 0.5}))
    assert levels == [0.1, 0.5, 0.8] and "by hand" in why  # a measured pair tuned by hand: no source


def test_default_speeds_spread_over_the_mills_range():
    from taimill.model.mills import load_mill
    from taimill.runs.advise import default_speeds

    assert default_speeds(load_mill("retsch-pm100")) == [100.0, 240.0, 380.0, 510.0, 650.0]
    assert default_speeds(load_mill("fritsch-p7-premium")) == [150.0, 390.0, 630.0, 860.0, 1100.0]
    with pytest.raises(ConfigError, match="--plate-rpm.*fritsch-p4"):
        default_speeds(load_mill("fritsch-p4"))


# ---------------------------------------------------------------- the real command
CHARGE = ("--mill", "retsch-pm100", "--jar-volume", 80, "--jar-material", "zirconia", "--ball-material", "zirconia",
          "--ball-diameter", 5, "--balls", 6, "--pair", "dry-ceramic-powder", "--plate-rpm", "300,600",
          "--duration", 0.4, "--analysis-start", 0.2, "--replicas", 1, "--workers", 1)


@pytest.fixture(scope="module")
def advised(tmp_path_factory):
    """The tiny case once, with --json, a store and a figure (6 points of 0.4 s, one
    worker: ≈ 10 s), then its table from the stored sweep."""
    d = tmp_path_factory.mktemp("advise")
    res = taimill("advise", *CHARGE, "--out", d / "a.zarr", "--figure", d / "a.png", "--json")
    assert res.returncode == 0, res.stderr
    again = taimill("advise", *CHARGE, "--out", d / "a.zarr")  # resumes: every point is stored
    assert again.returncode == 0, again.stderr
    return d, json.loads(res.stdout), res.stderr, again.stdout, again.stderr


def test_the_json_has_every_speed_and_mu_level(advised):
    _, rows, err, _, _ = advised
    assert [r["plate_rpm"] for r in rows] == [300.0, 600.0]
    for r in rows:
        assert [m["mu"] for m in r["by_mu"]] == [0.1, 0.2, 0.8]
        assert all(m["replicas"] == 1 for m in r["by_mu"])
        assert r["power"] == r["measure"] == "dissipated_power" and r["units"]["power"] == "W"
        assert r["power_mean"] > 0 and isinstance(r["hinges_on_mu"], bool)
        assert r["hinges_on_mu"] == bool(r["hinges_why"])
        assert all(set(m["regime_classes"]) <= {"cascading", "cataracting", "hopping bed", "pinned ring", "sliding bed",
                                                "rolling bed", "unknown"} for m in r["by_mu"])
    assert sorted(mu for r in rows for mu in r["best_at_mu"]) == [0.1, 0.2, 0.8]  # one best speed per μ
    assert "taimill: recommendation: " in err and "estimate" in err


def test_the_table_has_every_speed_mu_level_and_a_recommendation(advised):
    d, rows, _, out, err = advised
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("Ω rpm"))
    assert "hinges on μ" in lines[head] and "regime class across μ" in lines[head]
    assert [ln.split()[0] for ln in lines[head + 1:head + 3]] == ["300", "600"]
    for ln, r in zip(lines[head + 1:head + 3], rows):
        assert ln.rstrip().endswith("yes: " + ", ".join(r["hinges_why"]) if r["hinges_on_mu"] else "no")
    by_mu = next(i for i, ln in enumerate(lines) if ln.startswith("dissipated power (W) by μ"))
    assert lines[by_mu + 1].split() == ["Ω", "rpm", "μ", "0.1", "μ", "0.2", "μ", "0.8"]
    assert lines[-2].startswith("recommendation: ") and "rpm" in lines[-2]
    assert "estimate" in lines[0] and "0.1, 0.2, 0.8" in lines[0]
    assert "stored in" in lines[-1]
    assert (d / "a.png").read_bytes().startswith(b"\x89PNG")


def test_a_bad_measure_is_one_line_and_exit_2(tmp_path):
    res = taimill("advise", *CHARGE, "--measure", "bogus", cwd=tmp_path)
    assert res.returncode == 2 and res.stdout == ""
    assert len(res.stderr.splitlines()) == 1 and res.stderr.startswith("taimill: error: ")
    assert "--measure" in res.stderr and "bogus" in res.stderr and "dissipated_power" in res.stderr
    assert list(tmp_path.iterdir()) == []
