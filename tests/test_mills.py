"""Mills: every mill and bowl file loads with physical numbers, each sourced or marked an
estimate; the maker's gear "1:r" becomes K = r + 1; a mill's gear and plate speeds bind
the run (preset, command line, live mill); `taimill mills` lists them with estimates
marked; the thesis' P 4 presets resolve exactly as before."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from taimill.errors import ConfigError
from taimill.model import mills
from taimill.model.drive import RPM, Drive
from taimill.model.jars import load_jar
from taimill.model.mills import NUMBERS, bowl_path, k_from_maker, load_mill, maker_from_k, mill_names
from taimill.model.preset import load_preset
from taimill.model.tables import read_toml
from tests.inprocess import main

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ("fritsch-p4", "fritsch-p5", "fritsch-p6", "fritsch-p7-premium", "fritsch-p7-classic",
           "retsch-pm100", "retsch-pm100cm", "retsch-pm200", "retsch-pm400", "retsch-pm400-ma")


def preset_text(mill: str, plate_rpm: float, *, ratio=None, volume=80, count=6, radius_mm=3) -> str:
    """A short run of a mill's bowl: steel balls, steel-steel friction."""
    speed = f"ratio = {ratio}\n" if ratio is not None else ""
    return (f'mill = "{mill}"\njar_volume_ml = {volume}\npair = "steel-steel"\nplate_rpm = {plate_rpm}\n{speed}'
            f"duration = 0.05\n[balls]\ncount = {count}\nmaterial = \"steel-c1020\"\nradius_mm = {radius_mm}\n")


def write_preset(tmp_path, text: str, name="mill.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", SHIPPED)
def test_every_mill_loads_with_physical_numbers_each_sourced_or_estimated(name):
    assert set(SHIPPED) <= set(mill_names())
    m = load_mill(name)
    assert 0.030 <= m.plate_radius <= 0.400  # R_p 30-400 mm: bench-top micro mills to floor-standing ones
    assert 1 <= m.stations <= 8
    assert m.bowls_ml and all(10 <= v <= 1000 for v in m.bowls_ml)
    if m.plate_rpm_max is not None:
        assert 0 < (m.plate_rpm_min or 0) < m.plate_rpm_max <= 2000
    assert all(-4 <= k <= 1 for k in m.gear.ks)  # counter-rotating or translating bowls
    data = read_toml(Path(m.source), "mill")
    numbers = [k for k in NUMBERS if k in data]
    assert [o.key for o in m.origins] == numbers  # every number has exactly one origin
    assert all(o.text for o in m.origins)


@pytest.mark.parametrize("name", SHIPPED)
def test_every_bowl_of_every_mill_loads_at_its_nominal_volume(name):
    m = load_mill(name)
    for volume in m.bowls_ml:
        jar = load_jar(str(bowl_path(m, volume)))
        assert jar.volume * 1e6 == pytest.approx(volume, rel=0.02)  # sizes rounded to 0.1 mm
        notes = read_toml(bowl_path(m, volume), "bowl")
        assert set(notes.get("estimates", {})) | set(notes.get("sources", {})) == {"height_mm", "radius_mm"}


def test_bowl_path_refuses_a_volume_the_mill_does_not_take_naming_those_it_does():
    with pytest.raises(ConfigError, match=r"jar_volume_ml = 33: mill retsch-pm200 takes bowls of 12, 25, 50, 80, 125 ml"):
        bowl_path(load_mill("retsch-pm200"), 33)


def test_the_thesis_mill_is_the_default_with_its_sourced_radius():
    m = load_mill(mills.DEFAULT)
    assert m.name == "fritsch-p4" and m.plate_radius == 0.125 and m.gear.kind == "free"
    assert not m.is_estimate("plate_radius_mm") and "thesis" in m.origin("plate_radius_mm").text


def test_maker_gear_is_the_bowl_speed_relative_to_the_sun_wheel():
    # "1:-2": per turn of the sun wheel the bowl turns twice backwards relative to it, so
    # its absolute spin is -1 turn: K = ω/Ω + 1 = -1 (reading -2 as K is another mill)
    assert k_from_maker(-2.0) == -1.0 and maker_from_k(-1.0) == -2.0
    assert k_from_maker(-1.82) == pytest.approx(-0.82) and k_from_maker(-1.0) == 0.0
    assert load_mill("retsch-pm100").gear.k_text == "K = -1"
    assert load_mill("retsch-pm400-ma").gear.ks == (-1.5, -2.0)


