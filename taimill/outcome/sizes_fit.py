"""The population balance of particle sizes (taimill.outcome.grinding) fitted to
measured size distributions (taimill.outcome.sizes), and what a fit predicts at other
conditions, with bands (docs/outcome.md, "Particle sizes").

Weighted least squares on the cumulative passing shares (scipy.optimize.least_squares),
each weighted by 1/σ: the file's sigma column, or 2 % of the share (SIGMA_SHARE, at
least SIGMA_FLOOR, so that a share near 0 does not take an infinite weight). Every
parameter is fitted as its log10, so it stays positive and its interval is asymmetric.

Which parameters the data identify (FREE by default, the others HELD):
- f_mat and xw_min: how fast each size breaks at each condition and below which size it
  no longer does (the grinding limit). Fitted.
- capture_g: while Vogel and Peukert's probability is far from 1 the selection rate is
  capture · f_mat · Σ ṅ (x E / capture − xW_min) = f_mat Σ ṅ (x E − xW_min capture):
  capture enters only through xW_min · capture (which xw_min takes up) until the
  strongest events break nearly every particle they catch. Held at 1 mg, the fit
  reports xw_min for that capture; `--free capture_g` where the coarse classes' rate
  saturates.
- phi and gamma: the share and the slope of the fine fragments, which shape the fine
  tail of every measured distribution. Fitted. beta (the coarse fragments' slope) acts
  within a class or two of the parent, which laser diffraction barely resolves on a
  √2 grid: held at 3.5 (`--free beta` to try).
- k_att: the attrition route's rate per friction power. Off by default (0); `--free
  k_att` fits it where the conditions differ in their friction power relative to their
  impacts (a size-independent rate is otherwise told from the impacts' only by the
  shape of the distributions).

Intervals are profile likelihood as in taimill.outcome.fit: the values of one parameter
for which the best fit with the others free stays within Δ = χ²₁(level) of the best
(σ given or taken as 2 %); the parameter vectors at each interval's ends are kept (the
profile's ends) for the prediction bands. A prediction's band is the wider of the delta
method on the fit's covariance (in log x, log t) and the range of the predictions at
the profile's ends: the first is the linearised band, the second follows the model
where it is not linear in its parameters.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from taimill.errors import ConfigError
from taimill.outcome.fit import LeastSquares
from taimill.outcome.grinding import (
    Austin,
    Grinding,
    SizeClasses,
    feed,
    passing,
    quantile_size,
    rates,
    selection,
    time_to_x90,
)
from taimill.outcome.grinding import evolve as propagate

SIGMA_SHARE = 0.02  #: σ of a passing share without a sigma column: 2 % of it …
SIGMA_FLOOR = 1e-3  #: … and at least 0.1 percentage point
#: name -> (table of the parameter file, lower, upper bound of the fit (own unit), unit)
PARAMS = {
    "f_mat": ("impact", 1e-8, 1e4, "kg/(J m)"),
    "xw_min": ("impact", 1e-9, 1e4, "J m/kg"),
    "capture_g": ("impact", 1e-9, 1e2, "g"),
    "k_att": ("attrition", 1e-12, 1e3, "g/J"),
    "phi": ("breakage", 1e-4, 1.0, "–"),
    "gamma": ("breakage", 1e-2, 20.0, "–"),
    "beta": ("breakage", 1e-2, 50.0, "–"),
}
FREE = ("f_mat", "xw_min", "phi", "gamma")  #: fitted unless --fix (module doc)
HELD = {"capture_g": 1e-3, "beta": 3.5, "k_att": 0.0}  #: held unless --free
START = {"f_mat": 0.1, "xw_min": 0.01, "capture_g": 1e-3, "k_att": 1e-3, "phi": 0.4, "gamma": 1.0, "beta": 3.5}
SCAN = {"f_mat": np.logspace(-4, 2, 7), "xw_min": np.logspace(-4, 1, 6)}  #: the start's grid (log10 spaced)
MAX_STEPS = 40  #: profile steps each way before the interval is called open
CORRELATION_WARN = 0.99
DECADES_WARN = 3.0
MARK = "# taimill sizes fit"  #: a sizes fit file's first line: what tells taimill's own from a user's file


@dataclass
class Data:
    """What a fit compares: per condition its feed (masses per class) and the measured
    points after time 0 (time s, size m, passing share, σ), on common size classes."""

    classes: SizeClasses
    conditions: list[str]
    feeds: dict[str, np.ndarray]
    points: dict[str, list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]]
    sigma: str  #: "given" or "2 % of each share"

    @property
    def n_points(self) -> int:
        return sum(len(x) for rows in self.points.values() for _, x, _, _ in rows)


@dataclass
class SizeFit:
    """A fitted population balance: parameters (own units), their intervals and what
    held, the classes and feed it was fitted on, and how well it fits (module doc)."""

    params: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    fixed: dict[str, float]
    measure: str
    stress_only: bool
    level: float
    conditions: list[str]
    goodness: dict[str, float]
    sigma: str
    classes: SizeClasses
    feed: list[float]
    covariance_names: list[str] = field(default_factory=list)
    covariance: list[list[float]] = field(default_factory=list)  #: of the log10 parameters
    correlation: dict[str, float] = field(default_factory=dict)
    profile_ends: dict[str, list[list[float]]] = field(default_factory=dict)  #: name -> [lower, upper] log10 vectors
    warnings: list[str] = field(default_factory=list)
    open_ends: list[str] = field(default_factory=list)
    interval_method: str = "profile likelihood"

    def all_params(self) -> dict[str, float]:
        return {**self.fixed, **self.params}


def grinding(params: dict, measure: str, stress_only: bool) -> Grinding:
    p = {**HELD, **params}
    return Grinding(Austin(min(p["phi"], 1.0), p["gamma"], p["beta"]), capture_g=p["capture_g"], f_mat=p["f_mat"],
                    xw_min=p["xw_min"], k_att=p["k_att"], measure=measure, stress_only=stress_only)


def at_sizes(classes: SizeClasses, q: np.ndarray, x) -> np.ndarray:
    """The passing share at sizes x (m) from the shares q at the class edges, log-linear
    between edges (as quantile_size), the finest edge's below it, 1 above the top."""
    logs = np.log(classes.edges)[::-1]
    return np.interp(np.log(x), logs, np.asarray(q)[::-1], right=1.0)


