"""Fit an outcome model (taimill.outcome.models) to measured points by weighted least
squares (scipy.optimize.least_squares), with profile-likelihood confidence intervals,
goodness of fit and an identifiability check (docs/outcome.md).

Parameters marked `log` (κ, E*, E_c, n) are fitted as log10 of their value, so their
intervals are asymmetric and they stay positive. An energy threshold (E*) acts through
a binned spectrum: the rate above it is piecewise linear in log E, so the least-squares
surface has kinks at bin edges and may have several minima. The start is therefore
found by a scan over log10 E* (PER_DECADE points a decade over the energies the
conditions' spectra hold), fitting the other parameters at each.

Intervals are profile likelihood (Venzon & Moolgavkar, Appl. Stat. 37, 87 (1988);
Bates & Watts, Nonlinear Regression Analysis, 1988, ch. 6): the set of values of one
parameter for which the best fit with the others free stays within Δ of the best fit,
Δ = χ²₁(level) with the uncertainties given, or s² F(level; 1, n − p) with the
scatter estimated from the residuals (s² = S/(n − p)). Chosen over the Jacobian's
intervals because the model is far from linear in E* (bin kinks, a rate that can fall
to zero) and because a profile that never rises is the direct sign that a parameter
is not identifiable. The Jacobian's covariance is kept for the correlations, the
profile's step sizes and the linearised part of the prediction bands.

Each profile's path (the best fit of all parameters at each step of one parameter,
from its lower to its upper end) is kept too: a prediction's band is the range of the
prediction along these paths, the parameter sets the data allow at the fit's level,
where the best fit's covariance sees only the neighbourhood of one point
(taimill.outcome.predict).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from taimill.errors import ConfigError
from taimill.outcome.condition import Condition

PER_DECADE = 5  #: start scan of an energy threshold, points per decade
MAX_STEPS = 60  #: profile steps each way before the interval is called open
CORRELATION_WARN = 0.99  #: |correlation| above this: the data fix a combination, not each
DECADES_WARN = 3.0  #: a log parameter whose interval spans more decades is poorly determined
RATIO_TOLERANCE = 0.1  #: conditions whose drive keeps its ratio within this at every threshold
LOG_BOUND = 50.0  #: log10 bounds of the non-threshold log parameters
FLAT = 1e-15  #: an eigenvalue of JᵀJ at most this times the largest: a direction the data do not constrain


@dataclass
class Points:
    """Measured points: condition name, milling time (s), value, uncertainty (one
    standard deviation, or None: estimated from the scatter), and where each came from
    (for messages)."""

    condition: list[str]
    time: np.ndarray
    value: np.ndarray
    sigma: np.ndarray | None = None
    source: str = "points"
    lines: list[int] | None = None  #: each point's line in its file
    condition_column: int = 1  #: the condition's column in the file (1 = first)
    value_column: int = 3  #: the value's column in the file


@dataclass
class Fit:
    """A fitted model: parameters and intervals in their own units, what was measured
    and how well it fits. An interval's end that the profile never reached is where the
    search stopped; `open_ends` lists them ("e_star_J lower") and `warnings` says why."""

    model: str
    measure: str
    stress_only: bool
    params: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    fixed: dict[str, float]
    conditions: list[str]
    goodness: dict[str, float]
    sigma: str  #: "given" or "estimated from the residuals"
    level: float
    covariance_names: list[str] = field(default_factory=list)
    covariance: list[list[float]] = field(default_factory=list)  #: of the fitted log10 / linear values
    correlation: dict[str, float] = field(default_factory=dict)  #: "a:b" -> r
    warnings: list[str] = field(default_factory=list)
    open_ends: list[str] = field(default_factory=list)
    interval_method: str = "profile likelihood"
    #: name -> the fitted coordinates (covariance_names' order) of the best fits along its
    #: profile, lower end to upper end; empty in a fit file of an older taimill
    profiles: dict[str, list[list[float]]] = field(default_factory=dict)
    #: unit vectors of the fitted coordinates along which JᵀJ vanishes: the data do not
    #: constrain the parameters there, where the covariance (a pseudo-inverse) says zero
    flat_directions: list[list[float]] = field(default_factory=list)


class LeastSquares:
    """A weighted least-squares problem in fitting coordinates z: a subclass gives
    `bounds` ((lo, hi) per coordinate) and `residuals(z)`. DIFF_STEP: the relative step
    of the finite-difference Jacobian (None: scipy's default); EDGE: how far inside its
    bounds a start is put (a start on a bound can stall the trust region there)."""

    DIFF_STEP: float | None = None
    EDGE = 0.0
    bounds: list[tuple[float, float]]

    def residuals(self, z) -> np.ndarray:
        raise NotImplementedError

    def solve(self, z0, hold: dict[int, float] | None = None):
        """(z, S): the least-squares fit from z0 with the parameters in `hold` (index ->
        z) held; S the sum of squared weighted residuals."""
        hold = hold or {}
        z = np.array(z0, dtype=float)
        for i, v in hold.items():
            z[i] = v
        free = [i for i in range(len(z)) if i not in hold]
        if free:
            lo = np.array([self.bounds[i][0] for i in free])
            hi = np.array([self.bounds[i][1] for i in free])

            def res(x):
                z[free] = x
                return self.residuals(z)

            r = optimize.least_squares(res, np.clip(z[free], lo + self.EDGE, hi - self.EDGE), bounds=(lo, hi),
                                       x_scale=1.0, method="trf", diff_step=self.DIFF_STEP)
            z[free] = r.x
        return z, float(np.sum(self.residuals(z) ** 2))


class _Problem(LeastSquares):
    """The weighted residuals of a model over the points, as a function of the free
    parameters in fitting coordinates z (log10 for log parameters)."""

    def __init__(self, model, conds: dict[str, Condition], pts: Points, fixed: dict):
        self.model, self.conds, self.pts, self.fixed = model, conds, pts, dict(fixed)
        self.free = [p for p in model.params if p.name not in fixed]
        self.groups = {c: np.flatnonzero(np.asarray(pts.condition) == c) for c in dict.fromkeys(pts.condition)}
        self.w = 1.0 / pts.sigma if pts.sigma is not None else np.ones(len(pts.value))
        self.bounds = [self._bound(p) for p in self.free]

    def _bound(self, p) -> tuple[float, float]:
        if not p.threshold:
            return (-LOG_BOUND, LOG_BOUND) if p.log else (-np.inf, np.inf)
        ranges = [self.conds[c].energy_range(self.model.measure, self.model.stress_only) for c in self.groups]
        lo = min((r[0] for r in ranges if math.isfinite(r[0])), default=math.nan)
        hi = max((r[1] for r in ranges if math.isfinite(r[1])), default=math.nan)
        if not math.isfinite(lo):
            raise ConfigError(self.pts.source, "measure", self.model.measure,
                              "the conditions' spectra hold no events of this measure")
        return math.log10(lo), math.log10(hi)

    def params(self, z) -> dict:
        out = dict(self.fixed)
        for p, v in zip(self.free, z):
            out[p.name] = 10.0 ** v if p.log else float(v)
        return out

    def predict(self, params: dict) -> np.ndarray:
        out = np.empty(len(self.pts.value))
        for c, idx in self.groups.items():
            out[idx] = self.model.value(params, self.conds[c], self.pts.time[idx])
        return out

    def residuals(self, z) -> np.ndarray:
        r = (self.predict(self.params(z)) - self.pts.value) * self.w
        return np.where(np.isfinite(r), r, 1e10)


def fit(model, conds: dict[str, Condition], pts: Points, fixed: dict | None = None, level: float = 0.95) -> Fit:
    """Fit `model` to `pts` (module doc). `fixed`: parameters held at given values."""
    fixed = dict(fixed or {})
    unknown = [k for k in fixed if k not in {p.name for p in model.params}]
    if unknown:
        raise ConfigError(pts.source, "fixed", unknown[0], f"allowed: {', '.join(p.name for p in model.params)}")
    prob = _Problem(model, conds, pts, fixed)
    n, k = len(pts.value), len(prob.free)
    if n <= k:
        raise ConfigError(pts.source, "points", n, f"need more points than the {k} fitted parameters of {model.name}")
    z, s_min = _start(prob)
    cov, corr, flat = _covariance(prob, z, s_min, n - k)
    delta = _delta(pts, s_min, n - k, level)
    intervals, warnings, open_ends, profiles = {}, [], [], {}
    for j, p in enumerate(prob.free):
        lo, hi, z, s_min, open_end, path = _profile(prob, z, s_min, j, delta, cov)
        profiles[p.name] = [[float(v) for v in zi] for zi in path]
        intervals[p.name] = (float(10.0 ** lo if p.log else lo), float(10.0 ** hi if p.log else hi))
        warnings += _identifiable(prob, p, intervals[p.name], open_end, level)
        open_ends += [f"{p.name} {end}" for end, _ in open_end]
    warnings += [f"{a} and {b} are correlated {r:+.3f}: the data fix a combination of the two better than either"
                 for (a, b), r in corr.items() if abs(r) > CORRELATION_WARN]
    goodness = _goodness(prob, z, s_min, n, k)
    if pts.sigma is not None and goodness["p_value"] < 0.01:
        warnings.append(f"the model does not fit within the given uncertainties: χ²/dof = {goodness['reduced_chi2']:.3g}"
                        f" (p = {goodness['p_value']:.2g})")
    best = prob.params(z)
    return Fit(model.name, model.measure, model.stress_only, {q.name: float(best[q.name]) for q in prob.free}, intervals,
               fixed, list(prob.groups), goodness,
               "given" if pts.sigma is not None else "estimated from the residuals", level,
               [p.name for p in prob.free], cov.tolist(), {f"{a}:{b}": r for (a, b), r in corr.items()}, warnings, open_ends,
               profiles=profiles, flat_directions=flat)


def _start(prob: _Problem):
    """The best of the fits started along a scan of the energy threshold (or one fit)."""
    thr = [i for i, p in enumerate(prob.free) if p.threshold]
    conds = [prob.conds[c] for c in prob.pts.condition]
    threshold_name = next((p.name for p in prob.model.params if p.threshold), None)
    if not thr:
        g = prob.model.guess(prob.fixed.get(threshold_name, 0.0), prob.pts.time, prob.pts.value, conds)
        z0 = [math.log10(g[p.name]) if p.log else g[p.name] for p in prob.free]
        return prob.solve(z0)
    j = thr[0]
    lo, hi = prob.bounds[j]
    best = (None, math.inf)
    for x in np.linspace(lo, hi, max(2, int(round((hi - lo) * PER_DECADE)) + 1))[:-1]:
        g = prob.model.guess(10.0 ** x, prob.pts.time, prob.pts.value, conds) | {threshold_name: 10.0 ** x}
        z0 = [math.log10(max(g[p.name], 1e-300)) if p.log else g[p.name] for p in prob.free]
        z, s = prob.solve(z0, {j: x})
        if s < best[1]:
            best = (z, s)
    return prob.solve(best[0])


def _covariance(prob: _Problem, z, s_min: float, dof: int):
    """The Jacobian's covariance of z (s² (JᵀJ)⁻¹, s² = 1 with given uncertainties),
    the correlations of the parameter pairs, and the flat directions: unit vectors
    along which JᵀJ vanishes (at most FLAT of its largest eigenvalue; every direction
    when the residuals do not move at all). The pseudo-inverse gives those directions a
    variance of zero, the opposite of the truth: predict treats a prediction that moves
    along one as unbounded."""
    jac = optimize.approx_fprime(z, prob.residuals, 1e-6)
    s2 = 1.0 if prob.pts.sigma is not None else s_min / dof
    w, v = np.linalg.eigh(jac.T @ jac)
    flat = w <= FLAT * max(float(w.max()), 0.0)
    cov = (v * np.where(flat, 0.0, 1.0 / np.where(flat, 1.0, w))) @ v.T * s2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = {}
    for a in range(len(z)):
        for b in range(a + 1, len(z)):
            if sd[a] > 0 and sd[b] > 0:
                corr[(prob.free[a].name, prob.free[b].name)] = float(cov[a, b] / (sd[a] * sd[b]))
    return cov, corr, [[float(x) for x in v[:, i]] for i in np.flatnonzero(flat)]


def _delta(pts: Points, s_min: float, dof: int, level: float) -> float:
    if pts.sigma is not None:
        return float(stats.chi2.ppf(level, 1))
    return float(s_min / dof * stats.f.ppf(level, 1, dof))


def _profile(prob: _Problem, z, s_min: float, j: int, delta: float, cov):
    """(lower, upper) ends of parameter j's interval in z, the (possibly improved) best
    fit z and S, which ends are open ("lower", "upper"), and the path: the best fits
    (all of z) at the steps within the interval and at its ends, ordered by z[j]."""
    p = prob.free[j]
    sd = math.sqrt(max(cov[j, j], 0.0))
    h0 = min(max(sd / 3, 0.005), 0.2) if p.log else (sd / 3 if sd > 0 else 0.05 * abs(z[j]) + 1e-6)
    ends, open_end, path = [], [], [z.copy()]
    for sign in (-1, 1):
        h, zi, prev = h0, z.copy(), (z[j], 0.0)
        lo_b, hi_b = prob.bounds[j]
        for step in range(MAX_STEPS):
            x = min(max(prev[0] + sign * h, lo_b), hi_b)
            inside = zi.copy()
            zi, s = prob.solve(zi, {j: x})
            if s < s_min - 1e-9 * max(s_min, 1.0):  # a better fit than the start found: take it
                z, s_min = zi.copy(), s
            if s - s_min > delta:
                ends.append(_crossing(prob, zi, j, prev, (x, s - s_min), delta, s_min))
                path.append(prob.solve(inside, {j: ends[-1]})[0])
                break
            path.append(zi.copy())
            prev = (x, s - s_min)
            if x in (lo_b, hi_b):
                ends.append(x)
                open_end.append(("lower" if sign < 0 else "upper", "the end of the spectra" if p.threshold else "its bound"))
                break
            if step and step % 10 == 0:
                h *= 2
        else:
            ends.append(prev[0])
            open_end.append(("lower" if sign < 0 else "upper", "where the search stopped"))
    return ends[0], ends[1], z, s_min, open_end, sorted(path, key=lambda zi: zi[j])


def _crossing(prob, z, j, inside, outside, delta: float, s_min: float) -> float:
    """Where the profile of parameter j crosses Δ between a value inside the interval
    and one outside (Brent's method on the profile; linear in √ΔS if that fails)."""
    (a, da), (b, db) = inside, outside
    try:
        return optimize.brentq(lambda x: prob.solve(z, {j: x})[1] - s_min - delta, a, b, xtol=abs(b - a) / 50)
    except ValueError:
        ra, rb = math.sqrt(max(da, 0.0)), math.sqrt(db)
        return a + (b - a) * (math.sqrt(delta) - ra) / (rb - ra)


def _identifiable(prob: _Problem, p, interval, open_end, level) -> list[str]:
    out = []
    lo, hi = interval
    if open_end:
        reach = " and ".join(f"{'down to' if e == 'lower' else 'up to'} {(lo if e == 'lower' else hi):.3g} ({why})"
                             for e, why in open_end)
        out.append(f"{p.name} is not identifiable from these data: the fit stays within its {level:.0%} bound {reach}")
        if p.threshold:
            out += _same_shape(prob)
    elif p.log and math.log10(hi / lo) > DECADES_WARN:
        out.append(f"{p.name} is poorly determined: its {level:.0%} interval spans {math.log10(hi / lo):.1f} decades")
    return out


def _same_shape(prob: _Problem) -> list[str]:
    """Why a threshold cannot be found: one condition, or conditions whose spectra
    above every threshold keep the same ratio (they differ only in scale)."""
    names = list(prob.groups)
    if len(names) < 2:
        return [f"one condition ({names[0]}): a threshold is found only from conditions whose spectra differ in shape"]
    drive = prob.model.drive
    lo, hi = prob.bounds[[q.threshold for q in prob.free].index(True)]
    x = np.linspace(lo, hi, max(2, int((hi - lo) * PER_DECADE)))
    curves = np.array([getattr(prob.conds[c], drive)(10.0 ** x, prob.model.measure, prob.model.stress_only)
                       for c in names])
    ok = (curves > 0).all(axis=0)
    if not ok.any():
        return []
    ratio = np.log(curves[:, ok] / curves[0, ok])
    spread = float(np.max(ratio.max(axis=1) - ratio.min(axis=1)))
    if spread < math.log1p(RATIO_TOLERANCE):
        return [f"the conditions' {drive}s above E keep the same ratio (within {math.expm1(spread):.1%}) at every "
                "threshold where all have events: their spectra differ only in scale, which no threshold can tell apart"]
    return []


def _goodness(prob: _Problem, z, s_min: float, n: int, k: int) -> dict:
    y = prob.pts.value
    resid = prob.predict(prob.params(z)) - y
    dof = n - k
    out = {"n_points": n, "dof": dof, "rmse": float(np.sqrt(np.mean(resid ** 2))),
           "r2": float(1.0 - np.sum(resid ** 2) / np.sum((y - y.mean()) ** 2)) if np.ptp(y) > 0 else math.nan}
    if prob.pts.sigma is not None:
        out |= {"chi2": s_min, "reduced_chi2": s_min / dof, "p_value": float(stats.chi2.sf(s_min, dof))}
    else:
        out |= {"residual_sd": math.sqrt(s_min / dof)}
    return out
