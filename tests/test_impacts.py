"""Single impacts on the real engine against the thesis and analytic results (docs/validation.md):
drop tests, the two-sphere impacts of thesis §2.3, Chung & Ooi (2011) benchmarks."""

import math

import numpy as np
import pytest

from helpers import FRICTIONLESS, dt_for, elastic, steel, two_ball_impact
from taimill.model.materials import Friction
from taimill.model.contact_sets import NormalLaw, pair_contact
from taimill.model import laws as laws_np
from taimill.model.contact.registry import CONSTANT_E_LAWS
from taimill.calibration.runs import drop_test, impact_spec, run_spec

G = 9.81


def test_steel_drop_test_matches_thesis():
    # Issue acceptance: e within 0.03 of 0.52 (measured 0.516), 12 mm ball from 500 mm
    # with Table 3.2 parameters (the Adams law; its e depends on speed).
    r = drop_test("steel-steel", 0.5)
    assert r["e"] == pytest.approx(0.52, abs=0.03)
    assert r["rebound_height"] == pytest.approx(r["e"] ** 2 * 0.5, rel=1e-9)


def test_zirconia_drop_test_matches_thesis():
    # Table 2.1: e = 0.90 (0.86-0.92 over the heights); at 3.3 m/s within 0.02.
    r = drop_test("zirconia-zirconia", 3.3**2 / (2 * G))
    assert r["e"] == pytest.approx(0.90, abs=0.02)


def test_ball_ball_rebounds_higher_than_ball_plate():
    # Thesis §2.2.1: "a rebound h* approximately 20 % higher than for the sphere-plate
    # case". Two free balls give +27 %; accept +10 … +35 % (the thesis does not say how
    # its ball-ball drop was held).
    plate = drop_test("steel-steel", 0.5)
    ball = drop_test("steel-steel", 0.5, target="ball")
    assert 1.10 < ball["rebound_height"] / plate["rebound_height"] < 1.35


def test_engine_restitution_equals_the_law_integrated_finely():
    # The engine's symplectic step at the automatic dt against RK4 with 2000 steps per
    # contact: within 0.005 (the convergence bound we accept for e).
    _, _, bb, bw, _ = steel()
    for h0 in (0.05, 0.5, 2.0):
        v = math.sqrt(2 * G * h0)
        ref = laws_np.simulate_impact(bw.model, bw.k, bw.c, bw.d, bw.m_eff, v)["e"][0]
        assert drop_test("steel-steel", h0)["e"] == pytest.approx(ref, abs=5e-3)


def test_drop_test_converges_in_dt():
    # Halving dt from the automatic value changes e by < 0.003 (the time-step check).
    auto = drop_test("steel-steel", 0.5)
    half = drop_test("steel-steel", 0.5, dt=auto["dt"] / 2)
    assert abs(auto["e"] - half["e"]) < 3e-3


@pytest.mark.parametrize("law", CONSTANT_E_LAWS)
def test_constant_restitution_laws_deliver_e_in_the_engine(law):
    # Chung & Ooi case 2 (normal impact with a plane at several restitutions), on the
    # engine: measured e within 0.01 of nominal (dt-resolution of the clamp's release).
    for e in (0.3, 0.6, 0.9):
        ball, jar, bb, bw, fr = pair_contact("steel-steel", law=law)
        c = laws_np.calibrate_damping(bw.model, e, bw.k, bw.m_eff, bw.u_ref, bw.d)
        law_e = NormalLaw(bw.law, bw.k, bw.n, c, bw.d, bw.m_eff, e, bw.u_ref)
        v = 2.0
        dt = dt_for(law_e, v, 80)
        spec = impact_spec(ball, jar, bb, law_e, FRICTIONLESS, [[0, 0, ball.radius + 1e-7]], [[0, 0, -v]],
                           gravity=0.0, dt=dt, steps=int(3e-4 / dt))
        state, events = run_spec(spec)
        assert len(events["t_start"]) == 1
        assert state["v"][0, 2] / v == pytest.approx(e, abs=0.01)


def test_elastic_normal_impact_matches_hertz_theory():
    # Chung & Ooi case 1: duration and peak force of an elastic sphere-plane impact vs
    # Hertz. Tolerance 1 %: duration is counted in steps (200 per contact → 0.5 %).
    ball, jar, bb, bw, _ = steel()
    law = elastic(bw)
    v = 1.0
    dt = dt_for(law, v, 200)
    spec = impact_spec(ball, jar, bb, law, FRICTIONLESS, [[0, 0, ball.radius]], [[0, 0, -v]], gravity=0.0,
                       dt=dt, steps=int(2e-4 / dt))
    state, ev = run_spec(spec)
    m, k = ball.mass, law.k
    u_max = (5 * m * v**2 / (4 * k)) ** 0.4  # ½mv² = 2/5 k u^(5/2)
    assert ev["duration"][0] == pytest.approx(2.9432 * u_max / v, rel=0.01)
    assert ev["peak_force"][0] == pytest.approx(k * u_max**1.5, rel=0.01)
    assert ev["peak_penetration"][0] == pytest.approx(u_max, rel=0.01)
    assert state["v"][0, 2] == pytest.approx(v, rel=1e-3)  # elastic: e = 1


