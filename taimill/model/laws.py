"""Contact laws in NumPy: the twins of `laws.py`, plus what is derived from them
before a run (Hertz stiffness, damping calibrated to a restitution, automatic dt).

Every normal law has the form (docs/model.md, normal contact laws)

    F = max(0, k uⁿ + c g(u) u̇),     u ≥ 0 overlap, u̇ its rate (> 0 approaching)

with a law-specific damping shape g:

| law            | id | n   | g(u)                     | source                       |
|----------------|----|-----|--------------------------|------------------------------|
| adams-impact   | 0  | 1.5 | step(u/d)                | MSC.Adams IMPACT, eqs 2.20/3.2 |
| kelvin-voigt   | 1  | 1   | 1                        | eq 2.13, k* of eq 2.17       |
| hertz-damper   | 2  | 1.5 | 1                        | eq 2.18 (Dubowsky)           |
| hunt-crossley  | 3  | 1.5 | k uⁿ                     | eq 2.19, Hunt & Crossley 1975 |
| hertz-mindlin  | 4  | 1.5 | √(m_e n k) u^((n-1)/2)   | Tsuji 1992 / EDEM: constant e |

`c` of adams-impact is the thesis' c_m; for the other laws it is calibrated so that a
simulated head-on impact at u_ref has exactly the asked restitution e *with* the
F ≥ 0 clamp (the closed forms assume an attractive end of contact and overshoot e).
kelvin-voigt and hertz-mindlin are scale-free, so their e then holds at every speed.

REGISTRY holds one `ContactLaw` per row of the table, in id order: the id is the
integer the kernels receive. Adding a law touches its REGISTRY entry here (name, n,
NumPy g, first guess of c, how c and k are derived) and its Taichi g in
`taimill.physics.laws.SHAPES`; tests hold this table, REGISTRY and SHAPES in step.
The automatic time step needs nothing per law: `auto_dt` simulates each law's own
impacts (`contact_dt`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

# Contact resolution of the automatic time step: steps per contact at the fastest
# expected impact (typical impacts, 10x slower, get ~1.6x more). Measured on the CY
# steel preset, 4 seeds x 6 s windows, at 80/40/30/20 steps: mean SE 4.43/4.49/4.47/
# 4.48 mJ (seed scatter ±0.09), drop-test e 0.5267-0.5273, energy-balance error
# 0.05-0.13 %. 24 keeps e within 0.001 and SE within scatter of the 80-step result
# (tests/test_runs.py, tests/test_impacts.py hold it).
STEPS_PER_CONTACT = 24


def hertz_stiffness(e1, nu1, e2, nu2, r1, r2=None):
    """Hertz k (N/m^1.5), eqs 2.10-2.12: 4/(3π)·1/(η₁+η₂)·√R_eff, η = (1-ν²)/(πE).
    r2 = None is a plane (sphere-plane uses √R_ball, eq 2.11)."""
    eta = (1 - nu1**2) / (math.pi * e1) + (1 - nu2**2) / (math.pi * e2)
    r_eff = r1 if r2 is None else r1 * r2 / (r1 + r2)
    return 4.0 / (3.0 * math.pi) / eta * math.sqrt(r_eff)


def di_maio_stiffness(m_eff, u_ref, e_eff, r_eff):
    """Linear stiffness k* (N/m) matching Hertz' peak force/overlap ratio, eq 2.17."""
    return (320.0 / 81.0 * m_eff * u_ref**2 * e_eff**4 * r_eff**2) ** 0.2


