"""Run summary (docs/outputs.md) accumulated from the stream, as a sink: the event-based
stress-energy statistics over the analysis window, dissipated power, the energy
balance, g(r) and its randomness index, the motion regime, the wear hot spot and the
analytic landmarks (critical ratio, single-ball hit energy).

NumPy only; running sums so a 24 s run never holds its tables in memory. The same
accumulators (taimill.analysis) analyse stored runs afterwards.
"""

from __future__ import annotations

import math

import numpy as np

from taimill.analysis.events import EventStats
from taimill.analysis.regime import RegimeFeatures
from taimill.analysis.rungeometry import RunGeometry
from taimill.analysis.spatial import RadialDensity, WallMap
from taimill.analysis.theory import critical_ratio, single_ball_hit
from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.schema import ENERGY_COLUMNS, MECHANISM_CLASSES, MECHANISM_COLUMNS, MECHANISM_KINDS, MECHANISM_PARTS


class EnergyLedger:
    """Energy balance from the cumulative ledger rows: E_kin + E_pot + E_el + dissipated
    must equal E_0 + drive work; errors relative to the largest |drive work|.

    Everything is counted from the first row seen: a stream that starts mid-run (a
    recording begun in the TUI at t = 20 s) balances from its own start, where the
    ledger's dissipated energy and drive work are already large."""

    def __init__(self, t0: float):
        self.t0 = t0
        self.first = self.window = self.last = None
        self.worst = 0.0
        self.scale = 0.0

    def add(self, block: dict) -> None:
        cols = [np.asarray(block[k]) for k in ENERGY_COLUMNS if k in block]
        if not len(cols[0]):
            return
        row = lambda i: np.array([c[i] for c in cols])  # noqa: E731  one ledger row, every column
        if self.first is None:
            self.first = row(0)
        if self.window is None and (cols[0] >= self.t0).any():
            self.window = row(int(np.argmax(cols[0] >= self.t0)))
        self.last = row(-1)
        # the imbalance and scale need five columns: not a copy of all of them per row
        rows = np.column_stack(cols[:6])
        self.worst = max(self.worst, float(np.abs(self.imbalance(rows)).max()))
        self.scale = max(self.scale, float(np.abs(rows[:, 4] - self.first[4]).max()))

    def imbalance(self, rows):
        """(E_kin + E_pot + E_el + dissipated) - (E_0 + drive work), J, per row, with
        E_0, dissipated and drive work counted from the first row (for a stream that
        starts at t = 0 the ledger's first dissipated energy and work are exactly 0)."""
        e0 = self.first
        return ((rows[..., 1] + rows[..., 2] + rows[..., 3] + rows[..., 5])
                - (e0[1] + e0[2] + e0[3] + e0[5] + (rows[..., 4] - e0[4])))

    def result(self, tau: float) -> dict:
        if self.last is None:
            return {"dissipated_power": math.nan, "energy_balance_error": math.nan,
                    "energy_balance_worst": math.nan, "drive_work": math.nan}
        diss = (self.last[5] - self.window[5]) / tau if (tau > 0 and self.window is not None) else math.nan
        rel = (lambda x: x / self.scale if self.scale > 0 else math.nan)
        out = {"dissipated_power": float(diss), "energy_balance_error": float(rel(abs(self.imbalance(self.last)))),
               "energy_balance_worst": float(rel(self.worst)), "drive_work": float(self.last[4] - self.first[4])}
        if len(self.last) == len(ENERGY_COLUMNS) and self.window is not None and tau > 0:
            first = len(ENERGY_COLUMNS) - len(MECHANISM_COLUMNS)
            out.update(mechanism_powers((self.last[first:] - self.window[first:]) / tau))
        return out


