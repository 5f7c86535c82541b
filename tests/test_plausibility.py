"""Plausibility checks: values that load but are likely slips (a plate radius in metres
where mm are meant, a ball radius a thousand times off, an analysis window inside the
start-up ramp, a run of hours) are refused or said in one line before anything runs;
every shipped preset passes them without a word."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from taimill.cli.run import long_run_note
from taimill.errors import ConfigError
from taimill.model import rules
from taimill.model.preset import load_preset

ROOT = Path(__file__).resolve().parent.parent
PRESETS = sorted((ROOT / "presets").glob("*.toml"))
CY = str(ROOT / "presets" / "p4-cy-steel.toml")


def _preset(tmp_path, top: str = "", radius_mm: float = 6) -> str:
    """The CY steel preset with `top` lines added and the balls' radius given."""
    text = (f'jar = "CY"\npair = "steel-steel"\nplate_rpm = 200\nratio = -2.6\nduration = 2.0\n'
            f'analysis_start = 1.0\n{top}\n[balls]\ncount = 12\nmaterial = "steel-c1020"\nradius_mm = {radius_mm}\n')
    path = tmp_path / "p.toml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_every_shipped_preset_passes_the_checks_silently(path):
    assert load_preset(path).warnings == ()


def test_a_plate_radius_below_the_jars_is_refused(tmp_path):
    # 0.07 for 70 mm: the plate's axis would lie inside the CY jar (radius 32.5 mm)
    with pytest.raises(ConfigError) as e:
        load_preset(_preset(tmp_path, "plate_radius_mm = 0.07"))
    text = str(e.value)
    assert "plate_radius_mm" in text and "0.07" in text and "(32.5, 2000] mm" in text and "\n" not in text
    assert load_preset(_preset(tmp_path, "plate_radius_mm = 70")).plate_radius == pytest.approx(0.07)


def test_a_ball_far_from_its_contact_sets_size_warns(tmp_path):
    # the steel set was measured with 6 mm balls: 0.006 (µm where mm were meant) warns,
    # 60 mm (10×) is the last size that does not; both still run
    slip = load_preset(_preset(tmp_path, radius_mm=0.006))
    assert len(slip.warnings) == 1 and "1e+03 times smaller" in slip.warnings[0] and "'steel'" in slip.warnings[0]
    assert rules.ball_size_note(0.06, 0.006, "steel") is None
    assert "larger" in rules.ball_size_note(0.0601, 0.006, "steel")
    assert rules.ball_size_note(0.006, None, "derived") is None


def test_an_analysis_window_inside_the_start_up_ramp_warns_and_says_how_to_fix_it():
    inside = load_preset(CY, {"duration": 0.9})  # the whole run inside the 1 s ramp
    assert len(inside.warnings) == 1 and "whole run (0.9 s)" in inside.warnings[0] and "--duration" in inside.warnings[0]
    partly = load_preset(CY, {"duration": 3.0, "analysis_start": 0.5})
    assert len(partly.warnings) == 1 and "starts at 0.5 s" in partly.warnings[0] and "--analysis-start" in partly.warnings[0]
    assert load_preset(CY, {"duration": 3.0, "analysis_start": 1.0}).warnings == ()


def test_warnings_are_printed_one_line_each_before_anything_runs(tmp_path):
    # through the real command line (export liggghts: loads the preset, no kernels)
    proc = subprocess.run([sys.executable, "-m", "taimill.cli", "export", "liggghts", CY, "--duration", "0.9",
                           "--out", str(tmp_path / "case")], cwd=tmp_path, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=300)
    lines = proc.stderr.splitlines()  # the preset's warning first, then the export's own (model mapping)
    assert proc.returncode == 0 and lines[0].startswith("taimill: warning: --duration 0.9 s is shorter"), proc.stderr
    assert "the whole run (0.9 s)" in lines[0] and sum("start-up ramp" in ln for ln in lines) == 1


# the analysis window of a shortened run: (options, window, words of its one warning line or None)
WINDOWS = [
    ({}, (4.0, 24.0), None),
    ({"duration": 30.0}, (4.0, 30.0), None),  # longer: the preset's start, nothing to say
    ({"duration": 6.0}, (4.0, 6.0), ["--duration 6 s is shorter than the preset's 24 s", "keeps the preset's "
                                     "analysis_start = 4 s", "window is 4 … 6 s", "--analysis-start"]),
    ({"duration": 3.0}, (0.5, 3.0), ["ends before the preset's analysis_start = 4 s", "window is 0.5 … 3 s",
                                     "inside the 1 s start-up ramp"]),
    ({"duration": 0.9}, (0.15, 0.9), ["window is 0.15 … 0.9 s", "the whole run (0.9 s) lies inside the 1 s start-up ramp"]),
    ({"duration": 3.0, "analysis_start": 1.0}, (1.0, 3.0), None),  # both given: the user's window
    ({"duration": 3.0, "analysis_start": 0.5}, (0.5, 3.0), ["starts at 0.5 s, inside the 1 s start-up ramp"]),
]


@pytest.mark.parametrize("options, window, words", WINDOWS, ids=lambda x: str(x))
def test_the_analysis_window_rule_of_short_runs(options, window, words):
    p = load_preset(CY, options)
    assert (p.analysis_start, p.duration) == pytest.approx(window)
    if words is None:
        assert p.warnings == ()
    else:
        assert len(p.warnings) == 1 and all(w in p.warnings[0] for w in words), p.warnings


