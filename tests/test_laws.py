"""Contact laws: thesis constants, the damping unit trap, Taichi == NumPy twin."""

import numpy as np
import pytest

from taimill.model.contact_sets import pair_contact
from taimill.model.preset import load_preset
from taimill.physics import laws
from taimill.model import laws as laws_np
from taimill.model.contact import registry, tangential
from taimill.model.contact.registry import CONSTANT_E_LAWS
from taimill.physics.ti import ti

N_PER_MM15 = 1e3**1.5  # N/mm^1.5 → N/m^1.5


def test_hertz_stiffness_matches_thesis_table_3_2():
    # Tolerance 1 N/mm^1.5: the table prints integers.
    _, _, bb, bw, _ = pair_contact("steel-steel")
    assert bb.k / N_PER_MM15 == pytest.approx(252_146, abs=1)
    assert bw.k / N_PER_MM15 == pytest.approx(350_236, abs=1)


def test_zirconia_stiffness_matches_thesis_table_5_2():
    # Table 5.2 lists k_ss 176 730, k_sp 249 935 for 3 mm zirconia balls on a zirconia
    # jar; tolerance 0.1 %: the thesis rounds E and ν.
    _, _, bb, bw, _ = pair_contact("zirconia-zirconia")
    assert bb.k / N_PER_MM15 == pytest.approx(176_730, rel=1e-3)
    assert bw.k / N_PER_MM15 == pytest.approx(249_935, rel=1e-3)


def test_damping_is_read_as_newton_second_per_mm():
    # The unit trap: the tables' "10.1 kg/s" is 10.1 N·s/mm = 10 100 N·s/m.
    p = load_preset("presets/p4-cy-steel.toml")
    assert p.ball_ball.c == pytest.approx(10_100)
    assert p.ball_wall.c == pytest.approx(17_500)
    assert p.ball_ball.d == pytest.approx(0.211e-3)


def test_every_sub_model_has_a_taichi_twin_under_its_name():
    # The kernels look each sub-model up by its name in the physics tables.
    assert set(registry.SPRINGS) == set(laws.SPRINGS)
    assert set(registry.DAMPINGS) == set(laws.DAMPINGS)
    assert set(registry.TANGENTIAL) == set(laws.TANGENTIAL)
    assert set(registry.ROLLING) == set(laws.ROLLING)
    assert all(law.spring in registry.SPRINGS.values() and law.damping in registry.DAMPINGS.values()
               for law in registry.LAWS.values())


def test_law_table_in_the_docstring_matches_the_registry():
    rows = [[c.strip() for c in line.split("|")[1:4]] for line in registry.__doc__.splitlines()
            if line.startswith("| ") and not line.startswith("| law ")]
    assert [(name, spring, damping.split(":")[0]) for name, spring, damping in rows] == [
        (law.name, law.spring.name, law.damping.name) for law in registry.LAWS.values()]


def test_no_integer_model_id_outside_the_registries():
    # Models are objects chosen by name; the kernels are compiled for them. The only
    # integer that picks a model is an engine's own variant index among the models it
    # was compiled for (a batch mixing models).
    import ast
    from pathlib import Path

    root = Path(laws.__file__).resolve().parent.parent
    bad = []
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in ("law_id", "contact_law") \
                    or isinstance(node, ast.Name) and node.id in ("REGISTRY", "law_id"):
                bad.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not bad, bad


@ti.kernel
def _eval_normal(u: ti.types.ndarray(), ud: ti.types.ndarray(), k: ti.f64, c: ti.f64, d: ti.f64, m: ti.f64,
                 law: ti.template(), out: ti.types.ndarray()):
    for i in range(u.shape[0]):
        f, fel = laws.normal_force(law, u[i], ud[i], k, c, d, m)
        out[i, 0] = f
        out[i, 1] = fel
        out[i, 2] = laws.elastic_energy(u[i], fel, law.n)


