"""Contact sub-models as Taichi functions: pure functions of local quantities, each
the twin of the NumPy sub-model of the same name in `taimill.model.contact` (the tests
hold the two equal), registered here by name in one table per kind. `normal_force`
and the kernels take the sub-models as compile-time (template) arguments: a run's
kernels contain only the sub-models it uses, with no test of a model in the loop."""

from taimill.physics.rolling_epsd2 import epsd2_torque
from taimill.physics.tangential_history import history_force
from taimill.physics.ti import ti


@ti.func
def smoothstep(s):
    """step(s) = s²(3-2s) on [0, 1], clamped outside (MSC.Adams STEP)."""
    s = ti.min(ti.max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


# ------------------------------------------------------------------ springs: uⁿ
@ti.func
def hertz_power(u, n: ti.template()):
    """u^(3/2) through a square root (5× cheaper than pow)."""
    return u * ti.sqrt(u)


@ti.func
def linear_power(u, n: ti.template()):
    return u


@ti.func
def power_law(u, n: ti.template()):
    return ti.pow(u, n)


SPRINGS = {"hertz": hertz_power, "linear": linear_power, "power": power_law}


# ------------------------------------------------------------------ damping shapes g(u)
@ti.func
def step_shape(u, un, k, n: ti.template(), d, m_eff):
    """adams-step: step(u/d), eqs 2.20 / 3.2."""
    return smoothstep(u / d)


@ti.func
def unit_shape(u, un, k, n: ti.template(), d, m_eff):
    """viscous: 1 (eqs 2.13, 2.18)."""
    return 1.0


@ti.func
def hunt_crossley_shape(u, un, k, n: ti.template(), d, m_eff):
    """hunt-crossley: k uⁿ, eq 2.19."""
    return k * un


@ti.func
def tsuji_shape(u, un, k, n: ti.template(), d, m_eff):
    """tsuji: √(m_e S_n), S_n = n k u^(n-1) (Tsuji 1992)."""
    return ti.sqrt(m_eff * n * k * un / u)


DAMPINGS = {"adams-step": step_shape, "viscous": unit_shape, "hunt-crossley": hunt_crossley_shape,
            "tsuji": tsuji_shape}


@ti.func
def normal_force(law: ti.template(), u, udot, k, c, d, m_eff):
    """(F, F_elastic), N, of the NormalModel `law`: F = max(0, k uⁿ + c g(u) u̇), never
    attractive. u > 0."""
    un = SPRINGS[law.spring.name](u, ti.static(law.n))
    f_el = k * un
    g = DAMPINGS[law.damping.name](u, un, k, ti.static(law.n), d, m_eff)
    return ti.max(0.0, f_el + c * g * udot), f_el


@ti.func
def elastic_energy(u, f_el, n: ti.template()):
    """k u^(n+1)/(n+1) = F_el u/(n+1), J."""
    return f_el * u / (n + 1.0)


# ------------------------------------------------------------------ tangential
@ti.func
def friction_coefficient(v, mu_s, mu_d, v_s, v_d):
    """Regularised Coulomb μ(v), thesis eq 3.7. (The reciprocals of the constants are
    off the contact's chain of dependent operations; a division by them is on it.)"""
    mu = mu_d
    if v < v_s:
        mu = mu_s * smoothstep(v * (1.0 / v_s))
    else:
        mu = mu_s - (mu_s - mu_d) * smoothstep((v - v_s) * (1.0 / (v_d - v_s)))
    return mu


@ti.func
def friction_force(slip, f_n, mu_s, mu_d, v_s, v_d, inv_mass_t, dt):
    """regularised-coulomb: friction force opposing `slip`; its impulse in one step never
    exceeds the one that stops the slip (inv_mass_t = Σ 1/m + a²/I of both bodies).
    Computed as -min(μ F_n / v, 1 / (dt inv_mass_t)) slip: one division by v, in
    parallel with μ(v)."""
    vs = slip.norm()
    f = ti.Vector([0.0, 0.0, 0.0])
    if vs > 0.0:
        per_v = ti.min(friction_coefficient(vs, mu_s, mu_d, v_s, v_d) * f_n * (1.0 / vs), 1.0 / (dt * inv_mass_t))
        f = -per_v * slip
    return f


@ti.func
def regularised_coulomb(slip, nrm, fn, u, mu_s, mu_d, v_s, v_d, kt, xi, inv_mass_t, dt):
    """regularised-coulomb in the tangential sub-models' signature: (force, history,
    energy stored in the history). It keeps none."""
    return friction_force(slip, fn, mu_s, mu_d, v_s, v_d, inv_mass_t, dt), xi, 0.0


# (slip, nrm, F_n, u, μ_s, μ_d, v_s, v_d, k_t, ξ, inv_mass_t, dt) -> (F_t, ξ', stored energy)
TANGENTIAL = {"regularised-coulomb": regularised_coulomb, "history": history_force}


# ------------------------------------------------------------------ rolling resistance
@ti.func
def rolling_torque(spin_rel, nrm, f_n, mu_r, r_eff, inv_inertia, dt):
    """constant-torque: rolling-resistance torque on the first body, μ_r R_eff F_n
    against ω_r = spin_rel without its twist about nrm; its angular impulse in one step
    never exceeds the one that stops ω_r (inv_inertia = Σ 1/I of both bodies). Returns
    (torque, energy it dissipates over the step at mid-step ω_r)."""
    w_r = spin_rel - spin_rel.dot(nrm) * nrm
    wn = w_r.norm()
    tq = ti.Vector([0.0, 0.0, 0.0])
    if wn > 0.0:
        mag = ti.min(mu_r * r_eff * f_n, wn / (dt * inv_inertia))
        tq = -mag / wn * w_r
    return tq, (-tq.dot(w_r) - 0.5 * tq.norm_sqr() * inv_inertia * dt) * dt


@ti.func
def constant_torque(spin_rel, nrm, fn, fel, u, kt, mu_r, r_eff, m_r, inv_inertia, dt):
    """constant-torque in the rolling sub-models' signature: (torque, work it removes
    over the step, history, energy stored in the history). It keeps none."""
    tq, d = rolling_torque(spin_rel, nrm, fn, mu_r, r_eff, inv_inertia, dt)
    return tq, d, m_r, 0.0


# (ω_rel, nrm, F_n, F_el, u, k_t, μ_r, R_eff, M_r, inv_inertia, dt) -> (torque, work, M_r', stored energy)
ROLLING = {"constant-torque": constant_torque, "epsd2": epsd2_torque}
