"""Statistics of a sweep: replicate means with Student-t confidence bands, the share of
the replicas in each motion regime at each K, and the rule `--refine` uses to locate
the maximum of a figure of merit along K. NumPy and math only (scipy is not a
dependency)."""

from __future__ import annotations

import math

import numpy as np

CONFIDENCE = 0.95
# table columns telling curves apart (tables of sweeps from before mills have no "mill": read as "")
CURVE_COLUMNS = ("mill", "jar", "balls", "pair", "plate_rpm")
REGIMES = ("cascading", "cataracting", "rolling")  # taimill.analysis.regime's labels


def t_two_sided_cdf(t: float, nu: int) -> float:
    """P(|T| < t) for Student's T with nu (integer ≥ 1) degrees of freedom, exact
    finite series of Abramowitz & Stegun 26.7.3 (θ = atan(t/√ν))."""
    if nu < 1:
        raise ValueError(f"degrees of freedom must be ≥ 1, got {nu}")
    if t <= 0:
        return 0.0
    theta = math.atan(t / math.sqrt(nu))
    s, c = math.sin(theta), math.cos(theta)
    if nu % 2:  # odd: (2/π)(θ + sinθ (cosθ + 2/3 cos³θ + … + (2·4…(ν−3))/(1·3…(ν−2)) cos^(ν−2)θ))
        term, series = c, 0.0
        for k in range(1, (nu - 1) // 2 + 1):
            series += term
            term *= c * c * (2 * k) / (2 * k + 1)
        return 2.0 / math.pi * (theta + s * series)
    term, series = 1.0, 0.0  # even: sinθ (1 + 1/2 cos²θ + 1·3/(2·4) cos⁴θ + …)
    for k in range(1, nu // 2 + 1):
        series += term
        term *= c * c * (2 * k - 1) / (2 * k)
    return s * series


def t_quantile(nu: int, confidence: float = CONFIDENCE) -> float:
    """t such that P(|T| < t) = confidence (two-sided), by bisection on the exact CDF
    to 1e-12 relative; e.g. ν = 1: 12.706, 4: 2.776, 30: 2.042 at 95 %."""
    lo, hi = 0.0, 1.0
    while t_two_sided_cdf(hi, nu) < confidence:
        hi *= 2.0
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if t_two_sided_cdf(mid, nu) < confidence else (lo, mid)
    return 0.5 * (lo + hi)


def mean_band(values, confidence: float = CONFIDENCE) -> tuple[float, float, int]:
    """(mean, half-width of the two-sided Student-t confidence interval of the mean,
    n) over the finite values; half-width NaN for fewer than two values."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n == 0:
        return math.nan, math.nan, 0
    if n == 1:
        return float(x[0]), math.nan, 1
    half = t_quantile(n - 1, confidence) * float(np.std(x, ddof=1)) / math.sqrt(n)
    return float(x.mean()), half, n


def group_mean(ks, values) -> tuple[np.ndarray, np.ndarray]:
    """Unique K (ascending) and the mean of `values` over the replicas at each K
    (NaN where none is finite)."""
    ks, values = np.asarray(ks, dtype=float), np.asarray(values, dtype=float)
    uk = np.unique(np.round(ks, 10))
    means = np.array([mean_band(values[np.isclose(ks, k, rtol=0, atol=1e-9)])[0] for k in uk])
    return uk, means


def regime_fractions(table) -> list[dict]:
    """Share of the replicas in each motion regime, per curve and K of a sweep table
    (a mapping of columns as in the sweep store, one row per point × replica; uses
    CURVE_COLUMNS, `ratio` and `regime`). One entry per curve (in order of first
    appearance) and K (ascending, rounded to 10 decimals):
    {jar, balls, pair, plate_rpm, ratio, replicas (count), regime_fractions
    ({label: share in [0, 1]}, always the three REGIMES, plus any other label seen,
    e.g. "unknown"), bistable}. `bistable` is true when the replicas end in more than
    one regime ("unknown" aside): their mean then mixes distinct states of the mill."""
    ks = np.round(np.asarray(table["ratio"], dtype=float), 10)
    labels = [str(v) or "unknown" for v in table["regime"]]
    curves = list(zip(*(np.asarray(table[c]).tolist() if c in table else [""] * len(ks) for c in CURVE_COLUMNS)))
    out = []
    for curve in dict.fromkeys(curves):
        on_curve = np.array([c == curve for c in curves])
        for k in np.unique(ks[on_curve]):
            seen = [lab for lab, here in zip(labels, on_curve & (ks == k)) if here]
            shares = {lab: seen.count(lab) / len(seen) for lab in (*REGIMES, *sorted(set(seen) - set(REGIMES)))}
            out.append(dict(zip(CURVE_COLUMNS, curve)) | {
                "ratio": float(k), "replicas": len(seen), "regime_fractions": shares,
                "bistable": len(set(seen) - {"unknown"}) > 1})
    return out


def _best(uk, means) -> int | None:
    ok = np.isfinite(means)
    return int(np.nanargmax(np.where(ok, means, -np.inf))) if ok.any() else None


def refine_candidates(ks, values, min_gap: float = 1e-6) -> list[float]:
    """One refinement round (the `--refine` rule): with the replicate-mean metric at
    each simulated K, take the best K and add the midpoints between it and each of its
    two neighbouring simulated K (one neighbour at an end of the range: the sweep never
    leaves the range asked for). Each round halves the spacing around the maximum;
    gaps narrower than `min_gap` are not split. Midpoints are rounded to 10 decimals
    so that the same K typed on the command line gives the same run."""
    uk, means = group_mean(ks, values)
    i = _best(uk, means)
    if i is None:
        return []
    out = []
    for j in (i - 1, i + 1):
        if 0 <= j < len(uk) and abs(uk[j] - uk[i]) > 2 * min_gap:
            out.append(round(float(0.5 * (uk[i] + uk[j])), 10))
    return out


def parabolic_peak(ks, values) -> dict:
    """Location of the maximum: the vertex of the parabola through the best K and its
    two neighbours (exact for any spacing), kept inside their interval; where the best
    K is an end of the range or the three points are not concave, the best simulated
    K itself. Returns {ratio, value, method ("parabola" | "grid" | "edge")}."""
    uk, means = group_mean(ks, values)
    i = _best(uk, means)
    if i is None:
        return {"ratio": math.nan, "value": math.nan, "method": "none"}
    if i == 0 or i == len(uk) - 1 or not np.isfinite(means[[i - 1, i + 1]]).all():
        return {"ratio": float(uk[i]), "value": float(means[i]), "method": "edge" if len(uk) > 1 else "grid"}
    x, y = uk[i - 1:i + 2], means[i - 1:i + 2]
    a, b, c = np.polyfit(x - x[1], y, 2)  # centred: well conditioned
    if a >= 0:
        return {"ratio": float(uk[i]), "value": float(means[i]), "method": "grid"}
    dx = float(np.clip(-b / (2 * a), x[0] - x[1], x[2] - x[1]))
    return {"ratio": float(x[1] + dx), "value": float(c + b * dx + a * dx * dx), "method": "parabola"}
