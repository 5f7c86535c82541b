"""What a fit says about a condition (docs/outcome.md): the predicted curve and the
time to reach a target, each with a band.

Bands are Jacobian-based (the delta method on the fit's covariance of its log10 /
linear parameters): ±q·sd of the prediction, q the normal quantile of the fit's level
(Student's t with the residual degrees of freedom when the scatter was estimated),
the time to target's band taken in log t. Quicker than profiling every prediction and
exact for a model linear in its parameters near the best fit; for a parameter the fit
warned about (not identifiable, poorly determined) the band is as wide as the data
leave it, which is the point.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from taimill.outcome.condition import Condition
from taimill.outcome.fit import Fit
from taimill.outcome.models import MODELS

STEP = 1e-5  #: finite-difference step in the fitted coordinates (log10 or linear)


def model_of(fit: Fit):
    return MODELS[fit.model](fit.measure, fit.stress_only)


def _coords(fit: Fit) -> tuple[np.ndarray, list[bool]]:
    logs = {p.name: p.log for p in MODELS[fit.model].params}
    names = fit.covariance_names
    z = np.array([math.log10(fit.params[n]) if logs[n] else fit.params[n] for n in names], dtype=float)
    return z, [logs[n] for n in names]


def _band(fit: Fit, f) -> tuple[float, float]:
    """(value, sd) of f(params) by the delta method."""
    z, logs = _coords(fit)
    cov = np.asarray(fit.covariance, dtype=float).reshape(len(z), len(z))

    def at(zz):
        p = dict(fit.fixed) | {n: (10.0 ** v if lg else v) for n, v, lg in zip(fit.covariance_names, zz, logs)}
        return f(p)

    v0 = at(z)
    g = np.array([(at(z + STEP * np.eye(len(z))[i]) - v0) / STEP for i in range(len(z))])
    return v0, float(math.sqrt(max(g @ cov @ g, 0.0))) if np.all(np.isfinite(g)) else math.inf


def quantile(fit: Fit) -> float:
    upper = 0.5 + fit.level / 2
    dof = fit.goodness.get("dof")
    if fit.sigma != "given" and dof:
        return float(stats.t.ppf(upper, dof))
    return float(stats.norm.ppf(upper))


def curve(fit: Fit, cond: Condition, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value, lower, upper) of the model at the times t (s)."""
    model, q = model_of(fit), quantile(fit)
    out = np.array([_band(fit, lambda p, ti=ti: float(model.value(p, cond, ti))) for ti in np.asarray(t, dtype=float)])
    return out[:, 0], out[:, 0] - q * out[:, 1], out[:, 0] + q * out[:, 1]


def time_to(fit: Fit, cond: Condition, target: float) -> tuple[float, float, float]:
    """(t, lower, upper) s to reach `target` (NaN: never, at this condition)."""
    model = model_of(fit)

    def log_t(p):
        t = model.time_to(p, cond, target)
        return math.log10(t) if t > 0 else math.nan

    v, sd = _band(fit, log_t)
    if not math.isfinite(v):
        return math.nan, math.nan, math.nan
    q = quantile(fit)
    return _exp10(v), _exp10(v - q * sd), _exp10(v + q * sd)


def _exp10(x: float) -> float:
    """10^x, ∞ (or 0) beyond what a float holds: a band as wide as a parameter the data
    do not fix."""
    return 10.0 ** x if x < 308 else math.inf