# ---------------------------------------------------------------- the data
def measured_feed(classes: SizeClasses, x, q) -> np.ndarray:
    """Masses per class of a measured distribution (sizes x m increasing, shares q),
    log-linear between its points; what lies above the top edge joins the coarsest
    class. Below the smallest measured size the share falls as the power law through
    the two finest points that differ (Gates–Gaudin–Schuhmann's fine tail), not into
    the sink: a feed measured from 50 µm up holds no dust of the finest class."""
    x, q = np.asarray(x, dtype=float), np.asarray(q, dtype=float)
    logs = np.log(classes.edges)
    below = np.interp(logs, np.log(x), q, left=float(q[0]), right=1.0)  # passing each edge
    finer = logs < math.log(x[0])
    rising = np.flatnonzero(q > q[0])
    if q[0] > 0 and rising.size and finer.any():
        slope = math.log(q[rising[0]] / q[0]) / math.log(x[rising[0]] / x[0])
        below[finer] = q[0] * np.exp(slope * (logs[finer] - math.log(x[0])))
    m = np.append(below[:-1] - below[1:], below[-1])
    m[0] += 1.0 - below[0]
    m = np.maximum(m, 0.0)
    return m / m.sum()


def prepare(dists, source: str, feed_x50_m: float | None = None, spread: float = 0.5) -> Data:
    """The fit's data from measured distributions (taimill.outcome.sizes): each
    condition's feed is its distribution at time 0 if it has one, else the log-normal
    of `feed_x50_m` and `spread`; classes √2 apart from the largest size (measured, or
    the log-normal feed's 99.9th percentile) down to the smallest measured."""
    conds = list(dict.fromkeys(d.condition for d in dists))
    xs = np.concatenate([d.sizes for d in dists])
    top = float(xs.max())
    if feed_x50_m is not None:
        top = max(top, feed_x50_m * math.exp(3.1 * spread))
    classes = SizeClasses.spanning(min(float(xs.min()), top / 2), top)
    feeds, points = {}, {}
    given = [d.sigma is not None for d in dists]
    if any(given) and not all(given):
        d = dists[given.index(not given[0])]
        raise ConfigError(f"{source}: line {d.line}", "sigma", "", "give sigma for every distribution or none")
    for c in conds:
        mine = [d for d in dists if d.condition == c]
        start = [d for d in mine if d.time == 0]
        if start:
            feeds[c] = measured_feed(classes, start[0].sizes, start[0].passing)
        elif feed_x50_m is not None:
            feeds[c] = feed(classes, feed_x50_m, spread)
        else:
            raise ConfigError(f"{source}: line {mine[0].line}", "condition", c,
                              "has no distribution at time 0 (the feed): measure it, or give the feed as --feed-x50 µm")
        later = sorted((d for d in mine if d.time > 0), key=lambda d: d.time)
        if not later:
            raise ConfigError(f"{source}: line {mine[0].line}", "condition", c,
                              "has no distribution after time 0: nothing to fit there")
        points[c] = [(d.time, d.sizes, d.passing, d.sigma if d.sigma is not None
                      else np.maximum(SIGMA_SHARE * d.passing, SIGMA_FLOOR)) for d in later]
    return Data(classes, conds, feeds, points, "given" if given[0] else "2 % of each share")