def smoothstep(s):
    """step(s) = s²(3-2s) on [0, 1], clamped outside (MSC.Adams STEP)."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


# ------------------------------------------------------------------ registry
def _step_shape(u, k, n, d, m_eff):
    """adams-impact: step(u/d), eqs 2.20 / 3.2."""
    return smoothstep(u / d)


def _unit_shape(u, k, n, d, m_eff):
    """kelvin-voigt, hertz-damper: 1 (eqs 2.13, 2.18)."""
    return np.ones_like(u)


def _hunt_crossley_shape(u, k, n, d, m_eff):
    """hunt-crossley: k uⁿ, eq 2.19."""
    return k * u**n


def _mindlin_shape(u, k, n, d, m_eff):
    """hertz-mindlin: √(m_e S_n) with S_n = n k u^(n-1) (Tsuji 1992)."""
    return np.sqrt(m_eff * n * k) * u ** (0.5 * (n - 1.0))


def damping_ratio(e):
    """ζ of a linear oscillator rebounding with restitution e, eq 2.15."""
    ln_e = math.log(e)
    return -ln_e / math.sqrt(ln_e**2 + math.pi**2)


def _eq_2_16_damping(e, k, n, m_eff, u_ref):
    """c = 2ζ√(m_e k), eq 2.16; a Hertz law uses its tangent stiffness n k u_max^(n-1)
    at the peak overlap u_max of an impact at u_ref (m/s)."""
    k_lin = k if n == 1.0 else (n * k * ((n + 1) * m_eff * u_ref**2 / (2 * k)) ** ((n - 1) / (n + 1)))
    return 2.0 * damping_ratio(e) * math.sqrt(m_eff * k_lin)


def _hunt_crossley_damping(e, k, n, m_eff, u_ref):
    """λ/k = 3(1-e)/(2 u_ref), Hunt & Crossley 1975 (s/m)."""
    return 1.5 * (1.0 - e) / u_ref


def _tsuji_damping(e, k, n, m_eff, u_ref):
    """2√(5/6)·β with β = ζ of eq 2.15 (Tsuji 1992 / EDEM), dimensionless."""
    return 2.0 * math.sqrt(5.0 / 6.0) * damping_ratio(e)


@dataclass(frozen=True)
class ContactLaw:
    """One normal law F = max(0, k uⁿ + c g(u) u̇): a row of the module's table."""

    name: str
    id: int  #: its index in REGISTRY, the integer the kernels receive
    n: float  #: exponent of the spring
    shape: Callable  #: g(u, k, n, d, m_eff), NumPy
    first_guess: Callable  #: closed-form c(e, k, n, m_eff, u_ref), ignoring the F ≥ 0 clamp
    calibrated: bool = True  #: c calibrated to e at u_ref; False: c = c_max of the contact set
    constant_e: bool = False  #: restitution independent of the impact speed
    parameters: tuple = ("k", "n", "c")  #: the NormalLaw fields its force depends on

    def stiffness(self, k_hertz, m_eff, u_ref, e_eff, r_eff):
        """k: Hertz' k (N/m^1.5), or for a linear spring k* of eq 2.17 (N/m)."""
        return di_maio_stiffness(m_eff, u_ref, e_eff, r_eff) if self.n == 1.0 else k_hertz

    def damping(self, c_max, e, k, m_eff, u_ref, d):
        """c: c_max (N·s/m) as given, or calibrated to the restitution e at u_ref."""
        return calibrate_damping(self.id, e, k, self.n, m_eff, u_ref, d) if self.calibrated else c_max


REGISTRY = (
    ContactLaw("adams-impact", 0, 1.5, _step_shape, _eq_2_16_damping, calibrated=False, parameters=("k", "n", "c", "d")),
    ContactLaw("kelvin-voigt", 1, 1.0, _unit_shape, _eq_2_16_damping, constant_e=True),
    ContactLaw("hertz-damper", 2, 1.5, _unit_shape, _eq_2_16_damping),
    ContactLaw("hunt-crossley", 3, 1.5, _hunt_crossley_shape, _hunt_crossley_damping),
    ContactLaw("hertz-mindlin", 4, 1.5, _mindlin_shape, _tsuji_damping, constant_e=True),
)
NAMES = tuple(law.name for law in REGISTRY)
CONSTANT_E_LAWS = tuple(law.name for law in REGISTRY if law.constant_e)


def law_by_name(name):
    """The ContactLaw called `name` (one of NAMES)."""
    return REGISTRY[NAMES.index(name)]


def damping_shape(law, u, k, n, d, m_eff):
    """g(u) of the law with id `law` (the table above)."""
    return REGISTRY[law].shape(u, k, n, d, m_eff)


def normal_force(law, u, udot, k, n, c, d, m_eff):
    """(F, F_elastic): the clamped normal force and its spring part, N. u ≥ 0 assumed."""
    u = np.maximum(u, 0.0)
    f_el = k * u**n
    return np.maximum(0.0, f_el + c * damping_shape(law, u, k, n, d, m_eff) * udot), f_el


