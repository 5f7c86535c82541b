"""The population balance of particle sizes (taimill.outcome.grinding): the solver
against Reid's closed-form solution of first-order breakage, mass conservation, a
spectrum without events, the breakage probability and the Austin matrix."""

from __future__ import annotations

import math

import numpy as np
import pytest

from taimill.model.spectra import from_rows
from taimill.outcome.condition import Condition, read_file
from taimill.outcome.grinding import (Austin, Grinding, SizeClasses, breakage_probability, evolve, feed,
                                      friction_power_per_g, grind, passing, quantile_size, rate_matrix, selection)
from taimill.model.files import ROOT

CLASSES = SizeClasses(2e-3, 24)  # 2 mm down to 2 mm / 2^12 ≈ 0.5 µm, √2 apart
AUSTIN = Austin(0.4, 0.9, 3.5)  # a typical shape (Austin's φ, γ, β for brittle minerals lie about here)
HOUR = 3600.0


def reid(s: np.ndarray, b: np.ndarray, m0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Reid's solution of dM_i/dt = −S_i M_i + Σ_{j<i} b_ij S_j M_j for distinct S
    (Reid, Chem. Eng. Sci. 20 (1965) 953): M_i(t) = Σ_{j ≤ i} a_ij exp(−S_j t) with
    a_ij = Σ_{k=j}^{i−1} b_ik S_k a_kj / (S_i − S_j) for j < i and a_ii = M_i(0) − Σ_{j<i} a_ij."""
    n = len(s)
    a = np.zeros((n, n))
    for i in range(n):
        for j in range(i):
            a[i, j] = sum(b[i, k] * s[k] * a[k, j] for k in range(j, i)) / (s[i] - s[j])
        a[i, i] = m0[i] - a[i, :i].sum()
    return np.array([a @ np.exp(-s * ti) for ti in t])


def test_pure_first_order_breakage_matches_reids_solution():
    # distinct rates, decreasing with size as in ball milling (S ∝ x^0.8), the sink at 0:
    # the matrix exponential against the closed form, to 10⁻⁶ of the charge at every time
    x = CLASSES.sizes
    s = 1e-3 * (x / x[0]) ** 0.8
    s[-1] = 0.0
    b, kept = AUSTIN.matrix(CLASSES)
    net = s * (1 - kept)
    m0 = feed(CLASSES, 0.8e-3, 0.4)
    t = np.array([0.0, 60.0, HOUR, 8 * HOUR, 64 * HOUR])
    got = evolve(rate_matrix(s, b, kept), m0, t)
    want = reid(net, b, m0, t)
    assert np.max(np.abs(got - want)) < 1e-6
    assert got[-1, -1] > 10 * got[0, -1] and got[0] == pytest.approx(m0, abs=1e-15)  # fines grow; t = 0 is the feed


def test_mass_is_conserved_to_rounding_on_a_real_spectrum():
    cond = read_file(ROOT / "examples" / "outcome" / "condition-a.json")
    g = Grinding(AUSTIN, capture_g=1e-3, f_mat=0.5, xw_min=0.05, k_att=1e-3)
    m0 = feed(CLASSES, 1e-3, 0.5)
    t = np.linspace(0, 64 * HOUR, 65)
    m = grind(g, CLASSES, cond, m0, t)
    assert np.max(np.abs(m.sum(axis=1) - 1.0)) < 1e-12
    assert np.all(m > -1e-12)
    q = passing(CLASSES, m)
    x50 = quantile_size(CLASSES, q, 0.5)
    assert np.all(np.diff(x50[np.isfinite(x50)]) <= 0) and not x50[-1] >= x50[0]  # finer with time (nan: below the finest edge)


def test_a_spectrum_without_events_leaves_the_powder_as_it_was():
    empty = Condition("empty", from_rows({k: np.zeros(0) for k in ("t_start", "kind", "un", "ut", "m_eff",
                                                                  "dissipated_normal", "dissipated_friction")},
                                         0.0, 10.0, 0.01), 5.0)
    g = Grinding(AUSTIN, capture_g=1e-3, f_mat=0.5, xw_min=0.05, k_att=1e-3)
    m0 = feed(CLASSES, 1e-3, 0.5)
    assert np.array_equal(grind(g, CLASSES, empty, m0, [0.0, HOUR, 64 * HOUR]), np.tile(m0, (3, 1)))


def test_breakage_probability_has_its_threshold_and_saturates():
    f_mat, xw_min = 0.8, 0.05  # kg/(J m), J m/kg
    x = 100e-6
    w_min = xw_min / x
    assert breakage_probability(x, 0.99 * w_min, f_mat, xw_min) == 0.0
    w = np.array([1.01, 2, 10, 1e3]) * w_min
    p = breakage_probability(x, w, f_mat, xw_min)
    assert np.all(np.diff(p) > 0) and p[-1] == pytest.approx(1.0)
    assert p[1] == pytest.approx(1 - math.exp(-f_mat * x * (2 * w_min - w_min)), rel=1e-14)
    # a smaller particle needs more specific energy
    assert breakage_probability(x / 10, 2 * w_min, f_mat, xw_min) == 0.0


def test_austin_matrix_sends_every_broken_mass_below_its_class():
    b, kept = AUSTIN.matrix(CLASSES)
    assert np.allclose(b[:, :-1].sum(axis=0), 1.0, rtol=0, atol=1e-14) and not b[:, -1].any()
    assert np.all(np.triu(b) == 0) and np.all((kept > 0) & (kept < 1) | (np.arange(len(kept)) == len(kept) - 1))
    y, x = CLASSES.edges[3], CLASSES.edges[5]
    assert b[5:, 3].sum() == pytest.approx(AUSTIN.passing(x, y) / AUSTIN.passing(CLASSES.edges[4], y), rel=1e-12)


def test_friction_drives_attrition_where_impacts_break_nothing():
    # a friction-led charge: the impact route's threshold above every event, so only
    # the friction work grinds (what a standard-gear mill's sliding bed does)
    cond = read_file(ROOT / "examples" / "outcome" / "condition-a.json")
    hard = Grinding(AUSTIN, capture_g=1e-3, f_mat=0.5, xw_min=1e9)
    s = selection(hard, CLASSES, cond)
    assert not s["impact"].any() and not s["attrition"].any()
    worn = Grinding(AUSTIN, capture_g=1e-3, f_mat=0.5, xw_min=1e9, k_att=0.01)
    s = selection(worn, CLASSES, cond)
    p_f = friction_power_per_g(cond)
    assert p_f > 0 and s["attrition"][:-1] == pytest.approx(0.01 * p_f, rel=1e-15) and s["attrition"][-1] == 0


def test_quantiles_of_a_log_normal_feed():
    m0 = feed(CLASSES, 100e-6, 0.5)
    q = passing(CLASSES, m0)
    x10, x50, x90 = (quantile_size(CLASSES, q, f)[0] for f in (0.1, 0.5, 0.9))
    assert x50 == pytest.approx(100e-6, rel=0.02)  # log-linear between √2 edges
    assert x90 / x50 == pytest.approx(math.exp(1.2816 * 0.5), rel=0.03) and x10 < x50 < x90


@pytest.mark.parametrize("bad", [dict(top_m=-1, n=10), dict(top_m=1e-3, n=1), dict(top_m=1e-3, n=10, ratio=3.0)])
def test_size_classes_refuse_what_is_not_a_sieve_series(bad):
    with pytest.raises(ValueError):
        SizeClasses(**bad)


# ---------------------------------------------------------------- through the real CLI
def _cli(*args, cwd=ROOT):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "taimill", *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_sizes_check_reads_units_from_the_header(tmp_path):
    # the same log-normal distribution in µm and percent, and in mm and fractions: one x50
    m0 = feed(CLASSES, 100e-6, 0.5)
    q = passing(CLASSES, m0)[0][::-1]
    x = CLASSES.edges[::-1]
    keep = (q > 0.001) & (q < 0.999)
    um = ["condition,time_h,size_um,passing_pct"] + [f"a.json,0,{xi * 1e6:.9g},{qi * 100:.9g}" for xi, qi in zip(x[keep], q[keep])]
    mm = ["condition,time_min,size_mm,passing_fraction"] + [f"a.json,0,{xi * 1e3:.9g},{qi:.9g}" for xi, qi in zip(x[keep], q[keep])]
    for name, lines in (("um.csv", um), ("mm.csv", mm)):
        (tmp_path / name).write_text("\n".join(lines) + "\n")
        res = _cli("sizes", "check", tmp_path / name, "--json")
        assert res.returncode == 0, res.stderr
        import json

        d = json.loads(res.stdout)["distributions"]
        assert len(d) == 1 and d[0]["x50_m"] == pytest.approx(100e-6, rel=0.02) and d[0]["points"] == keep.sum()


def test_sizes_predict_grinds_finer_with_time_and_finds_the_time_to_a_target(tmp_path):
    import json

    (tmp_path / "params.toml").write_text("[breakage]\nphi = 0.4\ngamma = 0.9\nbeta = 3.5\n[impact]\ncapture_g = 0.001\n"
                                          "f_mat = 0.5\nxw_min = 0.05\n")
    a, b = (ROOT / "examples" / "outcome" / f"condition-{c}.json" for c in "ab")
    res = _cli("sizes", "predict", tmp_path / "params.toml", a, b, "--feed-x50", 200, "--hours", "0,1,4",
               "--target-x90", 20, "--json")
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)["conditions"]
    for r in rows:
        x90 = r["x90_m"]
        assert x90[0] == pytest.approx(200e-6 * math.exp(1.2816 * 0.5), rel=0.03) and x90[0] > x90[1] > x90[2]
        t = r["time_to_target_x90_s"]
        assert 0 < t < math.inf
    # the time found is where the curve crosses the target
    cond = read_file(a)
    g = Grinding(AUSTIN.__class__(0.4, 0.9, 3.5), capture_g=1e-3, f_mat=0.5, xw_min=0.05)
    classes = SizeClasses.spanning(0.1e-6, 800e-6)
    m0 = feed(classes, 200e-6, 0.5)
    t = rows[0]["time_to_target_x90_s"]
    before, after = (quantile_size(classes, passing(classes, grind(g, classes, cond, m0, [f * t])), 0.9)[0]
                     for f in (0.99, 1.01))
    assert before > 20e-6 >= after


def test_a_sliding_bed_without_events_grinds_by_the_friction_of_its_whole_charge(tmp_path):
    # a friction-led charge: no event closes in the window, all its power is the friction
    # of persistent contacts, which the run summary carries (shear_w_per_g) and no spectrum
    from taimill.outcome.condition import write_file

    empty = from_rows({k: np.zeros(0) for k in ("t_start", "kind", "un", "ut", "m_eff", "dissipated_normal",
                                                "dissipated_friction")}, 4.0, 24.0, 0.01)
    bed = Condition("bed", empty, 2.1, shear_w_per_g=0.83)
    g = Grinding(AUSTIN, capture_g=1e-3, f_mat=0.5, xw_min=0.05, k_att=1e-4)
    s = selection(g, CLASSES, bed)
    assert not s["impact"].any() and s["attrition"][:-1] == pytest.approx(1e-4 * 0.83, rel=1e-15)
    m = grind(g, CLASSES, bed, feed(CLASSES, 20e-6), [0.0, 8 * HOUR])
    x50 = quantile_size(CLASSES, passing(CLASSES, m), 0.5)
    assert x50[1] < x50[0] / 2  # finer by friction alone
    write_file(tmp_path / "bed.json", empty, 2.1, "SYNTHETIC sliding bed", shear_w_per_g=0.83)
    assert read_file(tmp_path / "bed.json").shear_w_per_g == 0.83
    write_file(tmp_path / "old.json", empty, 2.1, "SYNTHETIC without the key")
    assert math.isnan(read_file(tmp_path / "old.json").shear_w_per_g)
    assert friction_power_per_g(read_file(tmp_path / "old.json")) == 0.0  # the spectra's events alone: none here