# ---------------------------------------------------------------- the fit
class Problem(LeastSquares):
    """Weighted residuals of the model over the data as a function of the free
    parameters' log10 values z."""

    DIFF_STEP = 1e-6  # the passing shares move by less than scipy's default step resolves
    EDGE = 1e-9

    def __init__(self, data: Data, conds: dict, free: list[str], held: dict, measure: str, stress_only: bool):
        self.data, self.conds, self.free, self.held = data, conds, list(free), dict(held)
        self.measure, self.stress_only = measure, stress_only
        self.bounds = [(math.log10(PARAMS[n][1]), math.log10(PARAMS[n][2])) for n in self.free]
        self.value = np.concatenate([q for c in data.conditions for _, _, q, _ in data.points[c]])
        self.sigma = np.concatenate([s for c in data.conditions for _, _, _, s in data.points[c]])

    def params(self, z) -> dict:
        return {**self.held, **{n: 10.0 ** float(v) for n, v in zip(self.free, z)}}

    def predict(self, params: dict) -> np.ndarray:
        g = grinding(params, self.measure, self.stress_only)
        out = []
        for c in self.data.conditions:
            rows = self.data.points[c]
            m = propagate(rates(g, self.data.classes, self.conds[c]), self.data.feeds[c], [t for t, *_ in rows])
            q = passing(self.data.classes, m)
            out += [at_sizes(self.data.classes, qi, x) for qi, (_, x, _, _) in zip(q, rows)]
        return np.concatenate(out)

    def residuals(self, z) -> np.ndarray:
        try:
            r = (self.predict(self.params(z)) - self.value) / self.sigma
        except ValueError:  # parameters Austin or Grinding refuse
            return np.full(len(self.value), 1e6)
        return np.where(np.isfinite(r), r, 1e6)

    def cost(self, z) -> float:
        return float(np.sum(self.residuals(z) ** 2))



