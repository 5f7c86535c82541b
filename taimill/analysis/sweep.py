"""Statistics of a sweep: which swept values vary (`sweep_axes`: the x axis, a second
numeric axis that makes the sweep a map, the curves), replicate means with Student-t
confidence bands, the share of the replicas in each motion regime at each value, and
the rule `--refine` uses to locate the maximum of a figure of merit along K. NumPy and
math only (scipy is not a dependency)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from taimill.schema import REGIME_CLASSES

CONFIDENCE = 0.95
# table columns telling curves apart (tables of sweeps from before mills have no "mill": read as "")
CURVE_COLUMNS = ("mill", "jar", "balls", "pair", "plate_rpm")
REGIMES = REGIME_CLASSES  # the regime classes of summaries, tables and figures (analysis.regime.row_class)

# The columns of a sweep table that describe a point (taimill.runs.sweep.point_values, and
# any other the sweep stores with the point) and can be its axes: column -> (symbol, unit,
# scale from the column's unit to the shown one, axis label). Where several vary together
# (a jar and its radius, a pair and its coefficients) the first listed names the axis: text
# axes first (one curve each), then numbers. A column not listed is an axis too, after
# these, named by itself.
AXIS_LABELS = {
    "mill": ("mill", "", None, "mill"),
    "jar": ("jar", "", None, "jar"),
    "pair_name": ("pair", "", None, "contact pair"),
    "pair_ball_wall": ("wall pair", "", None, "ball-wall pair"),
    "jar_material": ("jar material", "", None, "jar material"),
    "ball_material": ("ball material", "", None, "ball material"),
    "material": ("ball material", "", None, "ball material"),
    "ratio": ("K", "", 1, "K = ω/Ω + 1 (jar spin / plate spin; |K| grows to the right)"),
    "plate_rpm": ("Ω", "rpm", 1, "plate speed Ω (rpm)"),
    "jar_rpm": ("ω", "rpm", 1, "jar speed ω relative to the plate (rpm)"),
    "balls": ("balls", "", 1, "number of balls"),
    "ball_diameter_mm": ("d", "mm", 1, "ball diameter d (mm)"),
    "ball_radius": ("d", "mm", 2e3, "ball diameter d (mm)"),
    "mu": ("μ", "", 1, "friction μ (μ_s)"),
    "mu_r": ("μ_r", "", 1, "rolling resistance μ_r"),
    "mu_wall": ("μ wall", "", 1, "ball-wall friction μ (μ_s)"),
    "mu_r_wall": ("μ_r wall", "", 1, "ball-wall rolling resistance μ_r"),
    "mu_d": ("μ_d", "", 1, "dynamic friction μ_d"),
    "mu_d_wall": ("μ_d wall", "", 1, "ball-wall dynamic friction μ_d"),
    "plate_radius_mm": ("R_p", "mm", 1, "plate radius R_p (mm)"),
    "plate_radius": ("R_p", "mm", 1e3, "plate radius R_p (mm)"),
    "jar_radius": ("R", "mm", 1e3, "jar radius R (mm)"),
    "ball_mass": ("m", "g", 1e3, "ball mass m (g)"),
    "duration": ("duration", "s", 1, "simulated time per point (s)"),
    "pair": ("pair", "", None, "contact pair"),  # the pair and its tuned coefficients: named by them if they vary
}
NOT_AXES = ("point", "seed", "replica", "done", "batch")  # a point's identity, its replica, bookkeeping
# the point's description shown once above a table where these do not vary
HEADLINE = ("mill", "jar", "balls", "ball_radius", "pair", "plate_rpm", "ratio")


def is_text(values) -> bool:
    """Whether a column holds text (categorical axis) rather than numbers."""
    a = np.asarray(values)
    return a.dtype.kind in "USOT" and not all(isinstance(v, (int, float, np.number)) for v in a.tolist())


def codes(values) -> tuple:
    """A column as hashable values, numbers rounded to 10 decimals (as the sweep rounds K)."""
    a = np.asarray(values)
    return tuple(str(v) for v in a.tolist()) if is_text(a) else tuple(np.round(a.astype(float), 10).tolist())


def varying_axes(table, candidates=()) -> list[str]:
    """The columns of `table` (a mapping of columns, one row per point × replica) that
    vary over its rows and describe the points: AXIS_LABELS' columns, then `candidates`
    (e.g. the keys of the stored points' values), NOT_AXES left out. Columns that split
    the rows the same way (a jar and its radius) are one axis, named by the first."""
    names = [c for c in dict.fromkeys([*AXIS_LABELS, *candidates]) if c in table and c not in NOT_AXES]
    out, seen = [], []
    for c in names:
        col = codes(table[c])
        n = len(set(col))
        if n < 2:
            continue
        if any(len(set(zip(col, other))) == n == len(set(other)) for other in seen):
            continue  # varies with an axis already named
        seen.append(col)
        out.append(c)
    return out


@dataclass(frozen=True)
class SweepAxes:
    """How a sweep is drawn: `x` the column on the x axis; `y` a second numeric column
    when exactly two numeric columns vary (the sweep is then also a map, x by y);
    `curves` every other varying column (one curve, or one map panel, per combination
    of their values); `fixed` the HEADLINE columns that do not vary (one value in every
    row); `companions` (companion_columns) those that vary with an axis."""

    x: str
    y: str | None
    curves: tuple[str, ...]
    fixed: tuple[str, ...]
    text_x: bool = False  #: x is a text axis (no numeric one varies): its values are drawn as categories

    @property
    def columns(self) -> tuple[str, ...]:
        """The varying columns: curves, then x (the innermost)."""
        return (*self.curves, self.x)


def sweep_axes(table, candidates=()) -> SweepAxes:
    """The axes of a sweep table (varying_axes): x is the numeric axis with the most
    values (ties: the first in AXIS_LABELS' order), else the first text axis, else K."""
    varying = varying_axes(table, candidates)
    numeric = [c for c in varying if not is_text(table[c])]
    if numeric:
        x = max(numeric, key=lambda c: (len(set(codes(table[c]))), -numeric.index(c)))
    else:
        x = varying[0] if varying else "ratio"
    y = next((c for c in numeric if c != x), None) if len(numeric) == 2 else None
    # only what every row shares: a column that varies with an axis (the ball count a
    # filling gives each bowl volume) is not an axis, and not one value either
    fixed = tuple(c for c in HEADLINE if c in table and c not in varying and c != x and len(set(codes(table[c]))) == 1)
    return SweepAxes(x, y, tuple(c for c in varying if c != x), fixed, bool(varying) and not numeric)


def companion_columns(table, axes: "SweepAxes") -> list[str]:
    """HEADLINE columns that vary over the rows without being an axis: they vary with one
    (the ball count a filling gives each bowl volume), so a table shows them per row."""
    return [c for c in HEADLINE if c in table and c not in axes.columns and c not in axes.fixed
            and len(set(codes(table[c]))) > 1]


def axis_header(column: str) -> str:
    """A short column header: "Ω rpm", "K", "jar", or the column's own name."""
    sym, unit, _, _ = AXIS_LABELS.get(column, (column, "", 1, column))
    return f"{sym} {unit}".strip()


def axis_label(column: str) -> str:
    """The axis label of a column: "plate speed Ω (rpm)"."""
    return AXIS_LABELS.get(column, (column, "", 1, column))[3]


def axis_scale(column: str):
    """Scale from the table's unit to the shown one (None: text)."""
    return AXIS_LABELS.get(column, (column, "", 1, column))[2]


def value_text(column: str, value) -> str:
    """One value of an axis for a legend or a headline: "Ω = 200 rpm", "12 balls", "CY"."""
    sym, unit, scale, _ = AXIS_LABELS.get(column, (column, "", 1, column))
    if isinstance(value, str) or scale is None:
        return str(value)
    if column == "balls":
        return f"{int(value)} balls"
    return f"{sym} = {float(value) * scale:g}" + (f" {unit}" if unit else "")


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


def regime_fractions(table, columns=(*CURVE_COLUMNS, "ratio")) -> list[dict]:
    """Share of the replicas in each regime class, per point of a sweep table (a mapping
    of columns as in the sweep store, one row per point × replica; uses `columns` and the
    class of each row, taimill.analysis.regime.row_class: its `regime_class`, else from
    `regime` and the wall criteria). A point is a combination of `columns`' values, the
    last being the x axis (default: CURVE_COLUMNS, K). One entry per curve (the other
    columns, in order of first appearance) and x value (ascending; numbers rounded to 10
    decimals): {the columns' values, replicas (count), regime_fractions ({class: share in
    [0, 1]}, always every class of REGIMES, plus "unknown" where seen), bistable}.
    `bistable` is true when the replicas end in more than one class ("unknown" aside):
    their mean then mixes distinct states of the mill."""
    from taimill.analysis.regime import row_class

    *curve_cols, x = columns
    xs = np.asarray(codes(table[x]), dtype=object)
    names = list(table)
    labels = [row_class({c: py_value(table[c][i]) for c in names}) for i in range(len(xs))]
    # a table from before mills has no mill column: one mill
    curves = list(zip(*(np.asarray(table[c]).tolist() if c in table else [""] * len(xs) for c in curve_cols))) or [()] * len(xs)
    out = []
    for curve in dict.fromkeys(curves):
        on_curve = np.array([c == curve for c in curves])
        for k in sorted(set(xs[on_curve].tolist())):
            seen = [lab for lab, here in zip(labels, on_curve & (xs == k)) if here]
            shares = {lab: seen.count(lab) / len(seen) for lab in (*REGIMES, *sorted(set(seen) - set(REGIMES)))}
            out.append(dict(zip(curve_cols, curve)) | {
                x: k, "replicas": len(seen), "regime_fractions": shares,
                "bistable": len(set(seen) - {"unknown"}) > 1})
    return out


def seen_classes(groups: list[dict]) -> list[str]:
    """The classes some replica of `groups` (regime_fractions) ends in, in REGIMES'
    order, "unknown" last: what a table or figure of them shows."""
    seen = {lab for g in groups for lab, share in g["regime_fractions"].items() if share > 0}
    return [lab for lab in (*REGIMES, "unknown") if lab in seen] + sorted(seen - set(REGIMES) - {"unknown"})


def py_value(v):
    """A NumPy scalar of a table column as a Python value (str, float, int)."""
    return v.item() if hasattr(v, "item") else v


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


def x_values(table: dict, rows, x: str) -> np.ndarray:
    """The x coordinate of `rows`: the column's numbers (rounded to 10 decimals, in the
    table's unit), or for a text axis the index of each value among the table's values."""
    v = np.asarray(table[x])[rows]
    if is_text(table[x]):
        names = list(dict.fromkeys(str(c) for c in table[x]))
        return np.array([names.index(str(c)) for c in v], dtype=float)
    return np.round(v.astype(float), 10)


def curves(table: dict, axes: SweepAxes | None = None) -> dict[str, np.ndarray]:
    """Label → row indices, one curve per combination of the values of the axes that
    vary besides x (axes.curves); the label names those values ("Ω = 200 rpm, HM")."""
    axes = axes or sweep_axes(table)
    n = len(table["point"])
    out: dict = {}
    for i in range(n):
        label = ", ".join(value_text(c, table[c][i].item() if hasattr(table[c][i], "item") else table[c][i])
                          for c in axes.curves)
        out.setdefault(label or "all points", []).append(i)
    return {label: np.array(rows) for label, rows in out.items()}


def first_value(column):
    """The first value of a column, as a Python value."""
    v = np.asarray(column)[0]
    return v.item() if hasattr(v, "item") else v
