"""Bundled presets and jars found by name from any folder, files of the wrong kind named
as such, the cylinder jar builder, and the charge as users give it (ball filling,
powder mass and ball-to-powder ratio). CLI behaviour through the real CLI in a
subprocess started outside the repository."""

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from taimill.cli import parser
from taimill.cli.common import overrides
from taimill.errors import ConfigError
from taimill.model import charge, files
from taimill.model.jars import load_jar
from taimill.model.preset import load_preset
from texts import GOOD_PRESET

ROOT = Path(__file__).resolve().parent.parent
PAIR_FILE = """\
[pair.mine]
contact = "steel-steel"
mu_s = 0.5
mu_d = 0.4
v_s_mm_s = 1
v_d_mm_s = 10
"""
MILL_FILE = """\
plate_radius_mm = 62
stations = 4
gear = "1:-2"
"""


def taimill(*args, cwd):
    """The CLI from `cwd`, importing this checkout's package whatever the folder."""
    env = os.environ | {"PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


def one_line_error(res, *words):
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("taimill: error: "), res.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


# ------------------------------------------------------------------ bundled files by name

def test_repository_links_point_into_the_package():
    for kind in ("presets", "jars"):
        link = ROOT / kind
        assert link.is_symlink() and os.readlink(link) == f"taimill/data/{kind}"
        assert link.resolve() == files.BUNDLED[kind[:-1]][0].resolve()


def test_bundled_preset_runs_by_name_from_another_folder(tmp_path):
    res = taimill("run", "p4-cy-steel", "--duration", 0.05, "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert '"events"' in res.stdout


def test_a_bundled_preset_by_its_repository_path_from_another_folder_names_the_way(tmp_path):
    one_line_error(taimill("run", "presets/p4-cy-steel.toml", cwd=tmp_path), "no such preset file here",
                   "taimill run p4-cy-steel")


def test_presets_and_jars_list_from_another_folder(tmp_path):
    res = taimill("presets", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    header, *rows = res.stdout.splitlines()
    assert header.split()[:4] == ["preset", "mill", "jar", "balls"] and "Ω rpm" in header and "duration" in header
    cy = next(r.split() for r in rows if r.startswith("p4-cy-steel "))
    assert cy[:7] == ["p4-cy-steel", "fritsch-p4", "CY", "12", "6", "steel-steel", "-2.6"] and cy[7:9] == ["200", "24"]
    assert {r.split()[0] for r in rows if r.startswith(("p4-", "efv-"))} == set(files.bundled_names("preset"))
    res = taimill("jars", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert {line.split()[0] for line in res.stdout.splitlines()[1:]} >= {"CY", "HM", "1L", "3L", "T", "EFV45"}


def test_a_name_is_bundled_and_a_path_is_a_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert files.resolve("CY", "jar", True) == files.DATA / "jars" / "CY.toml"
    assert files.resolve("p4-cy-steel", "preset", True) == files.DATA / "presets" / "p4-cy-steel.toml"
    assert files.resolve("my.toml", "jar", True, tmp_path / "presets") == Path("my.toml")
    assert files.resolve("my.toml", "jar", False, tmp_path / "presets") == tmp_path / "presets" / "my.toml"
    assert files.resolve("sub/my", "preset", True) == Path("sub/my")  # a folder: a path, not a name
    with pytest.raises(ConfigError, match=r"no bundled preset .*known presets: .*p4-cy-steel"):
        files.resolve("p4-cy-nope", "preset", True)
    with pytest.raises(ConfigError, match=r"no bundled mill .*(known mills|no mills are bundled)"):
        files.resolve("nope", "mill", False, tmp_path)


def test_a_jar_name_falls_back_to_the_bundled_bowls_and_a_missing_bowls_folder_is_none(tmp_path, monkeypatch):
    from taimill.model.jars import jar_names

    bowls = tmp_path / "bowls"
    monkeypatch.setitem(files.BUNDLED, "jar", (files.DATA / "jars", bowls))
    assert "B1" not in jar_names()  # no folder: no bowls, no error
    with pytest.raises(ConfigError, match="known jars: 1L"):
        load_jar("B1", "command line")
    bowls.mkdir()
    (bowls / "B1.toml").write_text((ROOT / "jars" / "ZR500.toml").read_text())
    (bowls / "CY.toml").write_text((ROOT / "jars" / "ZR500.toml").read_text())  # a jar's name wins over a bowl's
    assert "B1" in jar_names()
    assert load_jar("B1", "command line").volume == pytest.approx(load_jar("ZR500").volume)
    assert load_jar("CY").volume == pytest.approx(79.97e-6, rel=1e-3)


def test_a_jar_given_on_the_command_line_is_read_from_the_current_folder(tmp_path, monkeypatch):
    res = taimill("jars", "new", "myjar", "--volume", 80, "--diameter", 65, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    elsewhere = tmp_path / "presets"
    elsewhere.mkdir()
    (elsewhere / "mine.toml").write_text(GOOD_PRESET)
    monkeypatch.chdir(tmp_path)
    a = parser().parse_args(["run", "presets/mine.toml", "--jar", "myjar.toml"])
    p = load_preset(a.preset, overrides(a))
    assert Path(p.jar.source).resolve() == (tmp_path / "myjar.toml").resolve()
    # named inside a preset: relative to the preset's folder
    (elsewhere / "named.toml").write_text(GOOD_PRESET.replace('jar = "CY"', 'jar = "myjar.toml"'))
    with pytest.raises(ConfigError, match=r"no jar file .*presets/myjar.toml"):
        load_preset("presets/named.toml")
    (elsewhere / "myjar.toml").write_text((tmp_path / "myjar.toml").read_text())
    assert Path(load_preset("presets/named.toml").jar.source).resolve() == (elsewhere / "myjar.toml").resolve()


# ------------------------------------------------------------------ files of the wrong kind

def test_a_jar_file_given_as_a_preset_says_so():
    line = one_line_error(taimill("run", "jars/HM.toml", cwd=ROOT), "jar file", "--jar jars/HM.toml", 'jar = "jars/HM.toml"')
    assert "unknown key" not in line


@pytest.mark.parametrize("kind, text, load, words", [
    ("preset as --jar", GOOD_PRESET, lambda f: load_preset(ROOT / "presets" / "p4-cy-steel.toml", {"jar": str(f)}),
     ["preset file, not a jar file", "taimill run"]),
    ("pair file as a preset", PAIR_FILE, lambda f: load_preset(f), ["pair file, not a preset file", "--pair"]),
    ("mill file as a preset", MILL_FILE, lambda f: load_preset(f), ["mill file, not a preset file", "mill = "]),
    ("jar as --pair", (ROOT / "jars" / "CY.toml").read_text(),
     lambda f: load_preset(ROOT / "presets" / "p4-cy-steel.toml", {"pair": str(f)}), ["jar file, not a pair file", "--jar"]),
])
def test_a_file_of_another_kind_is_named_with_its_use(tmp_path, kind, text, load, words):
    f = tmp_path / "other.toml"
    f.write_text(text)
    with pytest.raises(ConfigError) as e:
        load(f)
    for w in words:
        assert w in str(e.value)


@pytest.mark.parametrize("text, kind", [
    (GOOD_PRESET, "preset"), ((ROOT / "jars" / "HM.toml").read_text(), "jar"), (PAIR_FILE, "pair"),
    (MILL_FILE, "mill"), ("", None), ("colour = 'red'", None),
])
def test_kinds_by_their_characteristic_keys(text, kind):
    import tomllib

    assert files.kind_of(tomllib.loads(text)) == kind


# ------------------------------------------------------------------ the jar builder

def test_jars_new_writes_a_cylinder_of_the_volume_that_loads(tmp_path):
    res = taimill("jars", "new", "B250", "--volume", 250, "--diameter", 75, "--material", "zirconia",
                  "--out", "bowl.toml", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    jar = load_jar(str(tmp_path / "bowl.toml"), "command line")
    assert jar.volume == pytest.approx(250e-6, rel=0.005)
    assert jar.radius == pytest.approx(37.5e-3) and jar.wall_material == "zirconia"
    assert jar.height == pytest.approx(250e-6 / (math.pi * 37.5e-3**2), rel=1e-5)
    again = taimill("jars", "new", "B250", "--volume", 250, "--diameter", 75, "--out", "bowl.toml", cwd=tmp_path)
    one_line_error(again, "--out", "--overwrite")
    assert taimill("jars", "new", "B250", "--volume", 300, "--diameter", 75, "--out", "bowl.toml", "--overwrite",
                   cwd=tmp_path).returncode == 0
    assert load_jar(str(tmp_path / "bowl.toml")).volume == pytest.approx(300e-6, rel=0.005)


@pytest.mark.parametrize("args, words", [
    (["--volume", 0, "--diameter", 75], ["--volume", "> 0"]),
    (["--volume", -5, "--diameter", 75], ["--volume"]),
    (["--volume", 250, "--diameter", 0], ["--diameter", "allowed range"]),
    (["--volume", 1e9, "--diameter", 75], ["--volume", "mm high", "at most"]),
    (["--volume", 250, "--diameter", 75, "--fillet", 40], ["--fillet", "below the radius"]),
    (["--volume", 250, "--diameter", 75, "--material", "gold"], ["--material", "gold", "aisi-304"]),
    (["--volume", "nan", "--diameter", 75], ["--volume"]),
])
def test_jars_new_refuses_impossible_values_in_one_line(tmp_path, args, words):
    one_line_error(taimill("jars", "new", "X", *args, cwd=tmp_path), *words)
    assert not (tmp_path / "X.toml").exists()


# ------------------------------------------------------------------ the charge

def preset_file(tmp_path, balls="count = 12", extra=""):
    text = GOOD_PRESET.replace("count = 12", balls) + extra
    f = tmp_path / "charge.toml"
    f.write_text(text)
    return f


def test_filling_gives_the_count_of_a_hand_calculation(tmp_path):
    # CY: π 32.5² × 24.1 mm³ = 79 972 mm³; a 6 mm ball 904.8 mm³;
    # 0.3 × 79 972 × 0.60 / 904.8 = 15.91 → 16 balls
    p = load_preset(preset_file(tmp_path, "filling = 0.3"))
    assert charge.PACKING_FRACTION == 0.60
    assert p.balls.count == 16
    assert any("16 balls" in w and "φ = 0.6" in w and "estimate" in w for w in p.warnings)
    assert load_preset(preset_file(tmp_path), {"balls.filling": 1 / 3}).balls.count == round(79972.0 / 3 * 0.6 / 904.78)
    assert load_preset(preset_file(tmp_path, "filling = 0.3"), {"balls.count": 7}).balls.count == 7


@pytest.mark.parametrize("balls, over, words", [
    ("count = 12\nfilling = 0.3", {}, ["balls.filling", "not both"]),
    ("filling = 0.9", {}, ["balls.filling", "placed at random"]),
    ("filling = 0", {}, ["balls.filling", "allowed range"]),
    ("filling = 0.0001", {}, ["balls.filling", "gives 0 balls"]),
    ("material = 'x'", {}, []),
    ("count = 12", {"balls.count": 5, "balls.filling": 0.3}, ["--filling", "--balls", "not both"]),
])
def test_count_or_filling_exactly_one(tmp_path, balls, over, words):
    text = preset_file(tmp_path, balls)
    if balls.startswith("material"):  # neither: the preset's own material line is kept
        text.write_text(GOOD_PRESET.replace("count = 12\n", ""))
        words = ["balls.count", "balls.filling", "missing"]
    with pytest.raises(ConfigError) as e:
        load_preset(text, over)
    for w in words:
        assert w in str(e.value)


def test_powder_mass_and_ball_to_powder_give_each_other(tmp_path):
    balls = 12 * 7850 * 4 / 3 * math.pi * 6e-3**3  # kg, 85.23 g
    p = load_preset(preset_file(tmp_path, extra="\n[powder]\nmass_g = 8.523\n"))
    assert p.powder.mass == pytest.approx(8.523e-3) and p.powder.ball_to_powder == pytest.approx(balls / 8.523e-3)
    assert p.powder.ball_to_powder == pytest.approx(10.0, rel=1e-3)
    p = load_preset(preset_file(tmp_path, extra="\n[powder]\nball_to_powder = 20\n"))
    assert p.powder.mass == pytest.approx(balls / 20) and p.as_dict()["powder"] == {"mass": p.powder.mass, "ball_to_powder": 20.0}
    p = load_preset(preset_file(tmp_path, extra="\n[powder]\nmass_g = 8.523\nball_to_powder = 10.05\n"))  # within 1 %
    assert p.powder.ball_to_powder == 10.05
    assert "powder" not in load_preset(preset_file(tmp_path)).as_dict()
    # --powder-mass wins over the file and drops its ratio
    p = load_preset(preset_file(tmp_path, extra="\n[powder]\nball_to_powder = 20\n"), {"powder.mass_g": 17.046})
    assert p.powder.ball_to_powder == pytest.approx(5.0, rel=1e-3)


@pytest.mark.parametrize("powder, words", [
    ("mass_g = 8.523\nball_to_powder = 12", ["powder.ball_to_powder", "12", "disagrees", "ratio of 10"]),
    ("", ["powder", "missing"]),
    ("mass_g = -1", ["powder.mass_g", "allowed range"]),
    ("ball_to_powder = 0", ["powder.ball_to_powder", "allowed range"]),
    ("mass_kg = 1", ["mass_kg", "unknown key"]),
])
def test_powder_refusals(tmp_path, powder, words):
    with pytest.raises(ConfigError) as e:
        load_preset(preset_file(tmp_path, extra=f"\n[powder]\n{powder}\n"))
    for w in words:
        assert w in str(e.value)


def test_filling_and_powder_from_the_command_line(tmp_path):
    res = taimill("run", "p4-cy-steel", "--filling", 0.3, "--powder-mass", 5, "--dt", "1", cwd=tmp_path)
    # stops at the bad --dt, after the charge was read: the options are taken
    one_line_error(res, "dt")
    res = taimill("run", "p4-cy-steel", "--filling", 0.3, "--balls", 4, cwd=tmp_path)
    one_line_error(res, "--filling", "not both")
