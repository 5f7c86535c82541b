"""Sliding-window statistics of a run for the recording (pure NumPy functions).

The summary (taimill/analysis/summary.py) gives one number per run; a recording shows how the
same quantities evolve. At a time T each rate is taken over the window (T - W, T]:

    impact power  P_n = Σ SE_n / W, P_t = Σ SE_t / W          (thesis eq 3.8)
    mean SE       Σ (SE_n + SE_t) / n,  and its normal / tangential parts (in mJ)
    collision rate n / W                                       (events per second)
    dissipated    (D(T) - D(T - W)) / W                        (ledger, W)

with the sums over the events whose first touch t_start lies in the window. Near the
start of a recording the window is cut to what was recorded: W = min(W, T - T0).
The energy-balance error at T is the ledger's imbalance accumulated since the first
recorded row, relative to the largest drive work done since then (the summary's
definition) or, if larger, to the largest kinetic energy so far (the balls' first
fall, when the drive has done next to no work, then has a scale too).

Onset-velocity histograms use log10 bins (thesis Figs 4.6 / 4.15); speeds beyond the
range fall into the end bins.
"""

from __future__ import annotations

import numpy as np

from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.schema import MECHANISM_COLUMNS

MJ = 1e3  # mJ per J: stress energies are shown in mJ, as in the reports, the summary and the TUI
HIST_LOG10_RANGE = (-4.0, 1.0)  # log10(m/s): 0.1 mm/s to 10 m/s
HIST_BINS = 25  # 0.2 decade per bin


def window_sums(t_event: np.ndarray, values: dict[str, np.ndarray], times: np.ndarray,
                lengths: np.ndarray) -> dict[str, np.ndarray]:
    """Σ values over events with t_event in (T - L, T] for each T in `times`, L in
    `lengths` (s); the key "count" gives the number of events."""
    order = np.argsort(t_event, kind="stable")
    ts = t_event[order]
    hi = np.searchsorted(ts, times, side="right")
    lo = np.searchsorted(ts, times - lengths, side="right")
    out = {"count": (hi - lo).astype(float)}
    for k, v in values.items():
        cum = np.concatenate([[0.0], np.cumsum(v[order])])
        out[k] = cum[hi] - cum[lo]
    return out


def window_rates(events: dict[str, np.ndarray], ledger: dict[str, np.ndarray], times: np.ndarray,
                 window: float, t_origin: float) -> dict[str, np.ndarray]:
    """Series name -> values at `times` (s) over windows of `window` s cut at `t_origin`.

    events: t_start (s), un (m/s), se_n, se_t (J); the mean stress energies are in mJ (the
    unit in their names, as in the reports), the rest SI; the stress-energy series count
    stress events (onset u̇n ≥ STRESS_MIN_UN). ledger: time (s), kinetic, dissipated and
    its mechanism columns (J), covering every T - W and T (linear interpolation)."""
    length = np.minimum(window, times - t_origin)
    stress = events["un"] >= STRESS_MIN_UN
    s = window_sums(events["t_start"][stress], {"se_n": events["se_n"][stress], "se_t": events["se_t"][stress]},
                    times, length)
    persistent = sum(ledger[k] for k in MECHANISM_COLUMNS if "_persistent_" in k)

    def gain(cumulative):  # J over each window
        return np.interp(times, ledger["time"], cumulative) - np.interp(times - length, ledger["time"], cumulative)

    with np.errstate(invalid="ignore", divide="ignore"):
        dissipated = gain(ledger["dissipated"])
        return {
            "impact_power/normal": s["se_n"] / length,
            "impact_power/tangential": s["se_t"] / length,
            "mean_se_mJ/total": MJ * (s["se_n"] + s["se_t"]) / s["count"],
            "mean_se_mJ/normal": MJ * s["se_n"] / s["count"],
            "mean_se_mJ/tangential": MJ * s["se_t"] / s["count"],
            "collision_rate": s["count"] / length,
            "dissipated_power": dissipated / length,
            "dissipated_power_persistent": gain(persistent) / length,
            "kinetic_energy": np.interp(times, ledger["time"], ledger["kinetic"]),
        }


def imbalance(ledger: dict[str, np.ndarray]) -> np.ndarray:
    """(E_kin + E_pot + E_el + dissipated) - drive work per ledger row (J); its change
    between two rows is energy the bookkeeping lost or gained in between."""
    return ledger["kinetic"] + ledger["potential"] + ledger["elastic"] + ledger["dissipated"] - ledger["drive_work"]


def balance_error(rows: dict[str, np.ndarray], first: tuple[float, float], scale: float) -> tuple[np.ndarray, float]:
    """Relative energy-balance error per ledger row, and the updated scale S (J).

    |imbalance - imbalance₀| / S, S the running maximum of |drive work - W₀| and of the
    kinetic energy (index ₀: the first recorded row). NaN while S = 0."""
    bad0, work0 = first
    energy = np.maximum(np.abs(rows["drive_work"] - work0), rows["kinetic"])
    running = np.maximum.accumulate(np.concatenate([[scale], energy]))[1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.abs(imbalance(rows) - bad0) / running
    return np.where(running > 0, err, np.nan), float(running[-1]) if len(running) else scale


def hist_edges() -> np.ndarray:
    """log10 bin edges (log10 m/s) of the onset-velocity histograms."""
    return np.linspace(*HIST_LOG10_RANGE, HIST_BINS + 1)


def onset_histogram(speed: np.ndarray) -> np.ndarray:
    """Fraction of events per log10 bin of `speed` (m/s); zeros when there are none."""
    lo, hi = HIST_LOG10_RANGE
    with np.errstate(divide="ignore"):
        x = np.clip(np.log10(speed), lo, hi - 1e-9)
    counts = np.histogram(x, bins=hist_edges())[0].astype(float)
    return counts / counts.sum() if counts.sum() else counts
