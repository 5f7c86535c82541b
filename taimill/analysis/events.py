"""Stress-energy statistics from the event table: the exact, event-based estimator
(docs/outputs.md; default). One term per collision event, taken at its onset.

    SE = ½ m_e u̇²                       per event, normal and tangential parts
    E_I/τ = Σ SE / τ                    impact power (thesis eq 3.8, summed over events)
    E_I/(τ V)                           impact power density (eq 4.1)
    ⟨SE⟩ = Σ SE / n                     average stress energy (thesis eq 3.10)

each split ball–ball / ball–wall and normal / tangential. An optional threshold on
the onset normal speed drops micro-contact chatter (a resting ball re-touching at
mm/s). Accumulates block by block, so a 24 s run never needs its table in memory.
"""

from __future__ import annotations

import math

import numpy as np

KINDS = ("ball_ball", "ball_wall")
# log bins of the onset speeds (m/s) and stress energies (J) for the distributions
SPEED_BINS = np.logspace(-5, 1.5, 66)
ENERGY_BINS = np.logspace(-12, 0, 73)


class EventStats:
    """Event estimator over the window t_start ∈ [t0, t1), keeping events with onset
    normal speed u̇_n ≥ min_un (m/s); min_un = 0 keeps every event of the window,
    also one whose stored onset u̇_n is a rounding error below zero (a contact that
    opens while its surfaces barely approach: −4·10⁻⁷ m/s, say)."""

    def __init__(self, t0: float = 0.0, t1: float = math.inf, min_un: float = 0.0):
        self.t0, self.t1, self.min_un = t0, t1, min_un
        self.count = np.zeros(2, dtype=np.int64)  # per kind
        self.se_n = np.zeros(2)
        self.se_t = np.zeros(2)
        self.dropped = 0  # in the window but below min_un
        self.hist_un = np.zeros((2, len(SPEED_BINS) - 1), dtype=np.int64)
        self.hist_ut = np.zeros((2, len(SPEED_BINS) - 1), dtype=np.int64)
        self.hist_se_n = np.zeros((2, len(ENERGY_BINS) - 1), dtype=np.int64)
        self.hist_se_t = np.zeros((2, len(ENERGY_BINS) - 1), dtype=np.int64)
        # energy dissipated per event by the normal damper and by friction (J)
        self.hist_diss_n = np.zeros((2, len(ENERGY_BINS) - 1), dtype=np.int64)
        self.hist_diss_t = np.zeros((2, len(ENERGY_BINS) - 1), dtype=np.int64)

    def add(self, block: dict) -> None:
        t = block["t_start"]
        window = (t >= self.t0) & (t < self.t1)
        keep = window & (block["un"] >= self.min_un) if self.min_un > 0 else window
        self.dropped += int(window.sum() - keep.sum())
        kind = block["kind"][keep].astype(np.intp)
        np.add.at(self.count, kind, 1)
        np.add.at(self.se_n, kind, block["se_n"][keep])
        np.add.at(self.se_t, kind, block["se_t"][keep])
        for k in (0, 1):
            sel = kind == k
            for hist, col, bins in ((self.hist_un, "un", SPEED_BINS), (self.hist_ut, "ut", SPEED_BINS),
                                    (self.hist_se_n, "se_n", ENERGY_BINS), (self.hist_se_t, "se_t", ENERGY_BINS),
                                    (self.hist_diss_n, "dissipated_normal", ENERGY_BINS),
                                    (self.hist_diss_t, "dissipated_friction", ENERGY_BINS)):
                # out-of-range values (u̇ = 0, say) go to the end bins: every event counts
                values = np.clip(block[col][keep][sel], bins[0], bins[-1])
                hist[k] += np.histogram(values, bins=bins)[0]

    def result(self, tau: float, volume: float | None = None, n_balls: int | None = None) -> dict:
        """Summary over a window of length tau (s); volume (m³) adds the densities."""
        return estimator_keys("event", self.min_un, self.dropped, self.count, self.se_n, self.se_t, tau, volume, n_balls)


def estimator_keys(estimator: str, min_un: float, dropped: int, count, se_n, se_t, tau: float,
                   volume: float | None = None, n_balls: int | None = None) -> dict:
    """The event estimator's keys from its sums per kind (KINDS order): events, normal and
    tangential stress energy (J), over a window of tau s; stress events when min_un > 0
    (m/s), `dropped` events below it; volume (m³) adds the densities."""
    name = f"stress events (onset u̇n ≥ {min_un * 1e3:g} mm/s)" if min_un > 0 else "all contacts"
    out = {"estimator": estimator, "counted": name, "min_un": min_un, "events_below_threshold": int(dropped)}
    per = (lambda s: s / tau if tau > 0 else math.nan)
    n = int(np.sum(count))
    out.update(_split("", n, float(np.sum(se_n)), float(np.sum(se_t)), per))
    for k, kind in enumerate(KINDS):
        out.update(_split(f"_{kind}", int(count[k]), float(se_n[k]), float(se_t[k]), per))
    out["events_ball_ball"], out["events_ball_wall"] = int(count[0]), int(count[1])
    out["collision_rate"] = per(n)
    if n_balls:
        out["collision_rate_per_ball"] = per(n) / n_balls
    if volume:
        out["impact_power_density"] = out["impact_power"] / volume
        out["mean_se_density"] = out["mean_se"] / volume
    return out


def _split(suffix: str, n: int, se_n: float, se_t: float, per) -> dict:
    mean = (lambda s: s / n if n else math.nan)
    return {
        f"events{suffix}": n,
        f"impact_power{suffix}": per(se_n + se_t),
        f"impact_power_normal{suffix}": per(se_n),
        f"impact_power_tangential{suffix}": per(se_t),
        f"mean_se{suffix}": mean(se_n + se_t),
        f"mean_se_normal{suffix}": mean(se_n),
        f"mean_se_tangential{suffix}": mean(se_t),
        f"normal_fraction{suffix}": se_n / (se_n + se_t) if (se_n + se_t) > 0 else math.nan,
    }


def log_pdf(counts: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """Probability density per unit of log10(value) on log bins (integrates to 1 over
    log10 of the values), as the thesis' velocity distributions (Figs 4.6, 4.15)."""
    total = counts.sum()
    width = np.diff(np.log10(bins))
    return counts / total / width if total else np.zeros(len(counts))
