"""A population balance of the powder's particle sizes, driven by a run's collisions
(docs/outcome.md, "Particle sizes"): the batch grinding equation over geometric size
classes,

    dM_i/dt = −S_i M_i + Σ_{j<i} b_ij S_j M_j,

M_i the mass in class i (coarsest first), S_i (1/s) the rate at which class i's mass
breaks, b_ij the share of class j's broken mass that lands in class i. Two routes break
the powder, each with its own selection rate:

- **impact**: the run's stress events, bin by bin of their energy spectrum. An event of
  energy E catches `capture_g` of powder (one mass per event, fitted like the critical
  collisions' κ_g), giving it the specific energy W = E / capture; a particle of size x
  so stressed breaks with Vogel and Peukert's probability
  P(x, W) = 1 − exp(−f_Mat x (W − W_min(x))), W_min(x) = xW_min / x, zero below it
  (Vogel & Peukert, Powder Technol. 129 (2003) 101). Events per second and gram times
  the mass each catches is the share of the charge stressed per second:
  S_i = capture_g Σ_k ṅ_g,k P(x_i, E_k / capture).
- **attrition**: the friction work of the persistent and sliding contacts, which carry
  most of a standard-gear mill's power (a model that counted impacts only would say such
  charges do not grind): S_i = k_att P_f, P_f the friction power per gram of powder.

Fragments of either route follow Austin's cumulative breakage function relative to the
parent class's upper size y, B(x; y) = φ (x/y)^γ + (1 − φ)(x/y)^β (Austin & Luckie,
Powder Technol. 5 (1972) 215). The part of a breakage that stays in the parent class is
no breakage: the rates are taken net of it (S_j (1 − b_jj), b_ij / (1 − b_jj)), so each
broken mass leaves its class and the masses sum to the start's at every time.

The rates do not change with time (the balls do not feel the powder), so the solution is
M(t) = exp(A t) M(0) with A = (b − I) diag(S), lower triangular: one matrix exponential
per time (scaled and squared, `evolve`), a 0–64 h curve of 40 classes in milliseconds. The finest class is a
sink (everything below the finest edge) whose mass does not break further.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from taimill.model.spectra import CLASSES, LOWER, MEASURES
from taimill.outcome.condition import Condition

SQRT2 = math.sqrt(2.0)


@dataclass(frozen=True)
class SizeClasses:
    """Geometric size classes: edges top, top/ratio, …, top/ratio^n (m), coarsest first;
    class i (0 … n−1) lies between edges i+1 and i, class n (the sink) below the finest
    edge. `ratio` √2 (the sieve series) or finer."""

    top_m: float
    n: int
    ratio: float = SQRT2

    def __post_init__(self):
        if not (self.top_m > 0 and math.isfinite(self.top_m)):
            raise ValueError(f"top size {self.top_m!r} m: must be a positive number")
        if not 1.0 < self.ratio <= 2.0:
            raise ValueError(f"size ratio {self.ratio!r}: must lie in (1, 2] (√2 is the sieve series)")
        if not 2 <= self.n <= 400:
            raise ValueError(f"{self.n!r} classes: must lie in [2, 400]")

    @classmethod
    def spanning(cls, finest_m: float, top_m: float, ratio: float = SQRT2) -> "SizeClasses":
        """Classes from top_m down to at most finest_m."""
        if not 0 < finest_m < top_m:
            raise ValueError(f"finest size {finest_m!r} m must lie in (0, top size {top_m!r} m)")
        return cls(top_m, max(2, math.ceil(math.log(top_m / finest_m) / math.log(ratio) - 1e-9)), ratio)

    @property
    def edges(self) -> np.ndarray:
        """m, the n + 1 upper edges of the classes and of the sink, coarsest first."""
        return self.top_m * self.ratio ** -np.arange(self.n + 1, dtype=float)

    @property
    def sizes(self) -> np.ndarray:
        """m, each class's representative size: the geometric mean of its edges (the
        sink's: one ratio below its upper edge)."""
        e = self.edges
        return np.concatenate([np.sqrt(e[:-1] * e[1:]), [e[-1] / math.sqrt(self.ratio)]])

    def __len__(self) -> int:
        return self.n + 1


@dataclass(frozen=True)
class Austin:
    """Austin's breakage function: B(x; y) = φ (x/y)^γ + (1 − φ)(x/y)^β, the share of a
    broken parent of upper size y that passes x (0 < φ ≤ 1, 0 < γ < β)."""

    phi: float
    gamma: float
    beta: float

    def __post_init__(self):
        for name, v, lo, hi in (("phi", self.phi, 0.0, 1.0), ("gamma", self.gamma, 0.0, math.inf),
                                ("beta", self.beta, 0.0, math.inf)):
            if not (lo < v <= hi and math.isfinite(v)):
                raise ValueError(f"Austin breakage {name} = {v!r}: must lie in ({lo:g}, {hi:g}]")

    def passing(self, x, y) -> np.ndarray:
        r = np.clip(np.asarray(x, dtype=float) / y, 0.0, 1.0)
        return self.phi * r ** self.gamma + (1.0 - self.phi) * r ** self.beta

    def matrix(self, classes: SizeClasses) -> tuple[np.ndarray, np.ndarray]:
        """(b, kept): b[i, j] the share of class j's broken mass landing in class i > j,
        each column of a breakable class summing to 1 (the part that stays in class j
        taken out, module doc); kept[j], that part (1 − B(lower edge; upper edge))."""
        e = classes.edges
        m = len(classes)
        b = np.zeros((m, m))
        kept = np.zeros(m)
        for j in range(m - 1):
            y = e[j]
            upper = self.passing(e[j + 1:], y)  # passing the upper edge of each class below j
            lower = np.concatenate([upper[1:], [0.0]])  # … and its lower edge (the sink: 0)
            share = upper - lower
            kept[j] = 1.0 - upper[0]
            if upper[0] > 0:
                b[j + 1:, j] = share / upper[0]
        return b, kept


