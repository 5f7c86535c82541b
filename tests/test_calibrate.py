"""Calibration and validation tooling (issue 8): drop tests over several heights, the
fit of d (thesis §2.2.1) to synthetic data and to thesis Table 2.1, pair files used by
presets, the ±50 % sensitivity (Fig 2.5), the two-sphere impacts of Fig 2.8 against
eqs 2.3/2.4, and bad input. The Table 2.1 fit and the issue's three bad inputs go
through the CLI in a subprocess; the other commands call `taimill.cli.main` in this
process, which keeps its compiled kernels (a subprocess costs seconds to start)."""

import json
import math
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from taimill.calibration.data import TABLE_2_1, load_drop_data
from taimill.calibration.fit import FitError, fit_drops
from taimill.calibration.impacts import oblique
from taimill.calibration.optimise import brent
from taimill.cli import main
from taimill.errors import ConfigError
from taimill.model.contact_sets import pair_contact
from taimill.model.preset import load_preset
from taimill.model import laws as laws_np
from taimill.calibration.runs import drop_test, drop_tests
from taimill.runs.simulation import run
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink

ROOT = Path(__file__).resolve().parent.parent
OFFSETS_MM = list(range(13))  # thesis Fig 2.8: Δ = 0 … 12 mm (12 = 2r, grazing)
PNG = b"\x89PNG"


def taimill(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "taimill.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def cli(capsys, *args):
    """`taimill ARGS` in this process: (exit code, stdout, stderr lines but the notice
    that kernels are compiled, which comes whenever this process has none for the size)."""
    capsys.readouterr()
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, [ln for ln in out.err.strip().splitlines() if not ln.startswith("taimill: compiling kernels")]


@pytest.fixture(scope="module")
def table_fit(tmp_path_factory):
    """`taimill calibrate fit` of d to Table 2.1, writing a pair file and a figure."""
    where = tmp_path_factory.mktemp("fit")
    res = taimill("calibrate", "fit", "--pair", "zirconia-zirconia", "--data", TABLE_2_1, "--out", where / "zr-fit.toml",
                  "--figure", where / "fit.png", "--json")
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout), where




# ------------------------------------------------------------------ optimiser
@pytest.mark.parametrize("f,a,b,c,x_min", [
    (lambda x: (x - 0.3) ** 2 + 1, -1.0, 0.0, 2.0, 0.3),
    (lambda x: math.cosh(x - 1.234), 0.0, 1.0, 3.0, 1.234),
    (lambda x: math.exp(x) - 2 * x, -1.0, 0.2, 3.0, math.log(2)),
    (lambda x: abs(x - 0.7), 0.0, 0.5, 1.0, 0.7),  # a kink: golden-section steps must take over
])
def test_brent_finds_the_minimum_inside_its_bracket(f, a, b, c, x_min):
    x, fx, calls = brent(f, a, b, c, xtol=1e-8)
    assert x == pytest.approx(x_min, abs=1e-7)
    assert calls < 45


# ------------------------------------------------------------------ fits
def _table(e):
    from taimill.calibration.data import DropData

    return DropData("table.csv", np.array([0.1, 0.5]), np.array(e), np.array([np.nan, np.nan]))


def test_fit_search_finds_a_minimum_next_to_the_end_of_the_range_and_fails_beyond_it():
    # A stand-in model e = x/(1 + x) per row (x = d in mm): the search must find a
    # minimum between the last two grid points, and refuse one beyond the range.
    def model(values):
        x = np.asarray(values, float)[:, None]
        return np.repeat(x / (1 + x), 2, axis=1)

    hi = fit_drops("zirconia-zirconia", _table([0.5, 0.5]), model=model)["range"][1]
    x_near_end = 0.8 * hi
    fit = fit_drops("zirconia-zirconia", _table([x_near_end / (1 + x_near_end)] * 2), model=model)
    assert fit["value"] == pytest.approx(x_near_end, rel=2e-3)
    beyond = 2 * hi / (1 + 2 * hi)
    with pytest.raises(FitError, match=r"table\.csv: no d in .* the best lies at the upper end"):
        fit_drops("zirconia-zirconia", _table([beyond] * 2), model=model)


