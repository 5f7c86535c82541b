"""What is derived from the contact models before a run: damping calibrated to a
restitution by simulated impacts, contact times and the automatic time step. The
models themselves (springs, dampings, tangential and rolling sub-models, the named
normal laws) are in `taimill.model.contact`.

`c` of adams-impact is the thesis' c_m; for the other laws it is calibrated so that a
simulated head-on impact at u_ref has exactly the asked restitution e *with* the
F ≥ 0 clamp (the closed forms assume an attractive end of contact and overshoot e).
kelvin-voigt and hertz-mindlin are scale-free, so their e then holds at every speed.
Every function here takes the normal law as a `NormalModel` object, never an id.
The automatic time step needs nothing per law: `auto_dt` simulates each law's own
impacts (`contact_dt`).
"""

from __future__ import annotations

import math

import numpy as np

from taimill.model.contact.model import NormalModel
from taimill.model.contact.registry import ROLLING

# Contact resolution of the automatic time step: steps per contact at the fastest
# expected impact (typical impacts, 10x slower, get ~1.6x more). Measured on the CY
# steel preset, 4 seeds x 6 s windows, at 80/40/30/20 steps: mean SE 4.43/4.49/4.47/
# 4.48 mJ (seed scatter ±0.09), drop-test e 0.5267-0.5273, energy-balance error
# 0.05-0.13 %. 24 keeps e within 0.001 and SE within scatter of the 80-step result
# (tests/test_runs.py, tests/test_impacts.py hold it).
STEPS_PER_CONTACT = 24


def rolling_dt(frictions, inertia, r_eff, f_n_max):
    """Time-step bound (s) of the frictions in use (`Friction`), each by its own rolling
    sub-model (inf where μ_r = 0: off)."""
    return min((ROLLING[f.rolling].dt_limit(inertia, f.mu_r, r_eff, f_n_max) for f in frictions if f.mu_r > 0),
               default=math.inf)


# ------------------------------------------------------------------ impacts
def _elastic_contact_time(k, n, m_eff, v):
    """Duration of an undamped impact at speed v: Hertz (n = 3/2) or harmonic (n = 1)."""
    v = np.asarray(v, dtype=float)
    if n == 1.0:  # k and m_eff may be arrays broadcasting with v (calibrate_dampings)
        return np.broadcast_to(np.pi * np.sqrt(np.divide(m_eff, k)), v.shape).astype(float)
    u_max = ((n + 1.0) * m_eff * v * v / (2.0 * k)) ** (1.0 / (n + 1.0))
    return 2.9432 * u_max / v  # Hertz: t_c = 2.9432 u_max / v (Johnson, Contact Mechanics §11)


def simulate_impact(law: NormalModel, k, c, d, m_eff, v0, steps=2000):
    """Head-on impact at approach speed v0 (m/s), integrated with RK4. c and v0 may be
    arrays (one impact per broadcast pair, each with its own step), and so may k, d and
    m_eff (calibrate_dampings: several contact types in one batch). Every impact is
    integrated on its own: its results do not depend on the others in the batch.
    Returns dict of arrays: e, duration (s), peak_force (N), peak_penetration (m)."""
    c, v0 = np.broadcast_arrays(np.atleast_1d(np.asarray(c, dtype=float)), np.asarray(v0, dtype=float))
    h = 1.5 * _elastic_contact_time(k, law.n, m_eff, v0) / steps
    # the products below as the RK4 formulas group them ((0.5 h) k, (h / 6) Σ), once
    h2, h6 = 0.5 * h, h / 6
    u = np.zeros_like(c)
    w = v0.copy()
    t_end = np.full_like(c, np.nan)
    v_end = np.full_like(c, np.nan)
    f_peak = np.zeros_like(c)
    u_peak = np.zeros_like(c)

    def force(u, w):
        return law.force(u, w, k, c, d, m_eff)[0]

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


_DAMPING: dict = {}  # calibrate_damping's results by their arguments


def calibrate_damping(law: NormalModel, e, k, m_eff, u_ref, d=1.0):
    """Damping c such that a head-on impact at u_ref (m/s) rebounds with restitution e,
    F ≥ 0 clamp included. Bisection on a vectorised batch of impacts."""
    return calibrate_dampings([(law, e, k, m_eff, u_ref, d)])[0]