@pytest.mark.usefixtures("taichi")
@pytest.mark.parametrize("law", registry.NAMES)
def test_taichi_normal_law_equals_numpy_twin(law):
    # Same formula, same double precision: agreement to 1e-12 relative.
    _, _, _, bw, _ = pair_contact("steel-steel", law=law)
    rng = np.random.default_rng(1)
    u = rng.uniform(1e-9, 4e-4, 500)  # up to twice d, through the damping ramp
    ud = rng.uniform(-3.0, 3.0, 500)
    out = np.zeros((500, 3))
    _eval_normal(u, ud, bw.k, bw.c, bw.d, bw.m_eff, bw.model, out)
    f, fel = bw.model.force(u, ud, bw.k, bw.c, bw.d, bw.m_eff)
    np.testing.assert_allclose(out[:, 0], f, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[:, 1], fel, rtol=1e-12)
    np.testing.assert_allclose(out[:, 2], fel * u / (bw.n + 1.0), rtol=1e-12)
    assert (out[:, 0] >= 0).all()  # never attractive
    assert (out[ud < -1.0, 0] == 0).any() or law == "kelvin-voigt"  # the clamp acts on fast separation


@ti.kernel
def _eval_friction(v: ti.types.ndarray(), out: ti.types.ndarray(), mu_s: ti.f64, mu_d: ti.f64, vs: ti.f64, vd: ti.f64):
    for i in range(v.shape[0]):
        out[i] = laws.friction_coefficient(v[i], mu_s, mu_d, vs, vd)


@pytest.mark.usefixtures("taichi")
def test_friction_coefficient_eq_3_7_and_twin():
    v = np.linspace(0.0, 0.03, 3001)
    out = np.zeros_like(v)
    _eval_friction(v, out, 1.0, 0.8, 1e-3, 1e-2)
    np.testing.assert_allclose(out, tangential.friction_coefficient(v, 1.0, 0.8, 1e-3, 1e-2), rtol=1e-12, atol=1e-15)
    # eq 3.7 landmarks: 0 at rest, μ_s at v_s, μ_d from v_d on, continuous.
    mu = tangential.friction_coefficient(np.array([0.0, 1e-3, 1e-2, 2e-2]), 1.0, 0.8, 1e-3, 1e-2)
    np.testing.assert_allclose(mu, [0.0, 1.0, 0.8, 0.8])
    assert np.abs(np.diff(out)).max() <= 1.5 * 1.0 / 1e-3 * (v[1] - v[0]) * 1.0001  # max slope 1.5 μ_s/v_s: continuous


def test_friction_impulse_never_reverses_the_slip():
    # A huge normal force on a slow slip: the capped impulse stops the slip, no more.
    slip = np.array([1e-3, 2e-3, 0.0])
    inv_m, dt = 3.5 / 7e-3, 1e-6
    f = tangential.friction_force(slip, 1e5, 1.0, 0.8, 1e-3, 1e-2, inv_m, dt)
    after = slip + f * inv_m * dt
    assert np.dot(after, slip) >= -1e-15
    np.testing.assert_allclose(after, 0.0, atol=1e-15)


@pytest.mark.parametrize("law", CONSTANT_E_LAWS)
@pytest.mark.parametrize("e", [0.3, 0.516, 0.9])
def test_calibrated_laws_deliver_their_restitution_at_every_speed(law, e):
    # Calibration makes the clamped law hit e at u_ref; scale-free laws then hold it at
    # any speed. Tolerance 2e-3: bisection resolution plus RK4 crossing interpolation.
    _, _, _, bw, _ = pair_contact("steel-steel", law=law)
    c = laws_np.calibrate_damping(bw.model, e, bw.k, bw.m_eff, bw.u_ref, bw.d)
    for v in (0.3, 3.309, 8.0):
        got = laws_np.simulate_impact(bw.model, bw.k, c, bw.d, bw.m_eff, v)["e"][0]
        assert got == pytest.approx(e, abs=2e-3)


def test_closed_form_damping_overshoots_restitution_with_the_clamp():
    # With F ≥ 0 the closed-form β(e) rebounds higher than asked (0.516 → ≈0.56).
    _, _, _, bw, _ = pair_contact("steel-steel", law="hertz-mindlin")
    c0 = bw.model.first_guess(0.516, bw.k, bw.m_eff, bw.u_ref)
    got = laws_np.simulate_impact(bw.model, bw.k, c0, bw.d, bw.m_eff, 3.309)["e"][0]
    assert 0.54 < got < 0.58