def test_fit_recovers_a_known_d_from_synthetic_drops(tmp_path):
    # Issue acceptance: data generated with a known d are fitted back within 2 %. The
    # synthetic drops run at their own automatic dt, the fit at the pair's: the e they
    # differ by (~1e-4) moves d by ~0.1 %, well inside 2 %.
    d_true = 0.16
    heights = [0.1, 0.3, 0.5, 0.8]
    runs = drop_tests("zirconia-zirconia", heights, contact={"ball_wall": {"d_mm": d_true}})
    csv = tmp_path / "synthetic.csv"
    csv.write_text("h0_mm,e\n" + "".join(f"{r['h0'] * 1e3:g},{r['e']!r}\n" for r in runs))
    fit = fit_drops("zirconia-zirconia", load_drop_data(csv))
    assert fit["param"] == "d" and fit["law"] == "adams-impact"
    assert fit["value"] == pytest.approx(d_true, rel=0.02)
    assert fit["start"] != pytest.approx(d_true, rel=0.5)  # it had to travel from the eq 2.9/2.11 guess
    assert fit["rms_e"] < 1e-3
    assert fit["uncertainty"] < 0.02 * d_true


@pytest.mark.full
@pytest.mark.parametrize("law,param,key,true", [
    ("adams-impact", "c_max", "c_max_Ns_per_mm", 0.4),
    ("hertz-damper", "e", "e", 0.8),
])
def test_fit_recovers_c_max_and_e_from_synthetic_drops(tmp_path, law, param, key, true):
    # As for d: the other fitted parameters come back within 2 %.
    heights = [0.1, 0.3, 0.5, 0.8]
    runs = drop_tests("zirconia-zirconia", heights, law=law, contact={"ball_wall": {key: true}})
    csv = tmp_path / "synthetic.csv"
    csv.write_text("h0_mm,e\n" + "".join(f"{r['h0'] * 1e3:g},{r['e']!r}\n" for r in runs))
    fit = fit_drops("zirconia-zirconia", load_drop_data(csv), law=law, param=param)
    assert fit["param"] == param and fit["value"] == pytest.approx(true, rel=0.02)


@pytest.mark.full
@pytest.mark.parametrize("pair,h0_mm,e,d_thesis", [("steel-steel", 500, 0.516, 0.211), ("zirconia-zirconia", 555, 0.90, 0.114)])
def test_thesis_procedure_one_drop_height_gives_the_thesis_d(tmp_path, pair, h0_mm, e, d_thesis):
    # Thesis §2.2.1: d fitted so that one drop (12 mm steel ball from 500 mm, e = 0.516;
    # zirconia at 3.3 m/s, e = 0.9) rebounds as measured; Tables 3.2 / 5.2 give 0.211 and
    # 0.114 mm. Measured here: 0.206 and 0.112 mm. 5 %: the thesis' integrator (HHT) and
    # step differ, and e is quoted to 3 and 1 digits.
    csv = tmp_path / "one.csv"
    csv.write_text(f"h0_mm,e\n{h0_mm},{e}\n")
    fit = fit_drops(pair, load_drop_data(csv))
    assert fit["value"] == pytest.approx(d_thesis, rel=0.05)
    assert fit["rows"][0]["e_fit"] == pytest.approx(e, abs=1e-3)