def parameter_names(fix: dict, free: list[str]) -> tuple[list[str], dict]:
    """(fitted names, held values) from --fix NAME=VALUE and --free NAME."""
    held = {k: v for k, v in HELD.items() if k not in free}
    held.update(fix)
    fitted = [n for n in PARAMS if n not in held]
    return fitted, held


def fit_sizes(data: Data, conds: dict, fix: dict | None = None, free: list[str] | None = None,
              measure: str = "dissipated_normal", stress_only: bool = True, level: float = 0.95,
              source: str = "SIZES") -> SizeFit:
    """Fit the population balance to `data` (module doc)."""
    fitted, held = parameter_names(dict(fix or {}), list(free or []))
    prob = Problem(data, conds, fitted, held, measure, stress_only)
    n, k = len(prob.value), len(fitted)
    if not fitted:
        raise ConfigError("command line", "--fix", ", ".join(held), "leaves nothing to fit")
    if n <= k:
        raise ConfigError(source, "points", n, f"need more measured shares than the {k} fitted parameters")
    z, s_min = _start(prob)
    cov, corr = _covariance(prob, z)
    delta = float(stats.chi2.ppf(level, 1))
    intervals, ends, warnings, open_ends = {}, {}, [], []
    for j, name in enumerate(fitted):
        (lo, z_lo), (hi, z_hi), z, s_min, open_end = _profile(prob, z, s_min, j, delta, cov)
        intervals[name] = (10.0 ** lo, 10.0 ** hi)
        ends[name] = [z_lo.tolist(), z_hi.tolist()]
        open_ends += [f"{name} {e}" for e in open_end]
        warnings += _identifiable(name, intervals[name], open_end, level)
    cov, corr = _covariance(prob, z)  # at the best fit the profiles may have improved
    warnings += [f"{a} and {b} are correlated {r:+.3f}: the data fix a combination of the two better than either"
                 for (a, b), r in corr.items() if abs(r) > CORRELATION_WARN]
    if len(data.conditions) < 2:
        warnings.append(f"one condition ({data.conditions[0]}): how the rate follows the spectrum (f_mat against xw_min) "
                        "rests on one spectrum; fit two conditions or more before predicting others")
    best = prob.params(z)
    if best["gamma"] >= best["beta"]:
        warnings.append(f"gamma {best['gamma']:.3g} ≥ beta {best['beta']:.3g}: the fine and coarse fragments' terms "
                        "swapped roles (Austin's phi then describes the coarse fragments)")
    resid = prob.predict(best) - prob.value
    dof = n - k
    goodness = {"n_points": n, "dof": dof, "rmse": float(np.sqrt(np.mean(resid ** 2))), "chi2": s_min,
                "reduced_chi2": s_min / dof, "p_value": float(stats.chi2.sf(s_min, dof))}
    if goodness["p_value"] < 0.01:
        warnings.append(f"the model does not fit within the uncertainties ({data.sigma}): χ²/dof = "
                        f"{goodness['reduced_chi2']:.3g} (p = {goodness['p_value']:.2g})")
    first = data.conditions[0]
    return SizeFit({n_: float(best[n_]) for n_ in fitted}, intervals, held, measure, stress_only, level,
                   list(data.conditions), goodness, data.sigma, data.classes, data.feeds[first].tolist(), list(fitted),
                   cov.tolist(), {f"{a}:{b}": r for (a, b), r in corr.items()}, ends, warnings, open_ends)


def _start(prob: Problem):
    """The best fit from the best point of a coarse grid over f_mat and xw_min (each
    fitted; the others at START)."""
    z0 = np.array([math.log10(START[n]) for n in prob.free])
    grid = [(i, SCAN[n]) for i, n in enumerate(prob.free) if n in SCAN]
    best = (z0, prob.cost(z0))
    if grid:
        for values in np.array(np.meshgrid(*[v for _, v in grid])).reshape(len(grid), -1).T:
            z = z0.copy()
            for (i, _), v in zip(grid, values):
                z[i] = math.log10(v)
            s = prob.cost(z)
            if s < best[1]:
                best = (z, s)
    z, s = prob.solve(best[0])
    return z, s