@pytest.mark.parametrize("command", [["run", "{cy}", "--json"], ["sweep", "{cy}", "--ratio", "-2,-2.6", "--json"],
                                     ["export", "liggghts", "{cy}", "--out", "{tmp}/case"]], ids=lambda c: c[0])
def test_every_command_says_when_its_window_is_not_the_presets(command, tmp_path):
    # the rule lives in load_preset: run, sweep, export (and tui, record) apply it alike, each
    # saying so in one line (a sweep's points share theirs), and the stored window is the one said
    from tests.inprocess import main

    code, out, err = main(*(c.format(cy=CY, tmp=tmp_path) for c in command), "--duration", 0.3)
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if "--duration 0.3 s is shorter" in ln]
    assert len(lines) == 1 and lines[0].startswith("taimill: warning: ") and "window is 0.05 … 0.3 s" in lines[0]
    if command[0] == "run":
        assert json.loads(out)["analysis_window"] == pytest.approx([0.05, 0.3], abs=1e-3)


def test_a_run_of_more_than_a_few_minutes_states_its_estimate():
    assert long_run_note(load_preset(CY)) is None  # ≈ 4 s on one core
    note = long_run_note(load_preset(ROOT / "presets" / "p4-zr80-beads-1mm.toml"))
    assert note is not None and "30000 balls" in note and " h" in note


def test_a_pairs_friction_used_for_other_materials_is_said_once(tmp_path):
    # steel-steel's μ was measured with steel balls on a steel jar: with zirconia balls in a
    # zirconia bowl it is used as it is, and said so; a pair of those materials, the
    # dry-ceramic-powder pair (its own assumption line) and a [friction] table are silent
    zr = {"balls.material": "zirconia", "jar_material": "zirconia"}
    borrowed = [w for w in load_preset(CY, zr).warnings if w.startswith("friction of pair")]
    assert borrowed == ["friction of pair steel-steel (mu_s = 1, mu_d = 0.8) was measured for steel-c1020 balls on "
                        "aisi-304 walls and is used as it is for zirconia balls on zirconia walls; --pair names one for "
                        "your powder (taimill materials lists them, e.g. dry-ceramic-powder)"]
    for over in ({"pair": "zirconia-zirconia"}, {"pair": "dry-ceramic-powder"}):
        assert not [w for w in load_preset(CY, {**zr, **over}).warnings if w.startswith("friction of pair")]
    for top, said in (("", 1), ('[friction]\nmu_s = 0.5\nmu_d = 0.4\n', 0)):
        path = Path(_preset(tmp_path, top))
        path.write_text(path.read_text().replace('material = "steel-c1020"', 'material = "zirconia"'))
        assert len([w for w in load_preset(str(path)).warnings if w.startswith("friction of pair")]) == said


# metres typed as millimetres: 0.01 mm zirconia balls in a PM 100 bowl, 6 s (7.3·10⁹ steps)
SLIP = ("--mill", "retsch-pm100", "--jar-volume", "80", "--jar-material", "zirconia", "--ball-material", "zirconia",
        "--balls", "25", "--pair", "zirconia-zirconia", "--plate-rpm", "400", "--ball-diameter", "0.01", "--duration", "6")


def test_a_unit_slip_that_would_run_for_hours_is_refused_unless_asked_for(tmp_path):
    # it was accepted, announced 9·10⁸ steps and sat compiling for minutes
    from taimill.cli.run import UNASKED_SECONDS, unasked_limit
    from taimill.model.cost import run_seconds

    out = tmp_path / "slip.zarr"
    res = subprocess.run([sys.executable, "-m", "taimill", "run", *SLIP, "--out", str(out)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and not out.exists() and not list(tmp_path.iterdir())
    line, = [ln for ln in res.stderr.splitlines() if ln.startswith("taimill: error:")]
    assert "--duration" in line and "pass --yes" in line and "0.01 mm diameter" in line
    dry = subprocess.run([sys.executable, "-m", "taimill", "run", *SLIP, "--dry-run", "--out", str(out)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert dry.returncode == 0 and "nothing run (--dry-run)" in dry.stdout and " h " in dry.stdout and not out.exists()
    overrides = {"mill": "retsch-pm100", "jar_volume_ml": 80, "jar_material": "zirconia", "balls.material": "zirconia",
                 "balls.count": 25, "pair": "zirconia-zirconia", "plate_rpm": 400, "balls.diameter_mm": 0.01, "duration": 6}
    preset = load_preset(CY, overrides)
    assert run_seconds(preset)[1] > UNASKED_SECONDS
    unasked_limit(preset, yes=True)  # --yes: the user meant it
    with pytest.raises(ConfigError):
        unasked_limit(preset, yes=False)


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_every_shipped_preset_runs_without_being_asked_or_says_why(path):
    from taimill.cli.run import UNASKED_SECONDS
    from taimill.model.cost import run_seconds

    preset = load_preset(path)
    hours = run_seconds(preset)[1] / 3600
    # the bead presets are the point of their hours (docs/performance.md): they need --yes
    assert (hours * 3600 <= UNASKED_SECONDS) or "beads" in path.stem, (path.stem, hours)