def test_auto_dt_resolves_the_shortest_contact_below_the_top_speed():
    # The damped Adams steel contact is shortest near 6 m/s, not at the top speed (12 m/s
    # here, 400 rpm-like): the time step must give STEPS_PER_CONTACT steps to the shortest
    # contact at any speed up to v_max. Durations from a fine speed scan (RK4, 400 steps
    # per contact: ≤ 0.1 % error); tolerance 0.5 %: the rule scans speeds in √2 steps and
    # the minimum is flat.
    _, _, bb, bw, _ = pair_contact("steel-steel")
    speeds = np.linspace(0.5, 12.0, 47)
    shortest = min(float(np.min(laws_np.simulate_impact(c.model, c.k, c.c, c.d, c.m_eff, speeds, steps=400)["duration"]))
                   for c in (bb, bw))
    top = min(float(laws_np.simulate_impact(c.model, c.k, c.c, c.d, c.m_eff, 12.0, steps=400)["duration"][0]) for c in (bb, bw))
    assert top > 1.05 * shortest  # the case the rule must handle
    dt = laws_np.auto_dt((bb, bw), 12.0)
    assert dt * laws_np.STEPS_PER_CONTACT <= shortest * 1.005
    assert dt * laws_np.STEPS_PER_CONTACT == pytest.approx(shortest, rel=0.005)


def test_auto_dt_keeps_explicit_damping_stable():
    # A damper c_eff on m_eff advanced explicitly is stable only for c_eff·dt/m_eff < 2;
    # auto_dt keeps it ≤ RUN_DAMPING_LIMIT = 1. The thesis' steel contact, 50× damped,
    # would get c_eff·dt/m_eff ≈ 3.2 from the contact-time rule alone.
    from types import SimpleNamespace

    _, _, bb, _, _ = pair_contact("steel-steel")
    heavy = SimpleNamespace(model=bb.model, k=bb.k, n=bb.n, c=50 * bb.c, d=bb.d, m_eff=bb.m_eff)
    v = 6.0
    speeds = v * laws_np.DT_SPEED_FRACTIONS
    r = laws_np.simulate_impact(heavy.model, heavy.k, heavy.c, heavy.d, heavy.m_eff, speeds, steps=400)
    c_eff = heavy.c * np.max(heavy.model.shape(r["peak_penetration"], heavy.k, heavy.d, heavy.m_eff))
    assert np.min(r["duration"]) / laws_np.STEPS_PER_CONTACT * c_eff / heavy.m_eff > 2  # unstable without the bound
    dt = laws_np.auto_dt((heavy,), v)
    assert dt * c_eff / heavy.m_eff == pytest.approx(laws_np.RUN_DAMPING_LIMIT, rel=1e-9)
    # the thesis' own contact is far from the bound: the contact time sets its step
    t_c, dt_bb = laws_np.contact_dt(bb.model, bb.k, bb.c, bb.d, bb.m_eff, speeds)
    assert dt_bb == t_c / laws_np.STEPS_PER_CONTACT


def test_the_time_step_follows_the_rolling_sub_model_in_use(monkeypatch):
    # Each contact kind's rolling sub-model bounds the step, not the default one: a
    # registered model whose explicit integration needs 1 ns steps sets the automatic
    # step wherever a friction uses it (the default constant torque has no bound).
    import dataclasses
    import math

    from taimill.model import rules

    stiff = dataclasses.replace(registry.ROLLING["epsd2"], name="stiff", dt_limit=lambda inertia, mu_r, r_eff, f_n: 1e-9)
    monkeypatch.setitem(registry.ROLLING, "stiff", stiff)
    p = load_preset("presets/p4-cy-steel.toml")
    default = dataclasses.replace(p.friction, mu_r=0.1)
    own = dataclasses.replace(default, rolling="stiff")
    assert laws_np.rolling_dt((default, default), p.balls.inertia, p.balls.radius, math.inf) == math.inf
    for frictions in ((default, own), (own, default)):
        assert laws_np.rolling_dt(frictions, p.balls.inertia, p.balls.radius, math.inf) == 1e-9
        assert rules.auto_dt(p.ball_ball, p.ball_wall, frictions, p.balls, 10.0) == 1e-9
    assert rules.auto_dt(p.ball_ball, p.ball_wall, (default, dataclasses.replace(own, mu_r=0.0)), p.balls, 10.0) > 1e-8