def _covariance(prob: Problem, z):
    """(JᵀJ)⁻¹ of the log10 parameters (σ given), and each pair's correlation. The
    covariance (for bands) is the pseudo-inverse: a direction the data do not fix at
    all is left out, not given an unbounded variance that rounding in a prediction's
    gradient would turn into an unbounded band. The correlations come from a slightly
    regularised inverse instead, which keeps such a direction: two parameters that
    only enter as a product (xw_min · capture) then correlate −1, as they trade off;
    the pseudo-inverse would report the surviving direction's +1."""
    jac = optimize.approx_fprime(z, prob.residuals, 1e-6)
    info = jac.T @ jac
    cov = np.linalg.pinv(info)
    cov = (cov + cov.T) / 2
    ridge = np.linalg.inv(info + 1e-10 * max(float(np.trace(info)), 1e-300) * np.eye(len(z)))
    sd = np.sqrt(np.maximum(np.diag(ridge), 0.0))
    corr = {}
    for a in range(len(z)):
        for b in range(a + 1, len(z)):
            if sd[a] > 0 and sd[b] > 0:
                corr[(prob.free[a], prob.free[b])] = float(np.clip(ridge[a, b] / (sd[a] * sd[b]), -1.0, 1.0))
    return cov, corr


def _profile(prob: Problem, z, s_min: float, j: int, delta: float, cov):
    """((lower, its z), (upper, its z)) of parameter j's interval in log10, the best fit
    (the profile may find a better one) and which ends are open."""
    sd = math.sqrt(max(cov[j, j], 0.0))
    h0 = min(max(sd / 2, 0.01), 0.2)
    lo_b, hi_b = prob.bounds[j]
    ends, open_end = [], []
    for sign in (-1, 1):
        h, zi, prev = h0, z.copy(), (z[j], z.copy())
        for step in range(MAX_STEPS):
            x = min(max(prev[0] + sign * h, lo_b), hi_b)
            zi, s = prob.solve(zi, {j: x})
            if s < s_min - 1e-9 * max(s_min, 1.0):
                z, s_min = zi.copy(), s
            if s - s_min > delta:
                ends.append(_crossing(prob, prev, (x, zi), j, delta, s_min))
                break
            prev = (x, zi.copy())
            if x in (lo_b, hi_b):
                ends.append(prev)
                open_end.append("lower" if sign < 0 else "upper")
                break
            if step and step % 8 == 0:
                h *= 2
        else:
            ends.append(prev)
            open_end.append("lower" if sign < 0 else "upper")
    return ends[0], ends[1], z, s_min, open_end


def _crossing(prob: Problem, inside, outside, j: int, delta: float, s_min: float):
    """(x, z) where parameter j's profile crosses Δ between a value inside and one outside."""
    (a, za), (b, _) = inside, outside
    found = {}

    def f(x):
        zz, s = prob.solve(za, {j: x})
        found[x] = zz
        return s - s_min - delta

    try:
        x = optimize.brentq(f, a, b, xtol=abs(b - a) / 30)
    except ValueError:
        return (b, prob.solve(za, {j: b})[0])
    return (x, found.get(x, prob.solve(za, {j: x})[0]))


def _identifiable(name: str, interval, open_end, level: float) -> list[str]:
    lo, hi = interval
    if open_end:
        reach = " and ".join(f"{'down to' if e == 'lower' else 'up to'} {(lo if e == 'lower' else hi):.3g}"
                             for e in open_end)
        return [f"{name} is not identifiable from these data: the fit stays within its {level:.0%} bound {reach} "
                "(its profile is flat there)"]
    if math.log10(hi / lo) > DECADES_WARN:
        return [f"{name} is poorly determined: its {level:.0%} interval spans {math.log10(hi / lo):.1f} decades"]
    return []