def mechanism_powers(power: np.ndarray) -> dict:
    """Summary keys of the dissipated power by mechanism (W), from one value per
    schema MECHANISM_COLUMNS entry: the nested table, its sums by class, part and kind,
    and the largest single mechanism (`main_sink`) with its share."""
    p = np.asarray(power, dtype=float).reshape(len(MECHANISM_KINDS), len(MECHANISM_CLASSES), len(MECHANISM_PARTS))
    out = {"dissipation_by_mechanism": {k: {c: {q: float(p[i, j, l]) for l, q in enumerate(MECHANISM_PARTS)}
                                            for j, c in enumerate(MECHANISM_CLASSES)}
                                        for i, k in enumerate(MECHANISM_KINDS)}}
    out.update({f"dissipated_power_{c}": float(p[:, j].sum()) for j, c in enumerate(MECHANISM_CLASSES)})
    out.update({f"dissipated_power_{q}": float(p[..., l].sum()) for l, q in enumerate(MECHANISM_PARTS)})
    out.update({f"dissipated_power_{k}": float(p[i].sum()) for i, k in enumerate(MECHANISM_KINDS)})
    total = float(p.sum())
    i, j, l = np.unravel_index(int(np.argmax(p)), p.shape)
    where = "ball-ball contacts" if MECHANISM_KINDS[i] == "ball_ball" else f"contacts with the {MECHANISM_KINDS[i]}"
    out["main_sink"] = {"mechanism": f"{MECHANISM_PARTS[l]} in {MECHANISM_CLASSES[j]} {where}",
                        "power": float(p[i, j, l]), "share": float(p[i, j, l] / total) if total > 0 else math.nan}
    return out


class SummarySink:
    """Sink computing the summary keys (docs/outputs.md) over the analysis window [t0, end).

    analysis_start, duration: s. The geometry comes from the config given to start();
    the jar and ball radii arguments are accepted for older callers and not needed.
    min_un: m/s, the headline statistics count stress events, events with at least
    this onset normal speed (model/mechanisms.py); `all_contacts` counts every event."""

    def __init__(self, analysis_start: float, duration: float, jar_radius=None, ball_radius=None, *,
                 min_un: float = STRESS_MIN_UN):
        self.t0, self.duration, self.min_un = analysis_start, duration, min_un
        self.events_total = 0
        self.ledger = EnergyLedger(analysis_start)
        self.stats = EventStats(analysis_start, min_un=min_un)
        self.all_contacts = EventStats(analysis_start)

    def start(self, config, n_balls, radii):
        self.geom = RunGeometry.from_config(config, radii)
        self.n_balls = n_balls
        self.density = RadialDensity(self.geom, self.t0)
        self.regime = RegimeFeatures(self.geom, radii, self.t0)
        self.wall = WallMap(self.geom, self.t0)

    def events(self, block):
        self.events_total += len(block["t_start"])
        self.stats.add(block)
        self.all_contacts.add(block)
        self.regime.events(block)
        self.wall.add(block)

    def frames(self, block):
        self.density.add(block)
        self.regime.frames(block)

    def energy(self, block):
        self.ledger.add(block)

    def finish(self, summary, status):
        pass

    def result(self, sim_seconds: float, wall_seconds: float) -> dict:
        tau = max(sim_seconds - self.t0, 0.0)
        g = self.geom
        out = self.stats.result(tau, g.volume, self.n_balls)
        out["all_contacts"] = self.all_contacts.result(tau, g.volume, self.n_balls)
        out["events_total"] = self.events_total
        out.update(self.ledger.result(tau))
        out["randomness_index"] = self.density.randomness_index
        regime = self.regime.result()
        out.update(regime)
        out["side_wall_fraction"] = regime["regime_criteria"].get("wall_fraction", math.nan)
        out["wear_hot_spot"] = self.wall.hot_spot(tau) if tau > 0 else {}
        out["critical_ratio"] = critical_ratio(g.plate_radius, g.jar_radius, g.ball_radius)
        hit = single_ball_hit(g.plate_radius, g.jar_radius, g.ball_radius, g.plate.end, g.ratio, g.ball_mass)
        out["single_ball_se"] = hit["se"]
        out.update(analysis_window=[self.t0, sim_seconds], sim_seconds=sim_seconds, wall_seconds=wall_seconds,
                   realtime_factor=sim_seconds / wall_seconds if wall_seconds > 0 else math.nan)
        return out
