"""Run summary (SPEC §5, §9) accumulated from the stream, as a sink: event-based stress
energy statistics over the analysis window, dissipated power, the energy balance,
g(r) and its randomness index, and a provisional motion regime.

NumPy only; running sums so a 24 s run never holds its event table in memory.
"""

from __future__ import annotations

import math

import numpy as np

G_BINS = 20  # radial bins of the cylindrical distribution function


class SummarySink:
    """Sink computing the SPEC §9 summary keys.

    analysis_start, duration: s. jar_radius, ball_radius: m (g(r) spans the radii a
    ball centre can reach in a cylinder, 0 … R - r)."""

    def __init__(self, analysis_start: float, duration: float, jar_radius: float, ball_radius: float):
        self.t0, self.duration = analysis_start, duration
        self.r_max = jar_radius - ball_radius
        self.ball_radius = ball_radius
        self.counts = np.zeros(2, dtype=np.int64)  # ball-ball, ball-wall
        self.se_n = np.zeros(2)
        self.se_t = np.zeros(2)
        self.events_total = 0
        self.hist = np.zeros(G_BINS)
        self.wall_frames = 0
        self.ball_frames = 0
        self.ledger_first = None
        self.ledger_window = None
        self.ledger_last = None
        self.worst_balance = 0.0
        self.drive_scale = 0.0

    def start(self, config, n_balls, radii):
        pass

    def events(self, block):
        self.events_total += len(block["t_start"])
        sel = block["t_start"] >= self.t0
        kind = block["kind"][sel].astype(int)
        np.add.at(self.counts, kind, 1)
        np.add.at(self.se_n, kind, block["se_n"][sel])
        np.add.at(self.se_t, kind, block["se_t"][sel])

    def frames(self, block):
        sel = block["time"] >= self.t0
        x = block["position"][sel]
        rho = np.hypot(x[..., 0], x[..., 1]).ravel()
        self.hist += np.histogram(rho, bins=G_BINS, range=(0.0, self.r_max))[0]
        self.wall_frames += int(np.sum(rho > self.r_max - 0.05 * self.ball_radius))
        self.ball_frames += rho.size

    def energy(self, block):
        rows = np.column_stack([block[k] for k in ("time", "kinetic", "potential", "elastic", "drive_work", "dissipated")])
        if self.ledger_first is None:
            self.ledger_first = rows[0]
        if self.ledger_window is None and (rows[:, 0] >= self.t0).any():
            self.ledger_window = rows[np.argmax(rows[:, 0] >= self.t0)]
        self.ledger_last = rows[-1]
        for row in rows:
            self.worst_balance = max(self.worst_balance, abs(self._imbalance(row)))
        self.drive_scale = max(self.drive_scale, float(np.abs(rows[:, 4]).max()))

    def _imbalance(self, row):
        """(E_kin + E_pot + E_el + dissipated) - (E_0 + drive work), J."""
        e0 = self.ledger_first
        return (row[1] + row[2] + row[3] + row[5]) - (e0[1] + e0[2] + e0[3] + row[4])

    def finish(self, summary, status):
        pass

    def cylindrical_distribution(self):
        """g(r) (eq 3.9) on G_BINS shells, normalised so a uniform density gives 1."""
        edges = np.linspace(0.0, self.r_max, G_BINS + 1)
        shell = edges[1:] ** 2 - edges[:-1] ** 2
        total = self.hist.sum()
        if total == 0:
            return edges, np.full(G_BINS, np.nan)
        return edges, self.hist / total / (shell / self.r_max**2)

    def result(self, sim_seconds: float, wall_seconds: float) -> dict:
        tau = max(sim_seconds - self.t0, 0.0)
        n_bb, n_bw = (int(c) for c in self.counts)
        n = n_bb + n_bw
        se_n, se_t = float(self.se_n.sum()), float(self.se_t.sum())
        last, win = self.ledger_last, self.ledger_window
        dissipated_power = (last[5] - win[5]) / tau if (tau > 0 and win is not None) else math.nan
        balance = abs(self._imbalance(last)) / self.drive_scale if self.drive_scale > 0 else math.nan
        _, g = self.cylindrical_distribution()
        var = float(np.var(g))
        wall_fraction = self.wall_frames / self.ball_frames if self.ball_frames else math.nan
        per = (lambda s: s / tau if tau > 0 else math.nan)
        mean = (lambda s: s / n if n else math.nan)
        return {
            "events": n,
            "events_ball_ball": n_bb,
            "events_ball_wall": n_bw,
            "events_total": self.events_total,
            "impact_power": per(se_n + se_t),
            "impact_power_normal": per(se_n),
            "impact_power_tangential": per(se_t),
            "mean_se": mean(se_n + se_t),
            "mean_se_normal": mean(se_n),
            "mean_se_tangential": mean(se_t),
            "normal_fraction": se_n / (se_n + se_t) if n else math.nan,
            "collision_rate": per(n),
            "dissipated_power": float(dissipated_power),
            "energy_balance_error": float(balance),
            "energy_balance_worst": self.worst_balance / self.drive_scale if self.drive_scale > 0 else math.nan,
            "drive_work": float(last[4]) if last is not None else math.nan,
            "randomness_index": 1.0 / var if var > 0 else math.inf,
            "side_wall_fraction": wall_fraction,
            "regime": provisional_regime(wall_fraction),
            "analysis_window": [self.t0, sim_seconds],
            "sim_seconds": sim_seconds,
            "wall_seconds": wall_seconds,
            "realtime_factor": sim_seconds / wall_seconds if wall_seconds > 0 else math.nan,
        }


def provisional_regime(side_wall_fraction: float) -> str:
    """Rolling when balls stay on the side wall (> 85 % of ball-frames within 5 % of a
    radius of it); otherwise 'cataracting/cascading' (told apart by the analysis
    module's classifier, issue 4)."""
    if not math.isfinite(side_wall_fraction):
        return "unknown"
    return "rolling" if side_wall_fraction > 0.85 else "cascading/cataracting"
