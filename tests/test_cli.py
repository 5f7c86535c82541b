"""The real CLI in a subprocess (docs/outputs.md): --json output, bit-identical reruns, bad
input handled as one-line errors with exit code 2."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from taimill.store.run import open_run
from texts import GOOD_PRESET

ROOT = Path(__file__).resolve().parent.parent
SUMMARY_KEYS = (
    "events", "events_ball_ball", "events_ball_wall", "impact_power", "impact_power_normal",
    "impact_power_tangential", "mean_se", "mean_se_normal", "mean_se_tangential", "dissipated_power",
    "energy_balance_error", "randomness_index", "regime", "sim_seconds", "wall_seconds", "realtime_factor",
    "regime_class", "wall_lag", "slip_ratio",
)


def taimill(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "taimill.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def test_run_json_six_seconds_is_complete_balanced_and_bit_identical(tmp_path):
    # Issue acceptance: the summary keys, energy balance within 1 %, a second run
    # bit-identical (event tables compared exactly, summaries except timings).
    runs = []
    for name in ("a", "b"):
        out = tmp_path / f"{name}.zarr"
        res = taimill("run", "presets/p4-cy-steel.toml", "--duration", 6, "--json", "--out", out)
        assert res.returncode == 0, res.stderr
        summary = json.loads(res.stdout)  # stdout is exactly one JSON object
        runs.append((summary, open_run(out)))
    (s1, r1), (s2, r2) = runs
    for key in SUMMARY_KEYS:
        assert key in s1
    assert s1["sim_seconds"] == pytest.approx(6.0, abs=600 * s1["dt"])  # whole steps per 10 ms frame
    assert s1["events"] > 1000
    assert s1["energy_balance_error"] < 0.01
    assert r1.status == "complete" and r1.summary["events"] == s1["events"]
    timing = {"wall_seconds", "realtime_factor"}
    assert {k: v for k, v in s1.items() if k not in timing} == {k: v for k, v in s2.items() if k not in timing}
    for col in r1.events:
        np.testing.assert_array_equal(r1.events[col], r2.events[col])
    np.testing.assert_array_equal(r1.frames["position"], r2.frames["position"])
    assert len(r1.frames["time"]) == 601  # 100 Hz trajectory, both ends


def test_run_without_json_prints_a_table():
    res = taimill("run", "presets/p4-cy-fluorite.toml", "--duration", 0.2)
    assert res.returncode == 0, res.stderr
    assert "impact power" in res.stdout and "energy balance error" in res.stdout
    # the regime as the regime map splits it, and powers of one jar and of the whole mill (the P 4: 2 stations)
    assert "class (6, the plate frame too)" in res.stdout and "wall lag" in res.stdout
    assert "one jar" in res.stdout and "whole mill (2 stations)" in res.stdout


def test_calibrate_drop_prints_restitution():
    res = taimill("calibrate", "drop", "--pair", "steel-steel", "--h0", 500, "--json")
    assert res.returncode == 0, res.stderr
    r = json.loads(res.stdout)
    assert r["e"] == pytest.approx(0.52, abs=0.03)
    assert r["rebound_height"] == pytest.approx(r["e"] ** 2 * 0.5, rel=1e-9)


GOOD = GOOD_PRESET

# (name, edit of GOOD, words the message must contain)
BAD = [
    ("negative radius", ("radius_mm = 6", "radius_mm = -6"), ["balls.radius_mm", "-6", "allowed range"]),
    ("balls do not fit", ("count = 12", "count = 200"), ["balls.count", "200"]),
    ("unknown key", ("seed = 1", "seed = 1\nratoi = 2"), ["ratoi", "unknown key"]),
    ("unknown jar", ('jar = "CY"', 'jar = "XY"'), ["jar", "XY", "known jars"]),
    ("unknown pair", ('pair = "steel-steel"', 'pair = "steel-unobtainium"'), ["pair", "steel-steel"]),
    ("ratio out of range", ("ratio = -2.6", "ratio = -50"), ["ratio", "-50", "[-10, 10]"]),
    ("ratio and jar_rpm", ("ratio = -2.6", "ratio = -2.6\njar_rpm = -700"), ["jar_rpm", "either"]),
    ("analysis after end", ("analysis_start = 0.5", "analysis_start = 2.0"), ["analysis_start", "2.0"]),
    ("dt too large", ('dt = "auto"', "dt = 1e-4"), ["dt", "0.0001", "steps per contact"]),
    ("wrong type", ("plate_rpm = 200", 'plate_rpm = "fast"'), ["plate_rpm", "fast", "number"]),
    ("not TOML", ("seed = 1", "seed = = 1"), ["not valid TOML"]),
    ("material unknown", ('material = "steel-c1020"', 'material = "gold"'), ["balls.material", "gold", "zirconia"]),
    ("mu_d above mu_s", ("seed = 1", "seed = 1\n[friction]\nmu_s = 0.5\nmu_d = 0.8"), ["friction.mu_d", "0.8", "mu_s = 0.5"]),
    ("zero balls", ("count = 12", "count = 0"), ["balls.count", "0", "[1,"]),
    ("missing key", ("plate_rpm = 200\n", ""), ["plate_rpm", "missing"]),
    ("overlapping start", ("seed = 1", 'seed = 1\ninitial_positions = "overlap.csv"'), ["initial_positions", "overlap"]),
]


@pytest.mark.parametrize("name,edit,words", BAD, ids=[b[0] for b in BAD])
def test_bad_preset_gives_one_line_error_and_exit_2(tmp_path, name, edit, words):
    text = GOOD.replace(*edit)
    assert text != GOOD
    (tmp_path / "overlap.csv").write_text("\n".join(["0,0,0.01"] * 12))
    preset = tmp_path / "bad.toml"
    preset.write_text(text)
    res = taimill("run", preset, "--out", tmp_path / "never.zarr")
    assert res.returncode == 2, res.stdout + res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    for w in words:
        assert w in lines[0], lines[0]
    if name not in ("not TOML",):
        assert "bad.toml" in lines[0] or "materials" in lines[0] or "command line" in lines[0]
    assert not (tmp_path / "never.zarr").exists()  # nothing ran


def test_bad_jar_file_names_file_and_key(tmp_path):
    jar = tmp_path / "hex.toml"
    jar.write_text('height_mm = 24\nwall_material = "aisi-304"\n[[profile]]\ntype = "hexagon"\nradius_mm = 30\n')
    preset = tmp_path / "p.toml"
    preset.write_text(GOOD.replace('jar = "CY"', 'jar = "hex.toml"'))
    res = taimill("run", preset)
    assert res.returncode == 2
    assert "hex.toml" in res.stderr and "profile[0].type" in res.stderr and "hexagon" in res.stderr


def test_bad_command_line_override_is_named_as_such():
    res = taimill("run", "presets/p4-cy-steel.toml", "--ratio", -40)
    assert res.returncode == 2
    assert res.stderr.startswith("taimill: error: command line: ratio = -40.0")


@pytest.mark.parametrize("command", ["run", "sweep"])
@pytest.mark.parametrize("dt", ["fast", "1e-3"])
def test_bad_dt_on_the_command_line_names_value_and_range(command, dt):
    # run and sweep parse --dt alike (cli.dt_option): a number is range-checked by
    # load_preset, any other text is refused with the allowed values
    extra = ["--ratio", "-2"] if command == "sweep" else []
    res = taimill(command, "presets/p4-cy-steel.toml", *extra, "--dt", dt)
    assert res.returncode == 2
    shown = "'fast'" if dt == "fast" else "0.001"
    assert res.stderr.startswith(f"taimill: error: command line: dt = {shown}")
    assert "'auto' or a time step in (0," in res.stderr


def test_existing_output_is_not_overwritten(tmp_path):
    out = tmp_path / "keep.zarr"
    out.mkdir()
    (out / "precious").write_text("x")
    res = taimill("run", "presets/p4-cy-steel.toml", "--duration", 0.01, "--out", out)
    assert res.returncode == 2 and "--overwrite" in res.stderr
    assert (out / "precious").exists()


def test_a_reader_that_leaves_early_gets_no_traceback():
    # `taimill presets | head -1`: the pipe closes under the listing
    p = subprocess.Popen([sys.executable, "-m", "taimill.cli", "presets"], cwd=ROOT,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.read(10)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 0 and "Traceback" not in err and "BrokenPipe" not in err, err