@dataclass(frozen=True)
class Grinding:
    """The population balance's parameters (module doc). Impact: `capture_g` (g of powder
    one event catches), `f_mat` (kg/(J m)) and `xw_min` (J m/kg) of Vogel and Peukert's
    breakage probability, the spectra's `measure` and whether only stress events count.
    Attrition: `k_att` (g/J: share of the charge abraded per J of friction work per g).
    `breakage`: the fragments' Austin function."""

    breakage: Austin
    capture_g: float = 0.0
    f_mat: float = 0.0
    xw_min: float = 0.0
    k_att: float = 0.0
    measure: str = "dissipated_normal"
    stress_only: bool = True

    def __post_init__(self):
        for name in ("capture_g", "f_mat", "xw_min", "k_att"):
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise ValueError(f"{name} = {v!r}: must be a finite number ≥ 0")
        if self.measure not in MEASURES:
            raise ValueError(f"measure {self.measure!r}: one of {', '.join(MEASURES)}")


def breakage_probability(x, w, f_mat: float, xw_min: float) -> np.ndarray:
    """Vogel and Peukert's P(x, W) = 1 − exp(−f_Mat x (W − xW_min / x)), 0 where W is
    below the size's minimum: x (m), W (J/kg), f_mat (kg/(J m)), xw_min (J m/kg)."""
    x, w = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(w, dtype=float))
    excess = np.maximum(f_mat * (x * w - xw_min), 0.0)
    return -np.expm1(-excess)