def calibrate_dampings(contacts):
    """calibrate_damping of each (law, e, k, m_eff, u_ref, d) in `contacts`, those
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
            todo.setdefault(law, []).append(args)  # one batch per law
    for law, group in todo.items():
        group = list(dict.fromkeys(group))
        col = lambda j: np.array([[a[j] for a in group]]).T  # noqa: E731 — one row per contact
        e, k, m_eff, u_ref, d = col(1), col(2), col(3), col(4), col(5)
        lo = [0.0] * len(group)
        hi = [8.0 * law.first_guess(a[1], a[2], a[3], a[4]) for a in group]
        for _ in range(4):
            grid = np.array([np.linspace(a, b, 17) for a, b in zip(lo, hi)])
            got = simulate_impact(law, k, grid, d, m_eff, u_ref)["e"]
            for r, row in enumerate(got > e):  # e falls as c grows
                i = int(np.argmin(row)) if not row.all() else len(row) - 1
                lo[r], hi[r] = grid[r, max(i - 1, 0)], grid[r, i]
        for args, a, b in zip(group, lo, hi):
            _DAMPING[args] = 0.5 * (a + b)
    return [_DAMPING[args] for args in contacts]


_DEPTH: dict = {}  # calibrate_depth's results by their arguments


def calibrate_depth(law: NormalModel, e, k, c, m_eff, u_ref):
    """Full-damping penetration d (m) such that a head-on impact at u_ref (m/s) with
    damping c_max = c rebounds with restitution e: the thesis' fit of d to a drop test
    (§2.1, Fig 2.5) on a simulated impact. e rises with d (less of c_max is reached), so
    d is bisected on a log grid from 10⁻³ to 10³ Hertz peak overlaps at u_ref."""
    args = (law, e, k, c, m_eff, u_ref)
    if args in _DEPTH:
        return _DEPTH[args]
    if not 0.0 < e < 1.0:
        raise ValueError(f"restitution e = {e} must lie in (0, 1)")
    u_max = ((law.n + 1.0) * m_eff * u_ref**2 / (2.0 * k)) ** (1.0 / (law.n + 1.0))
    lo, hi = math.log(1e-3 * u_max), math.log(1e3 * u_max)
    for _ in range(5):
        grid = np.linspace(lo, hi, 17)
        got = np.nan_to_num(simulate_impact(law, k, np.full(17, float(c)), np.exp(grid), m_eff, u_ref)["e"], nan=0.0)
        below = got < e  # e rises with d
        i = int(np.argmin(below)) if not below.all() else len(grid) - 1
        lo, hi = grid[max(i - 1, 0)], grid[i]
    _DEPTH[args] = math.exp(0.5 * (lo + hi))
    return _DEPTH[args]


# Impact speeds at which auto_dt looks for the shortest contact, as fractions of v_max.
# A damped contact is not shortest at the highest speed: the Adams steel contact is
# shortest near 6 m/s and 9 % longer at 12 m/s (tests/test_laws.py). The duration has
# one flat minimum, so √2 steps find it to well under 1 %.
DT_SPEED_FRACTIONS = 2.0 ** (-0.5 * np.arange(9))
# Explicit damping: a damper c_eff = c·g(u) on m_eff is stable for c_eff·dt/m_eff < 2.
# Runs keep a factor 2 from that edge; the thesis' contacts stay far below it (0.5-0.7
# at their own contact-time step), so it binds only for heavily damped user laws.
RUN_DAMPING_LIMIT = 1.0


def contact_dt(law: NormalModel, k, c, d, m_eff, speeds, steps=STEPS_PER_CONTACT, damping_limit=RUN_DAMPING_LIMIT):
    """(shortest contact time over `speeds` (m/s), time step): that time over `steps`,
    and at most damping_limit·m_eff/c_eff with c_eff = c·g(u_peak), the damping at the
    deepest overlap reached."""
    r = simulate_impact(law, k, c, d, m_eff, speeds, steps=400)
    t_c = float(np.min(r["duration"]))
    c_eff = c * float(np.max(law.shape(r["peak_penetration"], k, d, m_eff)))
    dt = t_c / steps
    if c_eff > 0:
        dt = min(dt, damping_limit * m_eff / c_eff)
    return t_c, dt


def auto_dt(contacts, v_max):
    """Time step (s) of a run: STEPS_PER_CONTACT steps to the shortest contact at any
    impact speed up to v_max, within the damping limit, over the contact types in use.
    `contacts` are NormalLaws (a model with its coefficients k, c, d, m_eff)."""
    return min(contact_dt(p.model, p.k, p.c, p.d, p.m_eff, v_max * DT_SPEED_FRACTIONS)[1] for p in contacts)