def elastic_energy(u, f_el, n):
    """Energy stored in the spring, k u^(n+1)/(n+1) = F_el u/(n+1), J."""
    return f_el * np.maximum(u, 0.0) / (n + 1.0)


def friction_coefficient(v, mu_s, mu_d, v_s, v_d):
    """Regularised Coulomb μ(v), thesis eq 3.7: μ_s·step(v/v_s), then easing to μ_d at v_d."""
    v = np.asarray(v, dtype=float)
    rise = mu_s * smoothstep(v / v_s)
    fall = mu_s - (mu_s - mu_d) * smoothstep((v - v_s) / (v_d - v_s))
    return np.where(v < v_s, rise, fall)


def friction_force(slip, f_n, mu_s, mu_d, v_s, v_d, inv_mass_t, dt):
    """Friction force (N, 3-vector) opposing the slip velocity `slip` (m/s). Its impulse
    in one step is capped at the one that brings the slip to rest (never reverses it):
    |F| dt · inv_mass_t ≤ |slip|, with inv_mass_t = Σ 1/m + a²/I over both bodies."""
    slip = np.asarray(slip, dtype=float)
    vs = np.linalg.norm(slip)
    if vs == 0.0:
        return np.zeros(3)
    mag = min(friction_coefficient(vs, mu_s, mu_d, v_s, v_d) * f_n, vs / (dt * inv_mass_t))
    return -mag * slip / vs


# ------------------------------------------------------------------ rolling resistance
def rolling_velocity(spin_rel, normal):
    """ω_r (rad/s, 3-vector): the relative spin ω_i − ω_j (absolute spins; a wall turns
    with the jar) without its twist about the contact normal."""
    spin_rel, normal = np.asarray(spin_rel, dtype=float), np.asarray(normal, dtype=float)
    return spin_rel - spin_rel.dot(normal) * normal


def rolling_torque(spin_rel, normal, f_n, mu_r, r_eff, inv_inertia, dt):
    """Rolling-resistance torque (N m, 3-vector) on the first body: a constant torque
    μ_r R_eff F_n against the relative rolling ω_r (Ai et al. 2011 model A; LIGGGHTS
    `rolling_friction cdt`, EDEM's constant directional torque). Regularised like the
    friction force: its angular impulse in one step never exceeds the one that stops
    ω_r, |M| dt · inv_inertia ≤ |ω_r| with inv_inertia = 1/I_i + 1/I_j (a wall: 1/I_i),
    so near ω_r = 0 it settles the rolling instead of flipping sign every step."""
    w_r = rolling_velocity(spin_rel, normal)
    wn = np.linalg.norm(w_r)
    if wn == 0.0 or mu_r == 0.0:
        return np.zeros(3)
    mag = min(mu_r * r_eff * f_n, wn / (dt * inv_inertia))
    return -mag * w_r / wn


def rolling_dissipation(torque, spin_rel, normal, inv_inertia, dt):
    """Energy (J) the rolling torque dissipates over one step: −M·ω_r at mid-step, as
    its own angular impulse changes ω_r (as for friction)."""
    torque = np.asarray(torque, dtype=float)
    return (-torque.dot(rolling_velocity(spin_rel, normal)) - 0.5 * torque.dot(torque) * inv_inertia * dt) * dt


def _constant_torque_dt(inertia, mu_r, r_eff, f_n):
    """No bound: the capped torque acts like a rotational damper of at most c = I/dt
    (it stops ω_r in one step, never more), and an explicit damper is stable for
    c·dt/I < 2; acting together with the capped friction on the same spin the sum stays
    below 1 + (r²/I)/(1/m + r²/I) = 12/7 < 2 for a solid sphere."""
    return math.inf


@dataclass(frozen=True)
class RollingLaw:
    """A rolling-resistance model: its torque (NumPy twin of taimill.physics.laws) and
    the time step its explicit integration needs."""

    name: str
    id: int
    torque: Callable  #: (spin_rel, normal, f_n, mu_r, r_eff, inv_inertia, dt) -> N m
    dt_limit: Callable  #: (inertia kg m², mu_r, r_eff m, f_n N) -> s


