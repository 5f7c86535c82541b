"""What a run's energy spectra say (taimill.model.spectra holds the spectra and their
bins; docs/outcome.md): rates and energies above a threshold, mean, median and P90,
per energy measure, contact kind and class.

Selections: `measure` one of spectra.MEASURES; `kind` "ball_ball", "ball_wall" or None
(both); `stress_only` True counts stress events only (onset u̇n ≥ the threshold), False
every contact. Within a bin the events are taken as spread evenly in log E: a
threshold or a quantile between two edges is interpolated so; on an edge it is exact.
"""

from __future__ import annotations

import math

import numpy as np

from taimill.model.spectra import EDGES, KINDS, MEASURES, Spectra

# J: the thresholds the summary reports the rate above (1 µJ … 1 J, a decade apart)
SUMMARY_THRESHOLDS = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)
# log10 J of each bin's ends; the two open bins are taken one bin width wide
_WIDTH = math.log10(EDGES[1] / EDGES[0])
LOG_LO = np.concatenate([[math.log10(EDGES[0]) - _WIDTH], np.log10(EDGES)])
LOG_HI = np.concatenate([np.log10(EDGES), [math.log10(EDGES[-1]) + _WIDTH]])


def selected(sp: Spectra, measure: str, kind: str | None = None, stress_only: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(events, energy in J) per bin of one selection."""
    q = MEASURES.index(measure)
    kinds = [KINDS.index(kind)] if kind else [0, 1]
    classes = [0] if stress_only else [0, 1]
    count = sp.count[np.ix_(kinds, classes, [q])].sum(axis=(0, 1, 2))
    energy = sp.energy()[np.ix_(kinds, classes, [q])].sum(axis=(0, 1, 2))
    return count, energy


def _fraction_above(threshold: float) -> np.ndarray:
    """Per bin, the share of its log-width at or above `threshold` (J)."""
    x = math.log10(threshold) if threshold > 0 else -math.inf
    return np.clip((LOG_HI - x) / (LOG_HI - LOG_LO), 0.0, 1.0)


def rate_above(sp: Spectra, threshold: float, measure: str, kind: str | None = None, stress_only: bool = True) -> float:
    """Events per second whose `measure` is at least `threshold` (J)."""
    count, _ = selected(sp, measure, kind, stress_only)
    return float((count * _fraction_above(threshold)).sum()) / sp.seconds if sp.seconds > 0 else math.nan


def power_above(sp: Spectra, threshold: float, measure: str, kind: str | None = None, stress_only: bool = True) -> float:
    """W: energy per second in events whose `measure` is at least `threshold` (J)."""
    _, energy = selected(sp, measure, kind, stress_only)
    return float((energy * _fraction_above(threshold)).sum()) / sp.seconds if sp.seconds > 0 else math.nan


def quantile(sp: Spectra, p: float, measure: str, kind: str | None = None, stress_only: bool = True) -> float:
    """The energy (J) below which a share p of the selected events lies (NaN: none)."""
    count, _ = selected(sp, measure, kind, stress_only)
    total = count.sum()
    if total == 0:
        return math.nan
    cum = np.cumsum(count) / total
    k = int(np.searchsorted(cum, p, side="left"))
    k = min(k, len(count) - 1)
    before = cum[k - 1] if k else 0.0
    share = (p - before) / (cum[k] - before) if cum[k] > before else 1.0
    return 10 ** (LOG_LO[k] + share * (LOG_HI[k] - LOG_LO[k]))


def mean(sp: Spectra, measure: str, kind: str | None = None, stress_only: bool = True) -> float:
    count, energy = selected(sp, measure, kind, stress_only)
    n = count.sum()
    return float(energy.sum() / n) if n else math.nan


def summary(sp: Spectra) -> dict:
    """The summary's `spectra` key: the window (s), the class threshold (m/s) and per
    measure, over stress events: events, energy (J), mean, median and P90 (J), and the
    rate of events (1/s) at or above each SUMMARY_THRESHOLDS energy (J)."""
    out: dict = {"window": [sp.start, sp.end], "stress_un": sp.stress_un}
    for m in MEASURES:
        count, energy = selected(sp, m)
        out[m] = {"events": int(count.sum()), "energy": float(energy.sum()), "mean": mean(sp, m),
                  "median": quantile(sp, 0.5, m), "p90": quantile(sp, 0.9, m),
                  "rate_above": {f"{e:g}": rate_above(sp, e, m) for e in SUMMARY_THRESHOLDS}}
    return out


def event_keys(sp: Spectra, tau: float, volume: float | None = None, n_balls: int | None = None,
               stress_only: bool = True) -> dict:
    """The event estimator's keys (taimill.analysis.events.EventStats.result) from the
    spectra over a window of tau s: counts and the kinematic stress energies, per kind,
    exact to the fixed point's 2⁻²⁴ per event. For a store that kept no event rows."""
    from taimill.analysis.events import KINDS as EVENT_KINDS, _split

    classes = [0] if stress_only else [0, 1]
    count = sp.count[:, classes, MEASURES.index("se_normal")].sum(axis=(1, 2))
    energy = sp.energy()
    se_n = energy[:, classes, MEASURES.index("se_normal")].sum(axis=(1, 2))
    se_t = energy[:, classes, MEASURES.index("se_tangential")].sum(axis=(1, 2))
    per = (lambda s: s / tau if tau > 0 else math.nan)
    name = f"stress events (onset u̇n ≥ {sp.stress_un * 1e3:g} mm/s)" if stress_only else "all contacts"
    out = {"estimator": "event (from the energy spectra)", "counted": name, "min_un": sp.stress_un if stress_only else 0.0,
           "events_below_threshold": int(sp.count[:, 1, 0].sum()) if stress_only else 0}
    n = int(count.sum())
    out.update(_split("", n, float(se_n.sum()), float(se_t.sum()), per))
    for k, kind in enumerate(EVENT_KINDS):
        out.update(_split(f"_{kind}", int(count[k]), float(se_n[k]), float(se_t[k]), per))
    out["events_ball_ball"], out["events_ball_wall"] = int(count[0]), int(count[1])
    out["collision_rate"] = per(n)
    if n_balls:
        out["collision_rate_per_ball"] = per(n) / n_balls
    if volume:
        out["impact_power_density"] = out["impact_power"] / volume
        out["mean_se_density"] = out["mean_se"] / volume
    return out