def test_pm100_kinematics_match_a_hand_calculation(tmp_path):
    # PM 100 at 400 rpm: gear 1:-2 → K = -1; the bowl's absolute spin K·Ω = -400 rpm, its
    # speed relative to the plate ω = (K - 1)·Ω = -800 rpm; R_p = 141 mm / 2
    p = load_preset(write_preset(tmp_path, preset_text("retsch-pm100", 400)))
    assert p.mill.name == "retsch-pm100" and p.plate_radius == pytest.approx(0.0705, abs=1e-12)
    assert p.drive.ratio == pytest.approx(-1.0, abs=1e-12)
    assert p.drive.jar_spin / RPM == pytest.approx(-400.0, abs=1e-9)
    assert p.drive.jar_rpm == pytest.approx(-800.0, abs=1e-9)
    assert p.jar.name == "retsch-80ml"
    config = p.as_dict()
    assert config["mill"]["name"] == "retsch-pm100" and config["mill"]["stations"] == 1
    assert config["plate_radius_from"] == "mill"
    assert any("R_p = 70.5 mm" in w and "estimate" in w for w in p.warnings)  # one line names every estimate
    assert any("bowl retsch-80ml" in w for w in p.warnings)


def test_a_preset_plate_radius_overrides_the_mill(tmp_path):
    text = preset_text("retsch-pm100", 400).replace("duration", "plate_radius_mm = 80\nduration")
    p = load_preset(write_preset(tmp_path, text))
    assert p.plate_radius == pytest.approx(0.080) and p.as_dict()["plate_radius_from"] == "preset"
    assert not any("R_p = 70.5 mm" in w for w in p.warnings)


def test_fixed_gear_refuses_a_jar_speed_from_file_or_command_line(tmp_path):
    with pytest.raises(ConfigError, match=r"ratio = -2.6: retsch-pm100 has a fixed gear 1:-2 \(K = -1\); ratio cannot be set"):
        load_preset(write_preset(tmp_path, preset_text("retsch-pm100", 400, ratio=-2.6)))
    path = write_preset(tmp_path, preset_text("retsch-pm100", 400), "ok.toml")
    with pytest.raises(ConfigError, match=r"command line: jar_rpm = -800.*fixed gear 1:-2 \(K = -1\); jar_rpm cannot be set"):
        load_preset(path, {"jar_rpm": -800.0})


