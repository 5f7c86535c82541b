"""Messages that explain a wait or a choice, and the catalog tables as JSON, all
through the real command line: `taimill presets/jars/mills/materials --json`, the
compile notice, the speed without compilation, the analysis window of a short run,
the LIGGGHTS import's own run time."""

from __future__ import annotations

import json

import pytest

from tests.inprocess import main


def table_and_json(*argv):
    code, text, err = main(*argv)
    assert code == 0, err
    code, out, err = main(*argv, "--json")
    assert code == 0, err
    return text, json.loads(out)


def test_presets_table_and_json_have_the_same_columns():
    text, rows = table_and_json("presets")
    head = text.splitlines()[0].split()
    assert head[:3] == ["preset", "mill", "jar"] and "duration" in head
    cy = next(r for r in rows if r["name"] == "p4-cy-steel")
    assert cy == {"name": "p4-cy-steel", "mill": "fritsch-p4", "jar": "CY", "balls": 12, "radius_mm": 6.0,
                  "pair": "steel-steel", "ratio_K": -2.6, "plate_rpm": 200.0, "duration_s": 24.0}
    line = next(x for x in text.splitlines() if x.startswith("p4-cy-steel "))
    assert line.split() == ["p4-cy-steel", "fritsch-p4", "CY", "12", "6", "steel-steel", "-2.6", "200", "24"]
    # aligned: every row's jar column starts where the heading's does
    col = text.splitlines()[0].index(" jar ") + 1
    assert all(r[col - 1] == " " and r[col] != " " for r in text.splitlines()[1:len(rows) + 1])


def test_mills_json_lists_every_mill_with_units_in_keys():
    text, rows = table_and_json("mills")
    assert [r["name"] for r in rows] == [x.split()[0] for x in text.splitlines()[1:len(rows) + 1]]
    p4 = next(r for r in rows if r["name"] == "fritsch-p4")
    assert p4["plate_radius_mm"] == 125.0 and "bowls_ml" in p4 and "estimates" in p4
    code, out, err = main("mills", "fritsch-p4", "--json")
    assert code == 0 and json.loads(out) == [p4]


@pytest.mark.parametrize("command", ["jars", "materials"])
def test_jars_and_materials_json(command):
    text, rows = table_and_json(command)
    assert rows and all("name" in r for r in rows)
    assert rows[0]["name"] in text


# ---------------------------------------------------------------- compiling kernels
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COMPILING = re.compile(r"^taimill: compiling kernels for (\d+) balls? \((first run of this size|from the kernel cache), "
                       r"≈ ([0-9.e+]+) s\)$", re.M)


def taimill(*args):
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, stdin=subprocess.DEVNULL)


def marker_of(*overrides):
    """The marker file of the engine shape `taimill run p4-cy-steel OVERRIDES` uses."""
    from taimill.model.preset import load_preset
    from taimill.model.spec import from_preset
    from taimill.physics.runner import compile_plan

    return Path(compile_plan([from_preset(load_preset("p4-cy-steel", dict(overrides)))]).marker)


def test_run_says_it_compiles_first_run_then_from_the_cache_and_leaves_compiling_out_of_its_speed():
    argv = ("run", "p4-cy-steel", "--balls", 5, "--duration", 0.05, "--json")
    marker = marker_of(("balls.count", 5), ("duration", 0.05))
    marker.unlink(missing_ok=True)  # as on a machine that never ran 5 (padded: 8) balls
    t0 = time.perf_counter()
    first = taimill(*argv)
    elapsed = time.perf_counter() - t0
    assert first.returncode == 0, first.stderr
    (n, why, seconds), = COMPILING.findall(first.stderr)
    assert n == "5" and why == "first run of this size" and float(seconds) > 0
    # the time of this compile is noted and told the next time; after a compile that
    # filled Taichi's cache (the shape was new to it too), this machine's last compile
    # from the cache
    noted = json.loads(marker.read_text())
    setup = noted["seconds"]
    # (on a machine that never compiled from the cache, the built-in figure, as the runner does)
    from taimill.physics.runner import CACHED_COMPILE_SECONDS

    machine = json.loads((marker.parent / "machine.json").read_text())
    expected = machine.get("cached_seconds", CACHED_COMPILE_SECONDS) if noted["first"] else setup
    again = taimill(*argv)
    (n, why, seconds), = COMPILING.findall(again.stderr)
    assert why == "from the kernel cache" and seconds == f"{expected:.2g}"
    # the speed is the simulation's: the set-up and compiling are not in its wall time
    s = json.loads(first.stdout)
    assert s["wall_seconds"] < elapsed - setup
    assert s["realtime_factor"] == pytest.approx(s["sim_seconds"] / s["wall_seconds"])