def event_bins(cond: Condition, measure: str, stress_only: bool) -> tuple[np.ndarray, np.ndarray]:
    """(events per second and gram, mean energy J) in each bin of the condition's
    spectrum of `measure`, both contact kinds; stress events only, or every contact."""
    q = MEASURES.index(measure)
    classes = [CLASSES.index("stress")] if stress_only else list(range(len(CLASSES)))
    sp = cond.spectra
    count = sp.count[:, classes, q, :].sum(axis=(0, 1)).astype(float)
    joules = sp.energy()[:, classes, q, :].sum(axis=(0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, joules / np.maximum(count, 1.0), LOWER)
    return count / sp.seconds / cond.powder_g, mean


def friction_power_per_g(cond: Condition) -> float:
    """W/g: the power friction dissipates per gram of powder in the whole charge (the
    condition's `shear_w_per_g`, from the run summary). A condition without it (a
    condition file written without the key) falls back to the friction of its spectra's
    events, which leaves out contacts that never closed in the window: a sliding bed's
    friction, all of a friction-led charge's power, is in no spectrum."""
    if math.isfinite(cond.shear_w_per_g):
        return float(cond.shear_w_per_g)
    rate, mean = event_bins(cond, "dissipated_friction", False)
    return float(np.sum(rate * mean))


def selection(g: Grinding, classes: SizeClasses, cond: Condition) -> dict[str, np.ndarray]:
    """1/s per class (the sink 0): the impact and attrition routes' selection rates
    before the fragments that stay in their class are taken out (module doc)."""
    x = classes.sizes
    impact = np.zeros(len(classes))
    if g.capture_g > 0 and g.f_mat > 0:
        rate, energy = event_bins(cond, g.measure, g.stress_only)
        on = rate > 0
        w = energy[on] / (g.capture_g * 1e-3)  # J/kg of the caught powder
        p = breakage_probability(x[:, None], w[None, :], g.f_mat, g.xw_min)
        impact = g.capture_g * (p @ rate[on])
    attrition = np.full(len(classes), g.k_att * friction_power_per_g(cond)) if g.k_att > 0 else np.zeros(len(classes))
    impact[-1] = attrition[-1] = 0.0
    return {"impact": impact, "attrition": attrition}


def rate_matrix(s: np.ndarray, b: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """A of dM/dt = A M: (b − I) diag(S (1 − kept)); every column sums to 0."""
    net = np.asarray(s, dtype=float) * (1.0 - kept)
    a = b * net[None, :]
    a[np.diag_indices_from(a)] = -net
    a[:, -1] = 0.0  # the sink keeps its mass
    return a


TAYLOR = 16  #: terms of exp(X) for ‖X‖₁ ≤ ½: the remainder is below 10⁻¹⁸


def evolve(a: np.ndarray, m0: np.ndarray, t) -> np.ndarray:
    """M at each time t (s): exp(A t) M(0), one row per time. A conserves mass (its
    columns sum to 0; anything else is refused), so exp(A t) maps masses to masses: its
    entries are ≥ 0 and its columns sum to 1. It is built as exp(A t / 2^k), with
    ‖A t / 2^k‖₁ ≤ ½ where a 16-term Taylor series is exact to rounding, squared k
    times, each square's columns scaled back to their sum of 1: a square doubles the
    error of the sums, and 30 squarings (rates of 10³/s over 64 h) would lose 10⁻⁷ of the
    charge. (scipy's expm of A t itself lost 15 % of it there; its Padé step on A t / 2^k
    is as exact but runs threaded, which cost a fit on a busy machine 20 times its
    arithmetic.)"""
    m0 = np.asarray(m0, dtype=float)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if np.any(~np.isfinite(t)) or np.any(t < 0):
        raise ValueError("milling times must be finite and ≥ 0 s")
    norm = float(np.max(np.abs(a).sum(axis=0))) if a.size else 0.0
    if np.max(np.abs(a.sum(axis=0)), initial=0.0) > 1e-12 * max(norm, 1e-300):
        raise ValueError("the rate matrix does not conserve mass: a breakage column does not sum to 1")
    out = []
    for ti in t:
        k = max(0, math.ceil(math.log2(norm * ti / 0.5))) if norm * ti > 0.5 else 0
        x = a * (ti / 2.0 ** k)
        e = term = np.eye(len(a))
        for j in range(1, TAYLOR + 1):
            term = term @ x / j
            e = e + term
        for _ in range(k):
            e = e @ e
            e /= e.sum(axis=0, keepdims=True)
        out.append(e @ m0)
    return np.array(out)


def rates(g: Grinding, classes: SizeClasses, cond: Condition) -> np.ndarray:
    """The rate matrix A of dM/dt = A M at a condition: both routes' selection rates."""
    s = selection(g, classes, cond)
    b, kept = g.breakage.matrix(classes)
    return rate_matrix(s["impact"] + s["attrition"], b, kept)


def grind(g: Grinding, classes: SizeClasses, cond: Condition, m0, t) -> np.ndarray:
    """Masses per class at each time t (s) from the start masses m0 (any unit)."""
    return evolve(rates(g, classes, cond), m0, t)


HOURS_MAX = 10_000.0  #: h, the longest milling a time to target looks for


def time_to_x90(g: Grinding, classes: SizeClasses, cond: Condition, m0, target_m: float,
                hours_max: float = HOURS_MAX) -> float:
    """s until x90 falls to `target_m` (bisection in log time; inf if not by hours_max).
    The rate matrix is built once."""
    a = rates(g, classes, cond)

    def x90(t):
        v = quantile_size(classes, passing(classes, evolve(a, m0, [t])), 0.9)[0]
        return 0.0 if math.isnan(v) else v  # nan: below the finest edge

    if x90(0.0) <= target_m:
        return 0.0
    hi = hours_max * 3600.0
    if x90(hi) > target_m:
        return math.inf
    lo = 1.0
    if x90(lo) <= target_m:
        return lo
    for _ in range(80):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if x90(mid) > target_m else (lo, mid)
        if hi / lo < 1.0001:
            break
    return hi


def passing(classes: SizeClasses, m: np.ndarray) -> np.ndarray:
    """Cumulative share passing each edge (coarsest first), per row of masses m."""
    m = np.atleast_2d(m)
    total = m.sum(axis=1, keepdims=True)
    below = total - np.cumsum(m, axis=1)  # mass below class i's lower edge = passing edge i + 1
    q = np.concatenate([np.ones((len(m), 1)) * (total > 0), below[:, :-1] / np.where(total > 0, total, 1.0)], axis=1)
    return q


def quantile_size(classes: SizeClasses, q: np.ndarray, share: float) -> np.ndarray:
    """m, the size below which `share` of the mass lies (x10: 0.1, x50, x90), per row of
    cumulative passing q (passing()), log-linear between edges; nan below the finest edge."""
    q = np.atleast_2d(q)
    logs = np.log(classes.edges)
    out = np.full(len(q), np.nan)
    for r, row in enumerate(q):
        asc_q, asc_x = row[::-1], logs[::-1]  # finest first: passing rises with size
        if asc_q[0] <= share <= asc_q[-1]:
            out[r] = math.exp(np.interp(share, asc_q, asc_x))
    return out


def feed(classes: SizeClasses, x50_m: float, spread: float = 0.5) -> np.ndarray:
    """A log-normal feed by mass (median x50_m, σ of ln x `spread`) over the classes,
    normalised to 1 (what lies above the top edge joins the coarsest class): a start for
    predictions when no measured feed is given."""
    from scipy.stats import norm

    if not (x50_m > 0 and spread > 0):
        raise ValueError("feed x50 and spread must be > 0")
    below = norm.cdf((np.log(classes.edges) - math.log(x50_m)) / spread)  # share below each edge
    m = np.append(below[:-1] - below[1:], below[-1])
    m[0] += 1.0 - below[0]
    return m / m.sum()