# ---------------------------------------------------------------- predictions with bands
def _q(fit: SizeFit) -> float:
    return float(stats.norm.ppf(0.5 + fit.level / 2))


def _variants(fit: SizeFit) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """(z of the best fit, the delta method's steps, the profile's ends) in log10."""
    z = np.array([math.log10(fit.params[n]) for n in fit.covariance_names])
    steps = [z + STEP * np.eye(len(z))[i] for i in range(len(z))]
    ends = [np.array(v, dtype=float) for n in fit.covariance_names for v in fit.profile_ends.get(n, [])]
    return z, steps, ends


STEP = 1e-4  #: finite-difference step in log10 of a parameter


def banded(fit: SizeFit, f) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value, lower, upper) of f(params) > 0 (an array: sizes or times), its band the
    wider of the delta method in log f and the range of f at the profile's ends
    (module doc). A value f cannot give (nan) has a nan band; one parameters do not
    move (the feed at time 0) a band of zero width."""
    z, steps, ends = _variants(fit)

    def at(zz):
        p = fit.fixed | {n: 10.0 ** v for n, v in zip(fit.covariance_names, zz)}
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.log(np.asarray(f(p), dtype=float))

    v0 = at(z)
    grad = np.array([(at(s) - v0) / STEP for s in steps]) if steps else np.zeros((0, *v0.shape))
    cov = np.asarray(fit.covariance, dtype=float).reshape(len(z), len(z))
    sd = np.sqrt(np.maximum(np.einsum("i...,ij,j...->...", grad, cov, grad), 0.0)) if len(z) else np.zeros_like(v0)
    lo, hi = v0 - _q(fit) * sd, v0 + _q(fit) * sd
    for e in ends:
        ve = at(e)
        ok = np.isfinite(ve)
        lo = np.where(ok, np.fmin(lo, ve), lo)
        hi = np.where(ok, np.fmax(hi, ve), hi)
        hi = np.where(np.isinf(ve) & (ve > 0), np.inf, hi)  # an end that never reaches the target
    with np.errstate(over="ignore"):
        return np.exp(v0), np.exp(lo), np.exp(hi)


def quantiles(fit: SizeFit, cond, m0, times, shares=(0.1, 0.5, 0.9)) -> dict[float, tuple]:
    """share -> (x, lower, upper) m at each time (s): x10, x50, x90 with bands."""
    classes = fit.classes

    def xs(p):
        m = propagate(rates(grinding(p, fit.measure, fit.stress_only), classes, cond), m0, times)
        q = passing(classes, m)
        return np.array([quantile_size(classes, q, f) for f in shares])

    v, lo, hi = banded(fit, xs)
    return {f: (v[i], lo[i], hi[i]) for i, f in enumerate(shares)}


def distribution(fit: SizeFit, cond, m0, times) -> np.ndarray:
    """The passing share at each class edge (columns) at each time (rows)."""
    g = grinding(fit.all_params(), fit.measure, fit.stress_only)
    return passing(fit.classes, propagate(rates(g, fit.classes, cond), m0, times))


def time_to_target(fit: SizeFit, cond, m0, target_m: float) -> tuple[float, float, float]:
    """(t, lower, upper) s until x90 ≤ target_m (inf: not within HOURS_MAX h)."""
    def t(p):
        return np.array([time_to_x90(grinding(p, fit.measure, fit.stress_only), fit.classes, cond, m0, target_m)])

    v, lo, hi = (float(a[0]) for a in banded(fit, t))
    if v == 0.0:  # the feed is already as fine: no parameter changes that
        return 0.0, 0.0, 0.0
    return v, lo, (math.inf if v == math.inf else hi)


def selection_rates(fit: SizeFit, cond) -> dict[str, np.ndarray]:
    """1/s per class, impact and attrition routes, at the fit's best parameters."""
    return selection(grinding(fit.all_params(), fit.measure, fit.stress_only), fit.classes, cond)