def test_the_summary_table_says_compiling_is_left_out():
    res = taimill("run", "p4-cy-steel", "--duration", 0.05)
    assert res.returncode == 0, res.stderr
    assert len(COMPILING.findall(res.stderr)) == 1
    assert re.search(r"^wall time, set-up and compiling left out +[0-9.]+ s$", res.stdout, re.M)
    assert re.search(r"^simulated s per wall s, compiling left out +[0-9.]+", res.stdout, re.M)


def test_calibrate_drop_says_it_compiles():
    res = taimill("calibrate", "drop", "--pair", "steel-steel", "--h0", 50, "--json")
    assert res.returncode == 0, res.stderr
    (n, _, _), = COMPILING.findall(res.stderr)
    assert n == "1" and "compiling kernels for 1 ball (" in res.stderr
    json.loads(res.stdout)  # stdout stays one JSON value


def test_sweep_says_what_its_workers_compile():
    res = taimill("sweep", "p4-cy-steel", "--ratio", "-2,-2.6", "--duration", 0.05, "--json")
    assert res.returncode == 0, res.stderr
    assert [n for n, _, _ in COMPILING.findall(res.stderr)] == ["12"]
    assert len(json.loads(res.stdout)) == 2


# ---------------------------------------------------------------- a file of the wrong kind
PAIR_FILE = '[pair.mine]\ncontact = "steel"\nmu_s = 0.5\nmu_d = 0.4\n'


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    """One of each kind of taimill file and store folder, the stores written by the CLI."""
    d = tmp_path_factory.mktemp("kinds")
    (d / "jar.toml").write_text((ROOT / "jars" / "HM.toml").read_text())
    (d / "preset.toml").write_text((ROOT / "presets" / "p4-cy-steel.toml").read_text())
    (d / "mill.toml").write_text((ROOT / "taimill" / "data" / "mills" / "fritsch-p5.toml").read_text())
    (d / "pair.toml").write_text(PAIR_FILE)
    assert main("run", d / "preset.toml", "--duration", 0.05, "--out", d / "run.zarr")[0] == 0
    assert main("sweep", d / "preset.toml", "--ratio", -2, "--duration", 0.05, "--out", d / "sweep.zarr")[0] == 0
    return d


# (command with {X} where the file goes, the kind it expects)
EXPECTS = [
    (["run", "{X}"], "preset file"), (["sweep", "{X}", "--ratio", "-2"], "preset file"), (["tui", "{X}"], "preset file"),
    (["export", "liggghts", "{X}", "--out", "{D}/case"], "preset file"), (["run", "--jar", "{X}"], "jar file"),
    (["jars", "show", "{X}"], "jar file"), (["run", "--pair", "{X}"], "pair file"), (["mills", "{X}"], "mill file"),
    (["calibrate", "drop", "--pair", "{X}", "--h0", "10"], "pair file"), (["run", "--mill", "{X}"], "mill file"),
    (["analyse", "{X}"], "run store"), (["report", "{X}", "--out", "{D}/figs"], "run store"),
    (["compare", "{X}", "{D}/run.zarr"], "run store"), (["record", "{X}", "--rrd", "{D}/x.rrd"], "run store"),
]
GIVEN = {"jar file": "jar.toml", "preset file": "preset.toml", "mill file": "mill.toml", "pair file": "pair.toml",
         "run store": "run.zarr", "sweep store": "sweep.zarr"}


@pytest.mark.parametrize("argv, expected", EXPECTS, ids=lambda x: " ".join(x) if isinstance(x, list) else x)
def test_a_file_of_another_kind_is_named_as_such(kinds, argv, expected):
    for given, name in GIVEN.items():
        if given == expected or (expected == "run store" and given == "sweep store" and argv[0] == "report"):
            continue  # report draws sweep stores too
        code, out, err = main(*(a.format(X=kinds / name, D=kinds) for a in argv))
        assert code == 2 and err.count("\n") == 1, (given, err)
        assert f"this is a {given}, not a {expected};" in err, (given, err)
        assert "taimill " in err.split(";", 1)[1] or "use it with" in err  # and says how to use it


def test_tui_says_it_compiles_before_its_screen_opens(monkeypatch, tmp_path):
    from taimill.physics import runner
    from taimill.tui.app import MillApp

    shown = []
    monkeypatch.setattr(runner, "_engines", {})  # this process has no kernels yet
    monkeypatch.setattr(MillApp, "run", lambda self: shown.append(self))  # the screen would open here
    code, out, err = main("tui", "p4-cy-steel", "--paused", "--out-dir", tmp_path)
    assert code == 0 and len(shown) == 1, err
    (n, _, _), = COMPILING.findall(err)
    assert n == "12"
    code, out, err = main("tui", "p4-cy-steel", "--paused", "--out-dir", tmp_path)  # its kernels are there now
    assert code == 0 and "compiling" not in err