def fit_table(text: str) -> list[list[str]]:
    """The rows of `taimill calibrate fit`'s printed table, split into cells."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.split()[:2] == ["h0", "mm"]) + 1
    return [line.split() for line in lines[start:] if line.split() and line.split()[0][0].isdigit()]


@pytest.mark.parametrize("columns", ["h0_mm,rebound_mm,e", "h0_mm,e"])
def test_fit_table_shows_the_measured_rebound_of_the_data(tmp_path, capsys, columns):
    # Table 2.1's rows at 300 and 700 mm: e² h0 = 221.9 and 592.5 mm, measured 215 and 582
    rows = {"300": ("215", "0.86"), "700": ("582", "0.92")}
    csv = tmp_path / "drops.csv"
    csv.write_text(columns + "\n" + "".join(f"{h},{hr},{e}\n" if "rebound" in columns else f"{h},{e}\n"
                                            for h, (hr, e) in rows.items()))
    code, out, _ = cli(capsys, "calibrate", "fit", "--pair", "zirconia-zirconia", "--data", csv)
    assert code == 0, out
    shown = {cells[0]: cells for cells in fit_table(out)}  # h0, e meas, e sim, Δe, h* meas, h* sim, Δh*, 2σ
    for h, (hr, e) in rows.items():
        expected = float(hr) if "rebound" in columns else float(e) ** 2 * float(h)
        assert float(shown[h][4]) == pytest.approx(expected, abs=0.05)
        assert float(shown[h][6]) == pytest.approx(float(shown[h][5]) - expected, abs=0.11)
    assert ("e²·h0 where the data give no rebound_mm" in out) == ("rebound" not in columns)


def test_table_2_1_fit_of_d_next_to_the_thesis_value(table_fit):
    # Thesis §2.2.1 fitted d = 0.114 mm at one height (3.3 m/s ≈ 555 mm); fitting all
    # eight heights of Table 2.1 must land within 15 % of it (c_max fixed at 0.57 N·s/mm).
    fit, where = table_fit
    assert fit["param"] == "d" and fit["pair_value"] == pytest.approx(0.114)
    assert fit["value"] == pytest.approx(0.114, rel=0.15)
    assert 0 < fit["uncertainty"] < 0.3 * fit["value"]
    rows = fit["rows"]
    assert [r["h0_mm"] for r in rows] == pytest.approx([100, 200, 300, 400, 500, 600, 700, 800])
    # h* meas is the table's measured rebound, not e² h0 of its (fitted) mean e
    assert [r["rebound_measured_mm"] for r in rows] == pytest.approx([76, 155, 215, 322, 404, 483, 582, 646])
    for r in rows:
        assert r["rebound_measured_from"] == "rebound_mm"
        assert r["residual_mm"] == pytest.approx(r["e_fit"] ** 2 * r["h0_mm"] - r["rebound_measured_mm"], abs=1e-9)
    # The Adams law's e falls with speed (damping ramps in over d ≫ u_max) while the
    # data stay near 0.9: around the thesis' fitting speed (500, 600 mm) it is within
    # the 2σ = 0.04 scatter, at 100-300 mm it is not — and the fit says so.
    e_fit = [r["e_fit"] for r in rows]
    assert all(np.diff(e_fit) < 0)
    assert rows[4]["within_scatter"] and rows[5]["within_scatter"]
    assert not rows[0]["within_scatter"] and not fit["within_scatter"]
    assert (where / "fit.png").read_bytes()[:4] == PNG


def test_table_2_1_within_scatter_with_a_constant_restitution_law():
    # Table 2.1 within its scatter: σ_e = 0.02 per height (the spread of the eight e
    # about their mean; the thesis reduces them to e = 0.90), "within" = |Δe| ≤ 2σ.
    # The constant-e law fits every height and gives e next to the thesis' e_average.
    fit = fit_drops("zirconia-zirconia", load_drop_data(TABLE_2_1), law="hertz-mindlin")
    assert fit["param"] == "e"
    assert fit["within_scatter"], fit["rows"]
    assert fit["chi2_per_dof"] < 2.0
    assert fit["value"] == pytest.approx(0.90, abs=0.02)


def test_a_preset_runs_with_the_written_pair_file_and_its_fitted_d(table_fit, tmp_path):
    fit, where = table_fit
    (tmp_path / "pairs").mkdir()
    shutil.copy(where / "zr-fit.toml", tmp_path / "pairs" / "zr-fit.toml")
    preset = tmp_path / "efv-fit.toml"
    text = (ROOT / "presets" / "efv-zirconia-60rpm.toml").read_text()
    preset.write_text(text.replace('pair = "zirconia-zirconia"', 'pair = "pairs/zr-fit.toml"'))  # relative to the preset
    p = load_preset(preset)
    d = fit["value"] * 1e-3
    assert p.ball_wall.d == pytest.approx(d, rel=1e-12) and p.ball_ball.d == pytest.approx(d, rel=1e-12)
    builtin = load_preset(ROOT / "presets" / "efv-zirconia-60rpm.toml")
    assert p.friction.mu_s == builtin.friction.mu_s and p.ball_wall.c == builtin.ball_wall.c
    out = tmp_path / "run.zarr"
    summary = run(p, ZarrSink(out), duration=0.05)  # the cwd is the repo, not the preset's directory
    assert summary["status"] == "complete" and summary["sim_seconds"] == pytest.approx(0.05, abs=0.011)
    assert open_run(out).config["ball_wall"]["d"] == pytest.approx(d, rel=1e-12)


def test_a_fit_that_cannot_match_fails_with_a_clear_message(tmp_path, capsys):
    # e = 0.02 at 500 mm: even d → 0 (full damping c_max from first touch) rebounds higher.
    csv = tmp_path / "too-plastic.csv"
    csv.write_text("h0_mm,e\n500,0.02\n")
    code, out, err = cli(capsys, "calibrate", "fit", "--pair", "zirconia-zirconia", "--data", csv, "--out", tmp_path / "x.toml")
    assert code == 1 and out == "" and len(err) == 1
    assert "too-plastic.csv" in err[0] and "no d in" in err[0] and "lower end" in err[0] and "--param c_max" in err[0]
    assert not (tmp_path / "x.toml").exists()


# ------------------------------------------------------------------ drop tests and sensitivity
def test_calibrate_drop_takes_several_heights(capsys, tmp_path):
    code, out, _ = cli(capsys, "calibrate", "drop", "--pair", "zirconia-zirconia", "--h0", 100, 400, 800, "--json",
                       "--figure", tmp_path / "drops.png")
    assert code == 0
    rs = json.loads(out)
    assert (tmp_path / "drops.png").read_bytes()[:4] == PNG
    assert [r["h0"] for r in rs] == pytest.approx([0.1, 0.4, 0.8])
    for r in rs:  # the batched runs equal single ones (each mill is independent in the kernel)
        assert r["e"] == pytest.approx(drop_test("zirconia-zirconia", r["h0"])["e"], rel=1e-12)
        assert r["rebound_height"] == pytest.approx(r["e"] ** 2 * r["h0"], rel=1e-9)
    assert rs[0]["e"] > rs[1]["e"] > rs[2]["e"]  # the Adams law's e falls with impact speed


def test_sensitivity_pm50_table_thesis_fig_2_5(tmp_path, capsys):
    fig = tmp_path / "fig25.svg"
    code, out, _ = cli(capsys, "calibrate", "sensitivity", "--pair", "steel-steel", "--json", "--figure", fig)
    assert code == 0
    s = json.loads(out)
    assert "<svg" in fig.read_text()
    rows = {(r["parameter"], r["factor"]): r for r in s["rows"]}
    assert set(rows) == {("reference", 1.0)} | {(p, f) for p in "kncd" for f in (0.5, 1.5)}
    ref = rows["reference", 1.0]
    assert ref["e"] == pytest.approx(0.52, abs=0.03)  # thesis: 0.516 at h0 = 500 mm
    # Each row is a real drop with that one parameter changed: the same drops through
    # the contact-set override (contact_sets.pair_contact) give the same rebound.
    for (p, key, base), f in ((("d", "d_mm", 0.211), 1.5), (("c", "c_max_Ns_per_mm", 17.5), 0.5)):
        alone = drop_test("steel-steel", 0.5, contact={"ball_wall": {key: base * f}})
        assert rows[p, f]["rebound_height"] == pytest.approx(alone["rebound_height"], rel=1e-9)
        assert rows[p, f]["change"] == pytest.approx(alone["rebound_height"] - ref["rebound_height"], abs=1e-12)
    # More damping, lower rebound; a deeper ramp d, less damping, higher rebound.
    assert rows["c", 1.5]["change"] < 0 < rows["c", 0.5]["change"]
    assert rows["d", 0.5]["change"] < 0 < rows["d", 1.5]["change"]


# ------------------------------------------------------------------ thesis Fig 2.8
def test_oblique_constant_e_law_follows_eqs_2_3_and_2_4():
    # Issue acceptance: hertz-mindlin (e = 0.516, frictionless), 3300 mm/s, Δ = 0…12 mm:
    # final relative velocities within 2 % of eqs 2.3/2.4 at every offset, normal
    # -e·u̇_n, tangential unchanged. Measured: ≤ 0.6 % (the engine's e at 60 steps per
    # contact is 0.5136) and ≤ 0.25 %.
    o = oblique("steel-steel", [x * 1e-3 for x in OFFSETS_MM], 3.3, law="hertz-mindlin")
    assert o["e_nominal"] == 0.516 and not o["friction"]
    for r in o["rows"]:
        if r["offset_mm"] == 12:  # grazing: no contact, nothing changes
            assert r["contacts"] == 0 and r["un_final"] == 0.0 and r["ut_final"] == pytest.approx(3.3, rel=1e-12)
            continue
        assert r["contacts"] == 1
        assert r["un_final"] == pytest.approx(-0.516 * r["un"], rel=0.02), r
        if r["offset_mm"]:
            assert r["ut_final"] == pytest.approx(r["ut"], rel=0.02), r
        else:
            assert abs(r["ut_final"]) < 1e-9
        assert r["un"] ** 2 + r["ut"] ** 2 == pytest.approx(3.3**2, rel=1e-9)  # a rotation of the impact velocity


def test_oblique_adams_law_normal_from_head_on_e_and_thesis_formula_off(tmp_path, capsys):
    # Issue acceptance: with the Adams law e depends on u̇_n: the normal component must
    # be -e(u̇_n)·u̇_n with e from a head-on run at that normal speed (2 %), the
    # tangential unchanged (2 %), and the table shows the constant e = 0.516 formula's
    # deviation. Measured: ≤ 0.1 % and ≤ 0.2 %.
    fig = tmp_path / "fig28.png"
    code, out, _ = cli(capsys, "calibrate", "oblique", "--pair", "steel-steel", "--offsets", "0:12:1", "--json", "--figure", fig)
    assert code == 0 and fig.read_bytes()[:4] == PNG
    o = json.loads(out)
    assert [r["offset_mm"] for r in o["rows"]] == pytest.approx(OFFSETS_MM)
    assert o["law"] == "adams-impact"
    _, _, bb, _, _ = pair_contact("steel-steel")
    for r in o["rows"][:-1]:
        # the head-on e is the law's e at u̇_n (RK4 twin; 5e-3: the engine's dt resolution)
        e_rk4 = laws_np.simulate_impact(bb.model, bb.k, bb.c, bb.d, bb.m_eff, r["un"])["e"][0]
        assert r["e_head_on"] == pytest.approx(e_rk4, abs=5e-3)
        assert r["un_final"] == pytest.approx(-r["e_head_on"] * r["un"], rel=0.02)
        if r["offset_mm"]:
            assert r["ut_final"] == pytest.approx(r["ut"], rel=0.02)
        thesis = -0.516 * r["un"]
        assert r["un_final_thesis"] == pytest.approx(thesis, rel=1e-12)
        assert r["thesis_error"] == pytest.approx((thesis - r["un_final"]) / abs(r["un_final"]), rel=1e-9)
    errors = [r["thesis_error"] for r in o["rows"][:-1]]
    assert errors[0] > 0.05 and all(np.diff(errors) > 0)  # slower normal impacts rebound more: the gap grows with Δ
    assert o["rows"][-1]["contacts"] == 0


# ------------------------------------------------------------------ bad input
BAD_CSV = {
    "missing-columns.csv": "height,bounce\n100,76\n",
    "negative-height.csv": "h0_mm,rebound_mm\n100,76\n-200,150\n",
    "rebound-above.csv": "h0_mm,rebound_mm\n100,160\n",
    "not-a-number.csv": "h0_mm,e\n100,high\n",
}
BAD_PAIR = '[pair.bad]\ncontact = "zirconia"\nmu_s = 0.5\nmu_d = 0.9\nv_s_mm_s = 1\nv_d_mm_s = 10\n'

# (name, arguments, words the one-line message must contain)
BAD = [
    ("unknown pair", ["drop", "--pair", "steel-unobtainium", "--h0", 100], ["command line", "pair", "steel-unobtainium", "steel-steel"]),
    ("negative height", ["drop", "--pair", "steel-steel", "--h0", 100, -50], ["command line", "--h0", "-50", "(0, 10000]"]),
    ("csv missing columns", ["fit", "--pair", "steel-steel", "--data", "missing-columns.csv"], ["missing-columns.csv", "columns", "height,bounce", "h0_mm"]),
    ("csv negative height", ["fit", "--pair", "steel-steel", "--data", "negative-height.csv"], ["negative-height.csv", "h0_mm (line 3)", "-200", "(0, 10000]"]),
    ("csv rebound above drop", ["fit", "--pair", "steel-steel", "--data", "rebound-above.csv"], ["rebound-above.csv", "rebound_mm (line 2)", "160"]),
    ("csv not a number", ["fit", "--pair", "steel-steel", "--data", "not-a-number.csv"], ["not-a-number.csv", "e (line 2)", "high", "number"]),
    ("missing data file", ["fit", "--pair", "steel-steel", "--data", "nothere.csv"], ["nothere.csv", "cannot read"]),
    ("unknown pair in fit", ["fit", "--pair", "zirconia-air", "--data", TABLE_2_1], ["pair", "zirconia-air"]),
    ("param of another law", ["fit", "--pair", "steel-steel", "--law", "hertz-mindlin", "--param", "d", "--data", TABLE_2_1], ["--param", "'d'", "e (law hertz-mindlin"]),
    ("offset beyond grazing", ["oblique", "--pair", "steel-steel", "--offsets", "0,13"], ["--offsets", "13", "[0, 12]"]),
    ("bad pair file", ["drop", "--pair", "bad-pair.toml", "--h0", 100], ["bad-pair.toml", "pair.bad.mu_d", "0.9"]),
    ("missing pair file", ["drop", "--pair", "gone.toml", "--h0", 100], ["pair", "gone.toml", "no pair file"]),
]
IN_SUBPROCESS = ("unknown pair", "negative height", "csv missing columns")  # the three, end to end


@pytest.fixture
def bad_files(tmp_path, monkeypatch):
    for file, text in BAD_CSV.items():
        (tmp_path / file).write_text(text)
    (tmp_path / "bad-pair.toml").write_text(BAD_PAIR)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("name,args,words", BAD, ids=[b[0] for b in BAD])
def test_bad_input_gives_one_line_error_and_exit_2(bad_files, capsys, name, args, words):
    if name in IN_SUBPROCESS:
        res = taimill("calibrate", *args, cwd=bad_files)
        code, out, err = res.returncode, res.stdout, res.stderr.strip().splitlines()
        assert "Traceback" not in res.stderr
    else:
        code, out, err = cli(capsys, "calibrate", *args)
    assert code == 2 and out == "", (out, err)
    assert len(err) == 1, err
    for w in words:
        assert str(w) in err[0], err[0]


def test_pair_file_layout_errors_name_the_file(tmp_path):
    bad = tmp_path / "two.toml"
    bad.write_text(BAD_PAIR.replace("mu_d = 0.9", "mu_d = 0.4") + BAD_PAIR.replace("[pair.bad]", "[pair.other]").replace("mu_d = 0.9", "mu_d = 0.4"))
    preset = tmp_path / "p.toml"
    preset.write_text(textwrap.dedent("""\
        jar = "EFV45"
        pair = "two.toml"
        plate_rpm = 60
        ratio = -3.4
        duration = 1.0
        [balls]
        count = 20
        material = "zirconia"
        radius_mm = 3
        """))
    with pytest.raises(ConfigError, match=r"two\.toml: pair = \['bad', 'other'\]: a pair file needs exactly one"):
        load_preset(preset)