# μ_r = 0 switches rolling resistance off (the thesis model); the torque is then never
# computed, so runs without it are bit-identical to runs before it existed.
ROLLING = (RollingLaw("constant-torque", 0, rolling_torque, _constant_torque_dt),)


def rolling_dt(frictions, inertia, r_eff, f_n_max):
    """Time-step bound (s) of the rolling model over the frictions in use (inf if off)."""
    return min((ROLLING[0].dt_limit(inertia, f.mu_r, r_eff, f_n_max) for f in frictions if f.mu_r > 0), default=math.inf)


# ------------------------------------------------------------------ impacts
def _elastic_contact_time(k, n, m_eff, v):
    """Duration of an undamped impact at speed v: Hertz (n = 3/2) or harmonic (n = 1)."""
    v = np.asarray(v, dtype=float)
    if n == 1.0:  # k and m_eff may be arrays broadcasting with v (calibrate_dampings)
        return np.broadcast_to(np.pi * np.sqrt(np.divide(m_eff, k)), v.shape).astype(float)
    u_max = ((n + 1.0) * m_eff * v * v / (2.0 * k)) ** (1.0 / (n + 1.0))
    return 2.9432 * u_max / v  # Hertz: t_c = 2.9432 u_max / v (Johnson, Contact Mechanics §11)


def simulate_impact(law, k, n, c, d, m_eff, v0, steps=2000):
    """Head-on impact at approach speed v0 (m/s), integrated with RK4. c and v0 may be
    arrays (one impact per broadcast pair, each with its own step), and so may k, d and
    m_eff (calibrate_dampings: several contact types in one batch). Every impact is
    integrated on its own: its results do not depend on the others in the batch.
    Returns dict of arrays: e, duration (s), peak_force (N), peak_penetration (m)."""
    c, v0 = np.broadcast_arrays(np.atleast_1d(np.asarray(c, dtype=float)), np.asarray(v0, dtype=float))
    h = 1.5 * _elastic_contact_time(k, n, m_eff, v0) / steps
    # the products below as the RK4 formulas group them ((0.5 h) k, (h / 6) Σ), once
    h2, h6 = 0.5 * h, h / 6
    u = np.zeros_like(c)
    w = v0.copy()
    t_end = np.full_like(c, np.nan)
    v_end = np.full_like(c, np.nan)
    f_peak = np.zeros_like(c)
    u_peak = np.zeros_like(c)

    def force(u, w):
        return normal_force(law, u, w, k, n, c, d, m_eff)[0]

    f = force(u, w)
    t = np.zeros_like(c)
    live = np.ones(c.shape, dtype=bool)  # not yet ended
    for _ in range(20 * steps):
        # RK4 stages (k1u = w); each stage's velocity is the next stage's position slope
        k1w = -f / m_eff
        k2u = w + h2 * k1w
        k2w = -force(u + h2 * w, k2u) / m_eff
        k3u = w + h2 * k2w
        k3w = -force(u + h2 * k2u, k3u) / m_eff
        k4u = w + h * k3w
        k4w = -force(u + h * k3u, k4u) / m_eff
        u1 = u + h6 * (w + 2 * k2u + 2 * k3u + k4u)
        w1 = w + h6 * (k1w + 2 * k2w + 2 * k3w + k4w)
        f = force(u1, w1)  # the peak's force is the next step's first stage
        f_peak = np.where(live, np.maximum(f_peak, f), f_peak)
        u_peak = np.where(live, np.maximum(u_peak, u1), u_peak)
        ended = live & (u1 < 0.0) & (t > 0.0)
        if ended.any():  # the crossing of the impacts ending in this step
            frac = np.where(ended, u / np.where(u - u1 == 0, 1, u - u1), 0.0)  # linear crossing
            t_end = np.where(ended, t + frac * h, t_end)
            v_end = np.where(ended, w + frac * (w1 - w), v_end)
            live = np.isnan(t_end)
            if not live.any():
                break
        u, w, t = u1, w1, t + h
    return {"e": -v_end / v0, "duration": t_end, "peak_force": f_peak, "peak_penetration": u_peak}


def closed_form_damping(law, e, k, n, m_eff, u_ref):
    """First guess of the damping c of the law with id `law` for restitution e."""
    return REGISTRY[law].first_guess(e, k, n, m_eff, u_ref)


