"""Fit of one contact parameter to measured drop tests (thesis §2.2.1, Fig 2.5 top
right), by weighted least squares on the restitution e(h₀) of ball-on-plate drops run
by the real engine.

Which law, which parameter: the fit applies to the pair's own normal law unless
another is named. For `adams-impact` (the thesis' MSC.Adams IMPACT law) it fits the
depth of full damping `d` (default, as the thesis did) or the damping `c_max`; the
other laws take their damping from a nominal restitution `e` at u_ref (contact_sets /
laws.calibrate_damping), so for them `e` is the parameter. A fitted d or e is
written to both the ball-ball and the ball-wall table (the thesis used the plate's d
and e for ball-ball impacts too, §2.2.1); a fitted c_max scales both tables' c_max by
the same factor (keeping eq 2.16's ratio between them).

Search: a 13-point scan (log-spaced for d and c_max) over the allowed range brackets
the minimum of χ² = Σ((e_sim - e_meas)/σ)²; Brent's method refines it. A minimum at
either end of the range that a step inside does not improve means no value in it
matches: FitError. Uncertainty:
σ_x² = s² / (JᵀJ) with J = ∂e/∂x by central differences and s² = χ²/(n-1) in units
of σ² (the residuals' own scatter); with one data row, s = 1 (the stated scatter).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from taimill.calibration.data import DropData
from taimill.calibration.optimise import brent
from taimill.errors import ConfigError
from taimill.model.materials import load_material
from taimill.model.contact_sets import NormalLaw, pair_contact
from taimill.model.preset import GRAVITY
from taimill.model import laws as laws_np
from taimill.model.contact.damping import damping_ratio, smoothstep
from taimill.model.contact.springs import di_maio_stiffness

GRID = 13
SPAN = 100.0  #: d and c_max are searched over [start/SPAN, start·SPAN]
E_RANGE = (0.02, 0.98)  #: e is searched over this range
# 1 s.d. of a per-height mean e when the data give none: the spread of Table 2.1's eight
# e values about their mean (0.0196; the thesis reduces them to one e = 0.90).
DEFAULT_SCATTER = 0.02
WITHIN = 2.0  #: a row is within the scatter when |e_sim - e_meas| <= WITHIN·σ (95 %)


class FitError(RuntimeError):
    """The data cannot be matched by any value of the parameter in its allowed range."""


@dataclass(frozen=True)
class Parameter:
    name: str  #: d, c_max or e
    key: str  #: key in the contact tables (materials.toml units)
    unit: str
    log: bool  #: searched in log space
    lo: float  #: allowed range, table units
    hi: float
    start: float  #: first guess (eqs 2.10-2.17), table units
    origin: str  #: where the first guess comes from
    current: float  #: the pair's value, table units
    base: NormalLaw  #: the pair's ball-wall law
    ratio: float = 1.0  #: c_max: ball-ball / ball-wall, kept
    e_of_c: tuple | None = None  #: e: (e, c) of impacts at u_ref, e rising (see `_damping_curve`)

    def t(self, x):
        return np.log(x) if self.log else np.asarray(x, float)

    def x(self, t):
        return np.exp(t) if self.log else np.asarray(t, float)

    @property
    def most_damped(self) -> float:
        return self.hi if self.name == "c_max" else self.lo

    def wall_law(self, x: float) -> NormalLaw:
        """The ball-wall law with the parameter at x (what a plate drop needs)."""
        if self.name == "d":
            return dataclasses.replace(self.base, d=x * 1e-3)
        if self.name == "c_max":
            return dataclasses.replace(self.base, c=x * 1e3)
        e, c = self.e_of_c  # = contact_sets' calibrated damping c(e), without a bisection per candidate
        return dataclasses.replace(self.base, c=float(np.exp(np.interp(x, e, np.log(c)))), e=x)

    def override(self, x: float) -> dict:
        """Contact-set override (contact_sets.pair_contact) setting the parameter to x."""
        scale = (self.ratio, 1.0) if self.name == "c_max" else (1.0, 1.0)
        return {table: {self.key: float(x) * s} for table, s in zip(("ball_ball", "ball_wall"), scale)}


def parameter(name: str | None, law, bb, ball, wall_material: str, data: DropData) -> Parameter:
    """The fitted parameter with its first guess at the data's median impact speed v:
    d = Hertz peak penetration (eqs 2.9/2.11, ½mv² = k u^(n+1)/(n+1)), the "expected
    compenetration" the thesis started from; c_max from eq 2.16 with k* of eq 2.17 and
    the mean measured e, divided by step(u_max/d), the fraction of c_max the IMPACT law
    reaches at that overlap (eq 2.16 assumes full damping); e = the mean measured e."""
    from_e = law.model.calibrated
    name = name or ("e" if from_e else "d")
    if name not in ("d", "c_max", "e") or (name == "e") != from_e:
        allowed = f"e (law {law.law} takes its damping from e)" if from_e else f"d or c_max ({law.law})"
        raise ConfigError("command line", "--param", name, f"must be {allowed}")
    v = math.sqrt(2.0 * GRAVITY * float(np.median(data.h0)))
    e_mean = float(np.clip(data.e.mean(), *E_RANGE))
    if name == "d":
        u_max = ((law.n + 1) * law.m_eff * v * v / (2 * law.k)) ** (1 / (law.n + 1))
        start = u_max * 1e3
        return Parameter("d", "d_mm", "mm", True, start / SPAN, start * SPAN, start, "Hertz peak overlap, eqs 2.9/2.11",
                         law.d * 1e3, law)
    if name == "c_max":
        wall = load_material(wall_material)
        e_eff = 1.0 / (1.0 / ball.material.youngs_modulus + 1.0 / wall.youngs_modulus)  # eq 2.17
        k_star = di_maio_stiffness(law.m_eff, v, e_eff, ball.radius)
        c_216 = 2.0 * damping_ratio(e_mean) * math.sqrt(law.m_eff * k_star)  # eq 2.16, N·s/m
        u_max = ((law.n + 1) * law.m_eff * v * v / (2 * law.k)) ** (1 / (law.n + 1))
        start = c_216 / float(smoothstep(u_max / law.d)) * 1e-3  # the law damps with c_max·step(u/d) ≤ c_max
        return Parameter("c_max", "c_max_Ns_per_mm", "N·s/mm", True, start / SPAN, start * SPAN, start,
                         "eqs 2.15-2.17 over step(u_max/d)", law.c * 1e-3, law, bb.c / law.c if law.c else 1.0)
    e, c = _damping_curve(law)
    lo, hi = max(E_RANGE[0], e[0]), min(E_RANGE[1], e[-1])  # hunt-crossley's clamp keeps e ≳ 0.2
    return Parameter("e", "e", "-", False, lo, hi, float(np.clip(e_mean, lo, hi)), "mean measured e", law.e, law,
                     e_of_c=(e, c))


def _damping_curve(law: NormalLaw, points=400):
    """(e, c): restitution of head-on impacts at u_ref over a log grid of damping c
    spanning E_RANGE with margin (RK4, F ≥ 0 clamp, as laws.calibrate_damping)."""
    c_lo, c_hi = (law.model.first_guess(e, law.k, law.m_eff, law.u_ref) for e in E_RANGE[::-1])
    c = np.geomspace(0.3 * c_lo, 3.0 * c_hi, points)
    e = laws_np.simulate_impact(law.model, law.k, c, law.d, law.m_eff, law.u_ref)["e"]
    return e[::-1], c[::-1]


def drop_model(pair: str, law_name: str | None, p: Parameter, heights):
    """values (table units) → e (K, n): plate drops from `heights` run by the engine,
    all candidates in one batch. Each height keeps one dt for every candidate (the
    pair's automatic dt there, or less if the most damped candidate needs it), so the
    objective is smooth in the parameter, and one run length: 3 × twice the contact time
    of the pair's law (damping shortens a clamped contact)."""
    from taimill.calibration.runs import Drop, resolved_dt, run_drops

    ball, jar, bb, bw, friction = pair_contact(pair, law=law_name)
    speeds = np.sqrt(2 * GRAVITY * np.asarray(heights))
    t_c, dts = zip(*(resolved_dt(bw, v) for v in speeds))
    dts = [min(dt, resolved_dt(p.wall_law(p.most_damped), v)[1]) for dt, v in zip(dts, speeds)]

    def model(values):
        drops = [Drop(ball, jar, bb, p.wall_law(x), friction, h, "plate", dt, 2 * t)
                 for x in values for h, t, dt in zip(heights, t_c, dts)]
        return np.reshape([r["e"] for r in run_drops(drops)], (len(values), len(heights)))

    return model


def fit_drops(pair: str, data: DropData, *, param: str | None = None, law: str | None = None,
              scatter: float = DEFAULT_SCATTER, model=None) -> dict:
    """Fit `param` so that simulated drops reproduce data.e; see the module docstring.
    `model` (values → e array (K, n)) replaces the engine (tests of the optimiser)."""
    ball, jar, bb, bw, _ = pair_contact(pair, law=law)
    p = parameter(param, bw, bb, ball, jar.wall_material, data)
    sigma = np.where(np.isnan(data.sigma), scatter, data.sigma)
    model = model or drop_model(pair, law, p, data.h0)

    def chi2(e_sim):
        return (((e_sim - data.e) / sigma) ** 2).sum(axis=-1)

    grid = np.linspace(p.t(p.lo), p.t(p.hi), GRID)
    seen = dict(zip(grid, model(p.x(grid))))  # t → simulated e per row
    c_grid = [chi2(e) for e in seen.values()]
    i = int(np.argmin(c_grid))

    def objective(t):
        seen[t] = model([p.x(t)])[0]
        return chi2(seen[t])

    calls = 0
    bracket, fb = grid[max(i - 1, 0) : i + 2], c_grid[i]
    if i in (0, GRID - 1):  # the minimum lies between the end and its neighbour, or beyond the end
        inner = grid[i] + (0.02 if i == 0 else -0.02) * (grid[1] - grid[0])
        fb, calls = objective(inner), 1
        if fb >= c_grid[i]:
            raise FitError(_no_match(p, data, seen[grid[i]], i, bw.law))
        bracket = (grid[0], inner, grid[1]) if i == 0 else (grid[-2], inner, grid[-1])
    t_best, _, more = brent(objective, *bracket, fb=fb, xtol=1e-3 if p.log else 1e-4)  # 0.1 % of d or c_max
    calls += more
    e_best = seen[t_best]
    x_best = float(p.x(t_best))
    h = 1e-2 if p.log else 2e-3
    x_pm = p.x(np.array([t_best - h, t_best + h]))
    e_pm = model(x_pm)
    jac = (e_pm[1] - e_pm[0]) / (x_pm[1] - x_pm[0])  # ∂e/∂x per row, 1/(table unit)
    n = len(data.e)
    chi2_min = float(chi2(e_best))
    s2 = chi2_min / (n - 1) if n > 1 else 1.0
    uncertainty = math.sqrt(s2 / float((jac / sigma) @ (jac / sigma)))
    res = e_best - data.e
    given = np.full_like(data.h0, np.nan) if data.measured_rebound is None else data.measured_rebound
    rows = [{
        "h0_mm": h0 * 1e3, "e_measured": em, "e_fit": ef, "residual_e": r, "sigma_e": s,
        "rebound_measured_mm": hm * 1e3, "rebound_measured_from": "rebound_mm" if np.isfinite(hg) else "e² h0",
        "rebound_fit_mm": ef**2 * h0 * 1e3, "residual_mm": (ef**2 * h0 - hm) * 1e3,
        "within_scatter": bool(abs(r) <= WITHIN * s),
    } for h0, em, ef, r, s, hm, hg in zip(data.h0, data.e, e_best, res, sigma, data.rebound_shown, given)]
    return {
        "pair": pair, "law": bw.law, "data": data.source, "param": p.name, "unit": p.unit,
        "value": x_best, "uncertainty": uncertainty, "start": p.start, "start_from": p.origin, "pair_value": p.current,
        "range": [p.lo, p.hi], "chi2": chi2_min, "chi2_per_dof": chi2_min / (n - 1) if n > 1 else None,
        "rms_e": float(np.sqrt(np.mean(res**2))), "within_scatter": all(r["within_scatter"] for r in rows),
        "evaluations": GRID + calls + 2, "rows": rows, "override": p.override(x_best),
    }


def _no_match(p: Parameter, data: DropData, e, i: int, law: str) -> str:
    """The message of a fit whose best value is the end i (0 or last) of the range; e:
    the simulated e per row there."""
    end = "lower" if i == 0 else "upper"
    hint = {
        ("d", "lower"): "d → 0 already damps with the full c_max: a lower e needs a larger c_max (--param c_max)",
        ("d", "upper"): "the contact is nearly elastic there: a higher e needs a smaller c_max (--param c_max)",
        ("c_max", "lower"): "damping is negligible there: the law cannot rebound higher; try a larger d",
        ("c_max", "upper"): "a lower e needs a smaller d (--param d)",
    }.get((p.name, end), f"law {law} cannot reach the measured restitution")
    return (f"{data.source}: no {p.name} in [{p.lo:.4g}, {p.hi:.4g}] {p.unit} matches ({law}); the best lies at the "
            f"{end} end, where the simulated e is {e.min():.3f}-{e.max():.3f} against the measured "
            f"{data.e.min():.3f}-{data.e.max():.3f}: {hint}")