def test_fixed_gear_refuses_ratio_through_the_real_command_line(tmp_path):
    path = write_preset(tmp_path, preset_text("retsch-pm100", 400))
    r = subprocess.run([sys.executable, "-m", "taimill", "export", "liggghts", str(path), "--ratio", "-2.6",
                        "--out", str(tmp_path / "case")], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip() == ("taimill: error: command line: ratio = -2.6: retsch-pm100 has a fixed gear 1:-2 (K = -1); "
                                "ratio cannot be set")
    assert not (tmp_path / "case").exists()


def test_a_set_of_gears_takes_only_its_ratios(tmp_path):
    p = load_preset(write_preset(tmp_path, preset_text("retsch-pm400-ma", 300, ratio=-1.5)))
    assert p.drive.ratio == pytest.approx(-1.5)
    with pytest.raises(ConfigError, match=r"ratio = -2.6: retsch-pm400-ma has the gears 1:-2.5 or 1:-3: allowed K = -1.5 or -2"):
        load_preset(write_preset(tmp_path, preset_text("retsch-pm400-ma", 300, ratio=-2.6)))
    with pytest.raises(ConfigError, match=r"missing.*K = -1.5 or -2"):
        load_preset(write_preset(tmp_path, preset_text("retsch-pm400-ma", 300)))


def test_plate_speed_limits_are_the_mills(tmp_path):
    path = write_preset(tmp_path, preset_text("fritsch-p7-premium", 1100, volume=45))
    assert load_preset(path).drive.plate_rpm == pytest.approx(1100)  # beyond the global 1000 rpm cap
    classic = write_preset(tmp_path, preset_text("fritsch-p7-classic", 1100, volume=45), "classic.toml")
    with pytest.raises(ConfigError, match=r"plate_rpm = 1100.0: allowed range \[100, 800\] rpm on the mill fritsch-p7-classic"):
        load_preset(classic)
    with pytest.raises(ConfigError, match=r"plate_rpm = 1100.0: allowed range \[100, 800\] rpm on the mill fritsch-p7-classic"):
        load_preset(path, {"mill": "fritsch-p7-classic", "plate_rpm": 1100.0})
    with pytest.raises(ConfigError, match=r"plate_rpm = 50.0: allowed range \[150, 1100\] rpm"):
        load_preset(path, {"plate_rpm": 50.0})


def test_the_p4_presets_resolve_as_before():
    for path in sorted((ROOT / "presets").glob("*.toml")):
        data = read_toml(path, "preset")
        p = load_preset(path)
        assert p.mill.name == "fritsch-p4" and p.warnings == ()
        assert p.plate_radius == data.get("plate_radius_mm", 125.0) * 1e-3
        speed = {"ratio": data["ratio"]} if "ratio" in data else {"jar_rpm": data["jar_rpm"]}
        assert p.drive == Drive.from_rpm(data["plate_rpm"], **speed, ramp_time=data.get("ramp_time", 1.0))


def test_a_users_mill_file_relative_to_the_preset_and_strictly_read(tmp_path):
    mill = (tmp_path / "mine.toml")
    good = ('maker = "Lab"\nmodel = "home-made"\nplate_radius_mm = 100\ngear = "free"\nratio_min = -3\nratio_max = 0\n'
            'stations = 2\nbowls_ml = [80]\n[sources]\nplate_radius_mm = "measured with a ruler"\n'
            '[estimates]\nratio_min = "motor limits"\nratio_max = "motor limits"\nstations = "counted"\nbowls_ml = "ours"\n')
    mill.write_text(good)
    text = preset_text("mine.toml", 200, ratio=-2).replace('jar_volume_ml = 80', 'jar = "CY"')
    p = load_preset(write_preset(tmp_path, text))
    assert p.mill.name == "mine" and p.plate_radius == pytest.approx(0.1)
    with pytest.raises(ConfigError, match=r"ratio = -3.5: mine drives the jar at K in \[-3, 0\]"):
        load_preset(write_preset(tmp_path, text.replace("ratio = -2", "ratio = -3.5")))
    for bad, words in ((good.replace("stations = 2", "stations = 2\nstaions = 3"), "unknown key 'staions'"),
                       (good.replace('plate_radius_mm = "measured with a ruler"\n', ""), "plate_radius_mm = 100: has no origin"),
                       (good + 'foo = "bar"\n', "estimates.foo"),
                       (good.replace("plate_radius_mm = 100", "plate_radius_mm = 3000"), "allowed range (0, 2000]"),
                       # a slip of units (m for mm) is refused with the jar, naming the mill file
                       (good.replace("plate_radius_mm = 100", "plate_radius_mm = 0.1"),
                        "mine.toml: plate_radius_mm = 0.1: allowed range (32.5, 2000] mm"),
                       (good.replace('gear = "free"', 'gear = "fixed"'), "ratio_min = -3: not used by gear = \"fixed\"")):
        mill.write_text(bad)
        with pytest.raises(ConfigError) as err:
            load_preset(write_preset(tmp_path, text))
        assert words in str(err.value) and "\n" not in str(err.value)


def test_mills_lists_every_mill_and_marks_estimates():
    code, out, err = main("mills")
    assert code == 0 and not err
    for name in SHIPPED:
        assert name in out
    assert "≈70.5*" in out and "* estimate" in out
    p4 = next(line for line in out.splitlines() if line.startswith("fritsch-p4 "))
    assert " 125 " in p4 and "≈125" not in p4  # the thesis' figure is sourced
    code, out, err = main("mills", "retsch-pm100")
    assert code == 0 and "estimate: effective sun-wheel diameter 141 mm" in out


def test_a_live_mill_keeps_its_mills_limits(tmp_path):
    from taimill.runs.live import LiveMill

    live = LiveMill(load_preset(write_preset(tmp_path, preset_text("fritsch-p7-classic", 400, volume=45)), {"ramp_time": 0.02}))
    live.set_speeds(plate_rpm=700)
    assert live.ratio == pytest.approx(-1.0) and live.plate_rpm == pytest.approx(700)
    with pytest.raises(ConfigError, match=r"TUI: plate_rpm = 900: allowed range \[0, 800\] rpm"):
        live.set_speeds(plate_rpm=900)
    with pytest.raises(ConfigError, match=r"TUI: ratio = -2.6: fritsch-p7-classic has a fixed gear 1:-2 \(K = -1\); ratio cannot be set"):
        live.set_speeds(ratio=-2.6)
    with pytest.raises(ConfigError, match=r"TUI: plate_rpm = 50: allowed range \[100, 800\] rpm on the mill fritsch-p7-classic"):
        live.set_speeds(plate_rpm=50)
    assert live.plate_rpm == pytest.approx(700)  # refused changes change nothing


def test_mills_are_a_sweep_axis(tmp_path):
    from taimill.runs.sweep import Request, plan

    path = write_preset(tmp_path, preset_text("retsch-pm100", 400))
    points = plan(Request(str(path), {}, {"mill": ["retsch-pm100", "fritsch-p7-premium"]}))
    assert [p["values"]["mill"] for p in points] == ["retsch-pm100", "fritsch-p7-premium"]
    assert [p["preset"].plate_radius for p in points] == [load_mill("retsch-pm100").plate_radius, 0.070]


@pytest.mark.parametrize("name", SHIPPED)
def test_export_liggghts_works_for_every_mill(name, tmp_path):
    from taimill.bridge.liggghts import DECK, export_case

    m = load_mill(name)
    lo, hi = m.plate_rpm_min or 100, m.plate_rpm_max or 400
    ratio = {"set": (m.gear.ks or (0,))[0], "free": -2.0}.get(m.gear.kind)
    p = load_preset(write_preset(tmp_path, preset_text(name, math.floor((lo + hi) / 2), ratio=ratio, volume=m.bowls_ml[-1])))
    export_case(p, tmp_path / "case")
    assert (tmp_path / "case" / "jar.stl").exists()
    assert f"origin {float(p.plate_radius)!r} 0. 0." in (tmp_path / "case" / DECK).read_text()