# ---------------------------------------------------------------- the fit file
def is_fit_file(path) -> bool:
    """True if `path` is a sizes fit file taimill wrote (its first line is MARK): the one
    kind of file `taimill sizes fit --out … --overwrite` replaces."""
    from taimill.outcome.files import starts_with

    return starts_with(path, MARK)


def write_fit(path, fit: SizeFit, header: str) -> None:
    """The fit as a small TOML file, MARK its first line, `header` (# comments) next."""
    from pathlib import Path

    from taimill.outcome.files import toml_value
    from taimill.store.output import whole_file

    top = {"model": MODEL, "measure": fit.measure, "stress_only": fit.stress_only, "level": fit.level,
           "interval_method": fit.interval_method, "sigma": fit.sigma, "conditions": fit.conditions,
           "warnings": fit.warnings, "open_ends": fit.open_ends, "covariance_names": fit.covariance_names,
           "covariance": fit.covariance}
    tables = {"parameters": fit.params, "intervals": {k: list(v) for k, v in fit.intervals.items()},
              "fixed": fit.fixed, "goodness": fit.goodness, "correlation": fit.correlation,
              "profile_ends": fit.profile_ends,
              "classes": {"top_m": fit.classes.top_m, "n": fit.classes.n, "ratio": fit.classes.ratio, "feed": fit.feed}}
    lines = [MARK] + [f"# {h}" for h in header.splitlines()]
    lines.append("# covariance and profile_ends: of the log10 parameters, for prediction bands; "
                 "classes.feed: masses per class of the first condition's feed")
    lines += [f"{k} = {toml_value(v)}" for k, v in top.items()]
    for name, table in tables.items():
        lines += ["", f"[{name}]"] + [f"{json.dumps(k)} = {toml_value(v)}" for k, v in table.items()]
    with whole_file(Path(path), "fit") as part:
        Path(part).write_text("\n".join(lines) + "\n")


MODEL = "population-balance"  #: the fit file's `model`: what tells it from a kinetics fit


