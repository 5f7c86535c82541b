"""The user's own mill, end to end through the real command line from a folder outside
the repository: a plate-speed sweep of a fixed-gear mill described only by options
(mill, bowl volume, wall and ball material, ball diameter and count), the same on the
P 7 premium line up to its 1100 rpm, and the refusals a fixed gear and a mill's speed
limits give. Short durations: what is checked is that the capability works and speaks
the mill's language, not the physics (tests/test_mills.py and tests/test_media.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MEDIA = ("--jar-volume", "80", "--jar-material", "zirconia", "--ball-material", "zirconia", "--ball-diameter", "5",
         "--balls", "25", "--pair", "dry-ceramic-powder")


def taimill(*args, cwd):
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=600)


def test_a_plate_speed_sweep_of_a_fixed_gear_mill_from_any_folder(tmp_path):
    res = taimill("sweep", "--mill", "retsch-pm100", *MEDIA, "--plate-rpm", "200,650", "--duration", 0.3,
                  "--workers", 1, "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)
    assert [r["plate_rpm"] for r in rows] == [200, 650]
    assert all(r["ratio"] == pytest.approx(-1.0) for r in rows)  # the gear 1:-2, read as relative: K = -1
    assert all(r["stations"] == 1 and r["impact_power_mill"] == r["impact_power"] for r in rows)
    # what was assumed is said once each, before the run: the mill's estimates, the bowl's,
    # the derived contact set, the powder pair's assumption, the preset's K given way to the gear
    warnings = [ln for ln in res.stderr.splitlines() if ln.startswith("taimill: warning: ")]
    assert len(warnings) == len(set(warnings))
    for words in ("mill retsch-pm100", "bowl retsch-80ml", "contact set derived for zirconia balls of 2.5 mm",
                  "dry-ceramic-powder", "replaced by the gear of retsch-pm100"):
        assert any(words in w for w in warnings), (words, warnings)


def test_the_table_of_a_fixed_gear_sweep_is_against_the_plate_speed(tmp_path):
    # the P 7 premium line up to its 1100 rpm (a speed the global cap of 1000 rpm refused)
    res = taimill("sweep", "--mill", "fritsch-p7-premium", *MEDIA, "--plate-rpm", "700,1100", "--duration", 0.2,
                  "--workers", 1, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0].startswith("every point: fritsch-p7-premium") and "K = -1" in lines[0]
    assert lines[1].split()[:3] == ["point", "Ω", "rpm"] and "K" not in lines[1].split()
    assert [ln.split()[1] for ln in lines[2:4]] == ["700", "1100"]


def test_a_fixed_gear_refuses_k_and_the_limits_are_the_mills(tmp_path):
    res = taimill("run", "--mill", "retsch-pm100", "--ratio", -2, "--duration", 0.1, cwd=tmp_path)
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert "retsch-pm100 has a fixed gear 1:-2 (K = -1)" in res.stderr
    classic = [m if m != "80" else "45" for m in MEDIA]  # the classic line takes 12 and 45 ml bowls
    res = taimill("sweep", "--mill", "fritsch-p7-classic", *classic, "--plate-rpm", "700,1100", "--duration", 0.1,
                  cwd=tmp_path)
    assert res.returncode == 2 and "800" in res.stderr and "rpm" in res.stderr and "fritsch-p7-classic" in res.stderr


def test_the_plate_radius_is_a_sweep_axis_in_mm(tmp_path):
    res = taimill("sweep", "p4-cy-steel", "--plate-radius", "70,125", "--duration", 0.1, "--workers", 1, "--json",
                  cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)
    assert [(r["plate_radius_mm"], r["plate_radius"]) for r in rows] == [(70, pytest.approx(0.07)), (125, pytest.approx(0.125))]
