"""What a fit says about a condition (docs/outcome.md): the predicted curve and the
time to reach a target, each with a band.

A band is the union of three ranges, the first two of the parameters, the third of
the condition:

- along the profiles: the prediction at each best fit the fit file keeps along each
  parameter's profile (taimill.outcome.fit), parameter sets the data allow at the
  fit's level. This is what a loose parameter does to the prediction: the best fit's
  covariance sees only the neighbourhood of one point, and near-identical spectra or a
  threshold above a condition's events give it a narrow band where refitting along
  the profile runs over decades or to "never". A profile open at an end (the data do
  not bound the parameter) leaves the band open where the prediction still moves
  there: "never" or 0 s for a time, the model's range (α: 0 or 1) or ±∞ for a value.
  An energy threshold open below every fitted event counts every event of the
  predicted condition; open above them, the fitted conditions say nothing about the
  predicted one, whose band is then everything;
- linearised: the delta method on the fit's covariance of its log10 / linear
  parameters, ±q·sd with q the normal quantile of the fit's level (Student's t with
  the residual degrees of freedom when the scatter was estimated), the time to target
  taken in log t. Along a flat direction of JᵀJ (the fit file lists them; its
  pseudo-inverse, the covariance, is zero there) the data do not constrain the
  parameters: a prediction that moves along one has an unbounded band, never a
  zero-width one;
- the simulation's own scatter: the condition's rate (or power) above the threshold
  comes from a finite window, a count with a relative standard error
  (Condition.counting_error, the Poisson floor), or, for a sweep point with replicas
  (points differing only in their seed), their relative standard deviation where that
  is larger; ±q of it scales the condition's drive at the best fit, added in quadrature
  to the parameters' half-widths (in log t).

A fit file without profiles (an older taimill) gives the linearised band and the
simulation's scatter; the command says so.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from taimill.outcome.condition import Condition
from taimill.outcome.fit import Fit
from taimill.outcome.models import MODELS

STEP = 1e-5  #: finite-difference step in the fitted coordinates (log10 or linear)
ALONG = 1e-3  #: a gradient's share along a flat direction above which the prediction moves along it
STILL = 1e-6  #: relative change of a prediction between a profile's last two points below which it has settled
LINEARISED = ("bands are linearised at the best fit (the fit file holds no profiles: written by an older "
              "taimill); where the fit warned they may be far too narrow: fit again for bands along the profiles")


def model_of(fit: Fit):
    return MODELS[fit.model](fit.measure, fit.stress_only)


def _logs(fit: Fit) -> list[bool]:
    logs = {p.name: p.log for p in MODELS[fit.model].params}
    return [logs[n] for n in fit.covariance_names]


def _coords(fit: Fit) -> tuple[np.ndarray, list[bool]]:
    logs = _logs(fit)
    z = np.array([math.log10(fit.params[n]) if lg else fit.params[n] for n, lg in zip(fit.covariance_names, logs)],
                 dtype=float)
    return z, logs


def _params(fit: Fit, z) -> dict:
    """The model's parameters at the fitted coordinates z."""
    return dict(fit.fixed) | {n: (10.0 ** v if lg else float(v)) for n, v, lg in zip(fit.covariance_names, z, _logs(fit))}


def _band(fit: Fit, f) -> tuple[float, float]:
    """(value, sd) of the scalar f(params) by the delta method; sd = ∞ where f moves
    along a direction the data do not constrain (module doc)."""
    z, _ = _coords(fit)
    cov = np.asarray(fit.covariance, dtype=float).reshape(len(z), len(z))
    v0 = f(_params(fit, z))
    g = np.array([(f(_params(fit, z + STEP * np.eye(len(z))[i])) - v0) / STEP for i in range(len(z))])
    if not np.all(np.isfinite(g)) or _unconstrained(fit, cov, g):
        return v0, math.inf
    return v0, float(math.sqrt(max(g @ cov @ g, 0.0)))


def _unconstrained(fit: Fit, cov: np.ndarray, g: np.ndarray) -> bool:
    """Whether the gradient g moves along a flat direction of the fit (every direction
    when the covariance is zero: an older fit file of a flat JᵀJ). When every direction
    is flat the data fix nothing, and a prediction that happens not to move at the best
    fit (a curve saturated there) is not known either."""
    if not len(g):
        return False
    flat = np.asarray(fit.flat_directions, dtype=float).reshape(-1, len(g))
    if not flat.size and not np.any(cov):
        flat = np.eye(len(g))
    norm = float(np.linalg.norm(g))
    if len(flat) >= len(g):
        return True
    return bool(flat.size) and bool(norm) and float(np.abs(flat @ g).max()) > ALONG * norm


def quantile(fit: Fit) -> float:
    upper = 0.5 + fit.level / 2
    dof = fit.goodness.get("dof")
    if fit.sigma != "given" and dof:
        return float(stats.t.ppf(upper, dof))
    return float(stats.norm.ppf(upper))


