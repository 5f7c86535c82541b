"""`taimill jars` (table, JSON) and `taimill jars show` (drawing), through the real CLI."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
JARS = ("CY", "HM", "1L", "3L", "T", "EFV45")
# volume ratio to CY: thesis Table 4.1 (60, 71, 69, 51 of 72 ml); EFV45 from its size
RATIOS = {"CY": 1.0, "HM": 0.833, "1L": 0.986, "3L": 0.958, "T": 0.708, "EFV45": 0.629}
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def taimill(*args):
    return subprocess.run([sys.executable, "-m", "taimill.cli", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_jars_table_lists_all_with_ratios():
    r = taimill("jars")
    assert r.returncode == 0, r.stderr
    rows = {line.split()[0]: line.split() for line in r.stdout.splitlines()[1:]}
    assert set(JARS) <= set(rows)
    for name, ratio in RATIOS.items():
        assert float(rows[name][3]) == pytest.approx(ratio, abs=2e-3), name
    assert rows["T"][4] == "12" and rows["CY"][4] == "1" and rows["HM"][5] == "8"


def test_jars_json():
    r = taimill("jars", "--json")
    assert r.returncode == 0, r.stderr
    rows = {row["name"]: row for row in json.loads(r.stdout)}
    assert set(JARS) <= set(rows)
    hm = rows["HM"]
    assert hm["ratio_to_CY"] == pytest.approx(0.833, abs=2e-3)
    assert hm["volume_ml"] == pytest.approx(hm["area_mm2"] * hm["height_mm"] / 1e3)
    assert hm["pieces"] == 4 and hm["fillet_mm"] == 8.0 and hm["description"]


def test_jars_show_png_and_svg(tmp_path):
    png = tmp_path / "x.png"
    r = taimill("jars", "show", "HM", "--out", str(png))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(png)
    data = png.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 10_000

    svg = tmp_path / "t.svg"
    r = taimill("jars", "show", str(ROOT / "jars" / "T.toml"), "--out", str(svg))  # a path works too
    assert r.returncode == 0, r.stderr
    text = svg.read_text()
    assert "<svg" in text and "positive inside" in text


def test_jars_show_unknown_is_one_line_exit_2():
    r = taimill("jars", "show", "NOPE")
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "NOPE" in r.stderr
    assert not (ROOT / "jar-NOPE.png").exists()


def test_jars_show_default_name_in_cwd(tmp_path):
    r = subprocess.run([sys.executable, "-m", "taimill.cli", "jars", "show", "3L"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "jar-3L.png"
    assert (tmp_path / "jar-3L.png").read_bytes()[:8] == PNG_MAGIC