def read_fit(path, source: str = "command line", key: str = "--fit") -> SizeFit:
    """A fit file written by write_fit. Everything a prediction uses is checked: a file
    that is not one (a kinetics fit, a parameter file), or one whose numbers a fit cannot
    have (edited, damaged), is a one-line ConfigError naming the file, the key, the
    value and what is allowed, rather than a wrong band."""
    from taimill.model.files import read_toml
    from taimill.model.spectra import MEASURES
    from taimill.outcome.files import _checked, _choice, _covariance, _goodness, _table

    path = str(path)
    doc = read_toml(path, source, key, "sizes fit file (TOML)")
    if doc.get("model") != MODEL:
        raise ConfigError(path, "model", doc.get("model"), f"allowed: {MODEL!r} (a file of taimill sizes fit)")
    for k in ("measure", "sigma", "covariance_names", "covariance", "classes", "parameters"):
        if k not in doc:
            raise ConfigError(path, k, None, "missing (a file of taimill sizes fit)")
    _choice(path, "measure", doc["measure"], MEASURES)
    _choice(path, "sigma", doc["sigma"], ("given", "2 % of each share"))
    if not isinstance(doc.get("stress_only", True), bool):
        raise ConfigError(path, "stress_only", doc["stress_only"], "true or false")
    level = _checked(path, "level", doc.get("level", 0.95), 0.5, 1.0, "[0.5, 1)", hi_open=True)
    for k in ("conditions", "warnings", "open_ends"):
        if not isinstance(doc.get(k, []), list) or not all(isinstance(x, str) for x in doc.get(k, [])):
            raise ConfigError(path, k, doc.get(k), "a list of strings")
    fitted, held = _table(doc, path, "parameters"), _table(doc, path, "fixed")
    if set(fitted) | set(held) != set(PARAMS) or set(fitted) & set(held) or not fitted:
        raise ConfigError(path, "parameters", sorted(fitted), f"with [fixed], each of {', '.join(PARAMS)} once, "
                          "at least one fitted")
    for table, values in (("parameters", fitted), ("fixed", held)):
        for name, v in values.items():
            _, lo, hi, unit = PARAMS[name]
            if table == "parameters":
                _checked(path, f"parameters.{name}", v, lo, hi, f"[{lo:g}, {hi:g}] {unit}")
            elif name in ("xw_min", "k_att"):
                _checked(path, f"fixed.{name}", v, 0.0, hi, f"[0, {hi:g}] {unit}")
            else:
                _checked(path, f"fixed.{name}", v, 0.0, hi, f"(0, {hi:g}] {unit}", lo_open=True)
    intervals = _table(doc, path, "intervals")
    if set(intervals) != set(fitted):
        raise ConfigError(path, "intervals", sorted(intervals), f"one [lower, upper] for each of {', '.join(fitted)}")
    for name, v in intervals.items():
        ok = (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                          and 0 < x < math.inf for x in v)
              and v[0] <= fitted[name] * (1 + 1e-9) and fitted[name] <= v[1] * (1 + 1e-9))
        if not ok:
            raise ConfigError(path, f"intervals.{name}", v, f"[lower, upper]: positive, around the value {fitted[name]!r}")
    cov = _covariance(path, doc["covariance_names"], doc["covariance"], fitted)
    ends = _table(doc, path, "profile_ends")
    for name, v in ends.items():
        ok = (name in fitted and isinstance(v, list) and len(v) == 2
              and all(isinstance(r, list) and len(r) == len(fitted) and all(
                  isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and
                  math.log10(PARAMS[n][1]) - 1e-9 <= x <= math.log10(PARAMS[n][2]) + 1e-9
                  for x, n in zip(r, doc["covariance_names"])) for r in v))
        if not ok:
            raise ConfigError(path, f"profile_ends.{name}", v, f"two lists of {len(fitted)} log10 values of "
                              f"{', '.join(doc['covariance_names'])}, each within its bounds")
    correlation = _table(doc, path, "correlation")
    for name, r in correlation.items():
        _checked(path, f"correlation.{name}", r, -1.0 - 1e-6, 1.0 + 1e-6, "[-1, 1]")
    goodness = _goodness(path, _table(doc, path, "goodness"), "given")
    c = _table(doc, path, "classes")
    top = _checked(path, "classes.top_m", c.get("top_m"), 1e-9, 0.1, "[1e-9, 0.1] m")
    n = c.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= 400:
        raise ConfigError(path, "classes.n", n, "a whole number in [2, 400]")
    ratio = _checked(path, "classes.ratio", c.get("ratio"), 1.0, 2.0, "(1, 2]", lo_open=True)
    feed_m = c.get("feed")
    if (not isinstance(feed_m, list) or len(feed_m) != n + 1
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and 0 <= x < math.inf for x in feed_m)
            or not sum(feed_m) > 0):
        raise ConfigError(path, "classes.feed", feed_m, f"{n + 1} masses ≥ 0 (one per class and the sink), not all 0")
    return SizeFit({k: float(v) for k, v in fitted.items()}, {k: (float(a), float(b)) for k, (a, b) in intervals.items()},
                   {k: float(v) for k, v in held.items()}, doc["measure"], bool(doc.get("stress_only", True)), level,
                   list(doc.get("conditions", [])), goodness, doc["sigma"], SizeClasses(top, n, ratio),
                   [float(x) for x in feed_m], list(doc["covariance_names"]), cov, correlation,
                   {k: [[float(x) for x in r] for r in v] for k, v in ends.items()}, list(doc.get("warnings", [])),
                   list(doc.get("open_ends", [])), str(doc.get("interval_method", "")))