def along_profiles(fit: Fit, f, limits: tuple[float, float]):
    """(lower, upper): the range of f(params) (a number or an array) along the fit's
    profiles, open to `limits` where a profile is open and f still moves (module
    doc); None without profiles."""
    if not fit.profiles:
        return None
    params = {p.name: p for p in MODELS[fit.model].params}
    lo = hi = None
    for name, path in fit.profiles.items():
        values = [np.asarray(f(_params(fit, z)), dtype=float) for z in path]
        for end in (e.split()[1] for e in fit.open_ends if e.split()[0] == name):
            last, before = (0, 1) if end == "lower" else (-1, -2)
            if params[name].threshold and end == "lower":  # below every fitted event: all of the condition's count
                values.append(np.asarray(f(_params(fit, path[last]) | {name: 0.0}), dtype=float))
            elif params[name].threshold:  # above every fitted event: the fitted conditions fix nothing here
                values += [np.full_like(values[0], limits[0]), np.full_like(values[0], limits[1])]
            elif len(path) > 1:
                a, b = values[last], values[before]
                moving = ~np.isclose(a, b, rtol=STILL, atol=0.0)
                values += [np.where(moving & (a > b), limits[1], a), np.where(moving & (a < b), limits[0], a)]
        stack = np.array(values)
        lo = stack.min(axis=0) if lo is None else np.minimum(lo, stack.min(axis=0))
        hi = stack.max(axis=0) if hi is None else np.maximum(hi, stack.max(axis=0))
    return lo, hi


class Scaled:
    """A condition whose rate and power are `factor` times another's: the same spectra
    counted over a window that happened to hold more or fewer events."""

    def __init__(self, cond: Condition, factor: float):
        self.cond, self.factor = cond, factor

    def rate(self, *args, **kw):
        return self.cond.rate(*args, **kw) * self.factor

    def power(self, *args, **kw):
        return self.cond.power(*args, **kw) * self.factor


def _drive(fit: Fit) -> tuple:
    """(threshold J, measure, stress_only, weighted) of the fit's drive at its best fit."""
    model = model_of(fit)
    name = next(p.name for p in model.params if p.threshold)
    return {**fit.params, **fit.fixed}[name], model.measure, model.stress_only, model.drive == "power"


def counting_error(fit: Fit, cond: Condition) -> float:
    """The relative standard error of the condition's drive (rate or power) above the
    fit's threshold, from the events its window holds."""
    energy, measure, stress_only, weighted = _drive(fit)
    return cond.counting_error(energy, measure, stress_only, weighted=weighted)


def scatter(fit: Fit, cond: Condition) -> tuple[float, str]:
    """(relative standard error, where from) of the condition's drive above the fit's
    threshold: the spread between its replicas where it has some and it is the larger,
    else the counting error."""
    energy, measure, stress_only, weighted = _drive(fit)
    counting = cond.counting_error(energy, measure, stress_only, weighted=weighted)
    spread = cond.replica_spread(energy, measure, stress_only, weighted=weighted)
    if spread > counting:
        return spread, f"{len(cond.replicas) + 1} replicas"
    return counting, "counting"


def _scattered(fit: Fit, cond: Condition, f) -> tuple:
    """(lower, upper) of f(params, condition) at the best fit over the condition's drive
    ±q times its counting error."""
    z, _ = _coords(fit)
    p, spread = _params(fit, z), quantile(fit) * scatter(fit, cond)[0]
    a = np.asarray(f(p, Scaled(cond, max(1.0 - spread, 0.0))), dtype=float)
    b = np.asarray(f(p, Scaled(cond, 1.0 + spread)), dtype=float)
    return np.minimum(a, b), np.maximum(a, b)


def _join(v, parts, scatter) -> tuple:
    """(lower, upper): the widest of the parameters' ranges `parts` around v, its
    half-widths added in quadrature to those of the scatter (all arrays)."""
    lo = np.min([p[0] for p in parts], axis=0)
    hi = np.max([p[1] for p in parts], axis=0)
    with np.errstate(invalid="ignore"):
        down = v - np.hypot(v - lo, v - scatter[0])
        up = v + np.hypot(hi - v, scatter[1] - v)
    finite = np.isfinite(v)
    return (np.where(finite, down, np.minimum(lo, scatter[0])), np.where(finite, up, np.maximum(hi, scatter[1])))


def curve(fit: Fit, cond: Condition, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value, lower, upper) of the model at the times t (s)."""
    model, q = model_of(fit), quantile(fit)
    t = np.asarray(t, dtype=float)
    out = np.array([_band(fit, lambda p, ti=ti: float(model.value(p, cond, ti))) for ti in t]).reshape(-1, 2)
    y, sd = out[:, 0], out[:, 1]
    parts = [(y - q * sd, y + q * sd)]
    limits = model.values or (-math.inf, math.inf)
    profiled = along_profiles(fit, lambda p: model.value(p, cond, t), limits)
    if profiled is not None:
        parts.append(profiled)
    lo, hi = _join(y, parts, _scattered(fit, cond, lambda p, c: model.value(p, c, t)))
    return y, np.clip(lo, *limits), np.clip(hi, *limits)


def time_to(fit: Fit, cond: Condition, target: float) -> tuple[float, float, float]:
    """(t, lower, upper) s to reach `target` (t NaN: never, at this condition; upper ∞:
    never is within the band)."""
    model = model_of(fit)

    def log_t(p, c=cond):
        t = model.time_to(p, c, target)
        return math.log10(t) if t > 0 else math.inf

    v, sd = _band(fit, log_t)
    q = quantile(fit)
    parts = [(v - q * sd, v + q * sd)] if math.isfinite(v) else [(v, v)]
    with np.errstate(divide="ignore"):
        profiled = along_profiles(fit, log_t, (-math.inf, math.inf))
    if profiled is not None:
        parts.append(profiled)
    lo, hi = _join(np.asarray(v), parts, _scattered(fit, cond, log_t))
    return (_exp10(v) if math.isfinite(v) else math.nan), _exp10(float(lo)), _exp10(float(hi))


def _exp10(x: float) -> float:
    """10^x, ∞ (or 0) beyond what a float holds: a band as wide as a parameter the data
    do not fix."""
    return 10.0 ** x if x < 308 else math.inf
