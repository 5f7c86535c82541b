"""Never lose a user's file or mix two results (docs/outputs.md, replacing an output and
resuming a sweep), through the real CLI: --overwrite replaces a run store taimill wrote
(and cleans what killed writers left beside it), never the case an import reads nor a
store another writer holds; a sweep resumes only
against the configuration it started with; two jar files of one name are two curves.
Refusals of inputs and of users' files before anything runs are cases of the table in
test_bad_input.py."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import zarr

from taimill.bridge import dumps
from taimill.bridge.liggghts import export_case
from taimill.store.output import OutputLock
from taimill.store.run import open_run
from test_liggghts import _synthetic_dump, free_flight_preset

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "presets" / "p4-cy-steel.toml"


def taimill(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)


def files(folder: Path) -> dict:
    return {f: f.read_bytes() for f in folder.rglob("*") if f.is_file()}


def test_an_old_run_store_is_replaced_and_leftovers_of_killed_writers_cleaned(tmp_path):
    out = tmp_path / "run.zarr"
    res = taimill("run", PRESET, "--duration", 0.05, "--out", out, "--json")
    assert res.returncode == 0, res.stderr
    gone = 2**22 + 1  # above Linux' largest pid: a writer that is no longer running
    shutil.copytree(out, tmp_path / f"run.partial-{gone}.zarr")  # an --overwrite killed while building
    shutil.copytree(out, tmp_path / f"run.zarr.old-{gone}")  # one killed between the renames of its swap
    (tmp_path / f"run.zarr.old-{gone + 1}").write_text("a user's file of that name stays")
    res = taimill("run", PRESET, "--duration", 0.1, "--out", out, "--overwrite", "--json")
    assert res.returncode == 0, res.stderr
    run = open_run(out)
    assert run.status == "complete" and run.config["duration"] == pytest.approx(0.1, rel=1e-3)  # whole steps
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.zarr", f"run.zarr.old-{gone + 1}"]  # no lock left
    notes = ("taimill: warning: ", "taimill: compiling")  # 0.1 s: in the ramp; and the compile notice
    assert [ln for ln in res.stderr.splitlines() if not ln.startswith(notes)] == [
        f"taimill: removed {tmp_path / name}, left by an earlier writer of {out} that did not finish"
        for name in (f"run.partial-{gone}.zarr", f"run.zarr.old-{gone}")]


def test_import_never_replaces_its_case_and_takes_the_lock(tmp_path):
    p = free_flight_preset(tmp_path)
    case = tmp_path / "case"
    export_case(p, case)
    man = dumps.read_manifest(case)
    steps = np.arange(0, man["steps"] + 1, man["frame_every"])
    x = np.tile([p.plate_radius - 0.005, 0.003, 0.017], (len(steps), 1, 1))  # a ball held still: any dump will do
    _synthetic_dump(case / "dumps" / "balls.dump", steps, x, 0 * x, 0 * x, p.balls.radius, p.balls.mass)
    before = files(case)
    res = taimill("import", "liggghts", case, "--out", case, "--overwrite")
    assert res.returncode == 2 and res.stderr.strip().endswith(f"'{case}': is an input of this command; not replaced")
    assert files(case) == before  # dumps, deck and STL all there
    out = tmp_path / "run.zarr"
    assert taimill("import", "liggghts", case, "--out", out).returncode == 0
    stored = files(out)
    with OutputLock(out):  # another process is writing it
        res = taimill("import", "liggghts", case, "--out", out, "--overwrite")
    assert res.returncode == 2 and f"{out}: in use: pid {os.getpid()}" in res.stderr
    assert files(out) == stored
    assert taimill("import", "liggghts", case, "--out", out, "--overwrite").returncode == 0  # ours: replaced
    assert sorted(f.name for f in tmp_path.iterdir()) == ["case", "free.toml", "run.zarr", "start.csv"]


def test_a_sweep_resumes_only_against_the_preset_it_started_with(tmp_path):
    preset = tmp_path / "P.toml"
    shutil.copy(PRESET, preset)
    out = tmp_path / "sweep.zarr"
    sweep = ("sweep", preset, "--ratio", "-2", "--duration", 0.05, "--workers", 1, "--out", out, "--json")
    res = taimill(*sweep)
    assert res.returncode == 0, res.stderr
    zarr.open_group(out, mode="r+")["table"]["done"][0] = False  # as if killed before its point finished
    shutil.rmtree(out / "points" / "p00000")
    text = preset.read_text()
    preset.write_text(text.replace("\ncount = 12\n", "\ncount = 24\n").replace("\nradius_mm = 6\n", "\nradius_mm = 4\n"))
    res = taimill(*sweep)
    assert res.returncode == 2
    assert res.stderr.splitlines()[-1].startswith(f"taimill: error: {out}: resume: preset {preset} changed since the sweep started: "
                                 "balls.count 12 → 24, balls.radius 0.006 → 0.004, ")
    assert not any(zarr.open_group(out, mode="r")["table"]["done"][:])  # nothing computed with the new balls


def test_two_jar_files_of_one_name_are_two_curves_and_a_changed_one_is_named(tmp_path):
    from taimill.cli.sweep import with_regimes
    from taimill.runs.sweep import Request, content, plan
    from taimill.store.sweep import changes

    mine = tmp_path / "CY.toml"
    shutil.copy(ROOT / "jars" / "CY.toml", mine)
    req = Request(str(PRESET), {"duration": 0.05}, {"jar": ["CY", str(mine)]})
    points = plan(req)
    assert [p["values"]["jar"] for p in points] == ["CY", str(mine)]
    _, curves = with_regimes([p["values"] | {"regime": "rolling"} for p in points])
    assert [c["replicas"] for c in curves] == [1, 1]  # not one curve of two replicas
    before = content(req, points)
    mine.write_text(mine.read_text().replace("height_mm = 24.1", "height_mm = 30"))
    after = content(req, plan(req))
    assert before["sha256"] != after["sha256"]
    assert changes(before, after) == f"--jar {mine} changed since the sweep started: jar.height 0.0241 → 0.03"


@pytest.mark.parametrize("kind", ["png", "svg", "pdf"])
def test_only_a_figure_taimill_drew_is_ours(tmp_path, kind):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from taimill.figures import is_figure

    fig = plt.figure()
    fig.savefig(tmp_path / f"ours.{kind}")
    plt.close(fig)
    (tmp_path / f"theirs.{kind}").write_bytes({"png": b"\x89PNG\r\n\x1a\n", "svg": b"<svg>", "pdf": b"%PDF-1.4"}[kind] + b"x" * 99)
    assert is_figure(tmp_path / f"ours.{kind}") and not is_figure(tmp_path / f"theirs.{kind}")


# 15 balls of 20 mm cannot be placed in the PM 400's 250 ml bowl (at most 13 fit): a
# refusal that comes once the outputs are open, at the start of the run
CROWDED = ("--mill", "retsch-pm400", "--jar-volume", 250, "--ball-diameter", 20, "--duration", 0.1)


def test_a_run_refused_at_its_start_leaves_nothing_in_the_way_of_the_retry(tmp_path):
    out, rrd = tmp_path / "pm400.zarr", tmp_path / "pm400.rrd"
    res = taimill("run", *CROWDED, "--balls", 15, "--out", out, "--rrd", rrd)
    assert res.returncode == 2 and "at most 13 balls fit" in res.stderr, res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no store, no recording, no lock
    res = taimill("run", *CROWDED, "--balls", 10, "--out", out, "--json")  # the retry needs no --overwrite
    assert res.returncode == 0, res.stderr
    assert open_run(out).summary["status"] == "complete"


def test_overwrite_replaces_the_empty_store_an_older_taimill_left_but_no_users_folder(tmp_path):
    empty = tmp_path / "old.zarr"
    zarr.open_group(empty, mode="w")  # zarr.json alone, as a refused run used to leave
    res = taimill("run", *CROWDED, "--balls", 10, "--out", empty)
    assert res.returncode == 2 and "--overwrite" in res.stderr
    assert taimill("run", *CROWDED, "--balls", 10, "--out", empty, "--overwrite").returncode == 0
    assert open_run(empty).summary["status"] == "complete"
    mine = tmp_path / "mine.zarr"
    zarr.open_group(mine, mode="w").attrs["note"] = "a user's group"
    res = taimill("run", *CROWDED, "--balls", 10, "--out", mine, "--overwrite")
    assert res.returncode == 2 and "not a run store written by taimill" in res.stderr
    assert zarr.open_group(mine, mode="r").attrs["note"] == "a user's group"