@pytest.mark.parametrize("offset_mm", [0, 3, 6, 9])
def test_frictionless_two_spheres_thesis_fig_2_8(offset_mm):
    # Thesis §2.3: 6 mm spheres at 3300 mm/s with centre offsets Δ (12 mm = grazing,
    # no contact). Eq 2.1 assumes an instantaneous impact; here the normal turns by
    # θ ≈ v_t t_c / 2r while the balls slide past each other, so the tangential part
    # changes by up to θ(1+e)u̇_n — that is the tolerance. Normal component -e·u̇_n with
    # e of a head-on impact at that normal speed (5e-3: dt resolution, plus θ).
    ball, _, bb, _, _ = steel()
    v, off = 3.3, offset_mm * 1e-3
    dt = dt_for(bb, v, 60)
    state, ev = two_ball_impact(bb, FRICTIONLESS, v, off, dt=dt)
    assert len(ev["t_start"]) == 1
    n = np.array([np.sqrt(4 * ball.radius**2 - off**2), off, 0.0]) / (2 * ball.radius)
    t = np.array([-n[1], n[0], 0.0])
    v_in = np.array([-v, 0.0, 0.0])
    v_out = state["v"][1] - state["v"][0]
    un = -v_in @ n
    assert ev["un"][0] == pytest.approx(un, rel=2e-3)  # onset normal speed is recorded
    theta = abs(v_in @ t) * ev["duration"][0] / (2 * ball.radius)
    assert v_out @ t == pytest.approx(v_in @ t, abs=theta * 2 * un + 1e-12)
    e = laws_np.simulate_impact(bb.model, bb.k, bb.c, bb.d, bb.m_eff, un)["e"][0]
    assert v_out @ n / un == pytest.approx(e, abs=5e-3 + theta)
    # momentum is exact (antisymmetric pair forces)
    np.testing.assert_allclose(state["v"].sum(axis=0), [-v, 0, 0], atol=1e-12)


def test_grazing_spheres_do_not_touch_thesis_fig_2_8_offset_12mm():
    # Δ = 12 mm = 2r: the balls pass side by side; nothing may happen.
    _, _, bb, _, _ = steel()
    state, ev = two_ball_impact(bb, FRICTIONLESS, 3.3, 12e-3 + 1e-9, dt=dt_for(bb, 3.3, 60))
    assert len(ev["t_start"]) == 0
    np.testing.assert_array_equal(state["v"], [[0, 0, 0], [-3.3, 0, 0]])


def test_constant_e_two_spheres_follow_eqs_2_3_and_2_4():
    # With hertz-mindlin (constant e) the discrete-impact equations hold outright:
    # v1f = v1i - (1+e) m2 (v1i - v2i)/(m1+m2) along n. Tolerance 0.01 on e.
    ball, _, bb, _, _ = pair_contact("steel-steel", law="hertz-mindlin")
    v = 3.3
    for off in (0.0, 6e-3, 10e-3):
        state, _ = two_ball_impact(bb, FRICTIONLESS, v, off, dt=dt_for(bb, v, 60))
        n = np.array([np.sqrt(4 * ball.radius**2 - off**2), off, 0.0]) / (2 * ball.radius)
        v1i, v2i = 0.0, -v * n[0]  # ball 0 at rest; ball 1's normal component
        e = bb.e
        v1f = v1i - (1 + e) * (v1i - v2i) / 2  # eq 2.3, equal masses
        v2f = v2i + (1 + e) * (v1i - v2i) / 2  # eq 2.4
        assert state["v"][0] @ n == pytest.approx(v1f, abs=0.01 * v)
        assert state["v"][1] @ n == pytest.approx(v2f, abs=0.01 * v)


@pytest.mark.parametrize("angle_deg", [10, 30, 50, 70])
def test_oblique_impact_with_plane_chung_ooi_case_6(angle_deg):
    # Rigid-body Coulomb theory (Maw et al.; Chung & Ooi case 6) for a sphere hitting a
    # plane with v_t/v_n = tan(angle): sticking ends in rolling, v_t' = 5/7 v_t, ω r = v_t';
    # gross sliding gives v_t' = v_t - μ(1+e)v_n, ω r = 5/2 μ(1+e) v_n. e from the run's
    # own normal rebound. Tolerance 2 % of v_t: the regularised μ(v) below v_d = 10 mm/s.
    ball, jar, bb, bw, _ = steel()
    mu = 0.3
    fr = Friction("test", mu, mu, 1e-3, 1e-2)
    v = 2.0
    a = math.radians(angle_deg)
    vn, vt = v * math.cos(a), v * math.sin(a)
    dt = dt_for(bw, vn, 80)
    spec = impact_spec(ball, jar, bb, bw, fr, [[0, 0, ball.radius + 1e-7]], [[vt, 0, -vn]], gravity=0.0,
                       dt=dt, steps=int(3e-4 / dt))
    state, ev = run_spec(spec)
    e = state["v"][0, 2] / vn
    if vt / vn < 3.5 * mu * (1 + e):
        vt_out, spin_r = 5 / 7 * vt, 5 / 7 * vt
    else:
        vt_out, spin_r = vt - mu * (1 + e) * vn, 2.5 * mu * (1 + e) * vn
    assert state["v"][0, 0] == pytest.approx(vt_out, abs=0.02 * vt)
    assert state["s"][0, 1] * ball.radius == pytest.approx(spin_r, abs=0.02 * vt)  # ω_y > 0 rolls towards +x
    assert ev["ut"][0] == pytest.approx(vt, rel=1e-9)  # onset slip recorded before any force