_DAMPING: dict = {}  # calibrate_damping's results by their arguments


def calibrate_damping(law, e, k, n, m_eff, u_ref, d=1.0):
    """Damping c such that a head-on impact at u_ref (m/s) rebounds with restitution e,
    F ≥ 0 clamp included. Bisection on a vectorised batch of impacts."""
    return calibrate_dampings([(law, e, k, n, m_eff, u_ref, d)])[0]


def calibrate_dampings(contacts):
    """calibrate_damping of each (law, e, k, n, m_eff, u_ref, d) in `contacts`, those
    of one law bisected together, one batch of impacts per round (a preset's two contact
    types: half the rounds, each ≈ 1500 RK4 steps whose cost is NumPy's per-call
    overhead). Results are cached and identical to one contact at a time: every
    impact of a batch is integrated on its own."""
    todo = {}
    for args in contacts:
        law, e = args[0], args[1]
        if not 0.0 < e < 1.0:
            raise ValueError(f"restitution e = {e} must lie in (0, 1)")
        if args not in _DAMPING:
            todo.setdefault((law, args[3]), []).append(args)  # one batch per law and exponent
    for (law, n), group in todo.items():
        group = list(dict.fromkeys(group))
        col = lambda j: np.array([[a[j] for a in group]]).T  # noqa: E731 — one row per contact
        e, k, m_eff, u_ref, d = col(1), col(2), col(4), col(5), col(6)
        lo = [0.0] * len(group)
        hi = [8.0 * closed_form_damping(law, a[1], a[2], n, a[4], a[5]) for a in group]
        for _ in range(4):
            grid = np.array([np.linspace(a, b, 17) for a, b in zip(lo, hi)])
            got = simulate_impact(law, k, n, grid, d, m_eff, u_ref)["e"]
            for r, row in enumerate(got > e):  # e falls as c grows
                i = int(np.argmin(row)) if not row.all() else len(row) - 1
                lo[r], hi[r] = grid[r, max(i - 1, 0)], grid[r, i]
        for args, a, b in zip(group, lo, hi):
            _DAMPING[args] = 0.5 * (a + b)
    return [_DAMPING[args] for args in contacts]


# Impact speeds at which auto_dt looks for the shortest contact, as fractions of v_max.
# A damped contact is not shortest at the highest speed: the Adams steel contact is
# shortest near 6 m/s and 9 % longer at 12 m/s (tests/test_laws.py). The duration has
# one flat minimum, so √2 steps find it to well under 1 %.
DT_SPEED_FRACTIONS = 2.0 ** (-0.5 * np.arange(9))
# Explicit damping: a damper c_eff = c·g(u) on m_eff is stable for c_eff·dt/m_eff < 2.
# Runs keep a factor 2 from that edge; the thesis' contacts stay far below it (0.5-0.7
# at their own contact-time step), so it binds only for heavily damped user laws.
RUN_DAMPING_LIMIT = 1.0


def contact_dt(law, k, n, c, d, m_eff, speeds, steps=STEPS_PER_CONTACT, damping_limit=RUN_DAMPING_LIMIT):
    """(shortest contact time over `speeds` (m/s), time step): that time over `steps`,
    and at most damping_limit·m_eff/c_eff with c_eff = c·g(u_peak), the damping at the
    deepest overlap reached."""
    r = simulate_impact(law, k, n, c, d, m_eff, speeds, steps=400)
    t_c = float(np.min(r["duration"]))
    c_eff = c * float(np.max(damping_shape(law, r["peak_penetration"], k, n, d, m_eff)))
    dt = t_c / steps
    if c_eff > 0:
        dt = min(dt, damping_limit * m_eff / c_eff)
    return t_c, dt


def auto_dt(contacts, v_max):
    """Time step (s) of a run: STEPS_PER_CONTACT steps to the shortest contact at any
    impact speed up to v_max, within the damping limit, over the contact types in use.
    `contacts` are objects with law_id, k, n, c, d, m_eff."""
    return min(contact_dt(p.law_id, p.k, p.n, p.c, p.d, p.m_eff, v_max * DT_SPEED_FRACTIONS)[1] for p in contacts)
