"""Figures of a live run over a sliding window of simulated time, from the run's stream
(taimill.store.sinks), computed by the run summary's own `Summary` so the live numbers
mean what the run summary means (docs/outputs.md).

The energy ledger is cumulative from t = 0; a window (or a recording started mid-run)
counts drive work and dissipation from its own first row (`rebased`), so its energy
balance error is relative to the drive work done inside it.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from taimill.analysis.rungeometry import RunGeometry
from taimill.analysis.summary import Summary
from taimill.schema import MECHANISM_COLUMNS
from taimill.store.sinks import Relay

CUMULATIVE = ("drive_work", "dissipated", *MECHANISM_COLUMNS)


def rebased(block: dict, origin: dict) -> dict:
    """Energy rows with the cumulative columns counted from `origin` (a row, J)."""
    return block | {k: block[k] - origin[k] for k in CUMULATIVE}


class Rebased(Relay):
    """Passes the stream to `sink` with drive work and dissipation counted from the
    first energy row it sees."""

    def __init__(self, sink):
        super().__init__(sink)
        self.origin = None

    def energy(self, block):
        if self.origin is None:
            self.origin = {k: float(block[k][0]) for k in CUMULATIVE}
        self.sink.energy(rebased(block, self.origin))


class WindowStats:
    """Sink keeping the last `seconds` of simulated time of the stream; `result()` gives
    the summary keys (docs/outputs.md) over that window from a `Summary` without the
    run-only accumulators (all-contacts twin, g(r), wall map, single-ball hit)."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.geom = None
        self._frames: deque = deque()
        self._events: deque = deque()
        self._energy: deque = deque()

    def start(self, config, n_balls, radii):
        self.geom = RunGeometry.from_config(config, radii)
        self.n_balls, self.radii = n_balls, np.asarray(radii)

    def frames(self, block):
        self._keep(self._frames, block, block["time"][-1])

    def events(self, block):
        self._keep(self._events, block, float(np.max(block["t_start"] + block["duration"])))

    def energy(self, block):
        self._keep(self._energy, block, block["time"][-1])

    def finish(self, summary, status):
        pass

    def _keep(self, blocks: deque, block: dict, t_last: float):
        blocks.append((t_last, block))
        horizon = t_last - self.seconds
        for table in (self._frames, self._events, self._energy):
            while table and table[0][0] < horizon:
                table.popleft()

    @staticmethod
    def _table(blocks: deque, t0: float, column: str) -> dict | None:
        """The retained blocks as one table, rows with column ≥ t0 (one call per
        accumulator: their cost is per block, not per row)."""
        if not blocks:
            return None
        keys = blocks[0][1].keys()
        table = {k: np.concatenate([b[k] for _, b in blocks]) for k in keys}
        keep = table[column] >= t0
        return {k: v[keep] for k, v in table.items()} if keep.any() else None

    def result(self, regime: bool = True) -> dict | None:
        """Summary keys over [end - seconds, end] (end: the last energy row, s), or None
        before the window holds two energy rows. regime=False leaves out the regime
        (three quarters of the cost: contacts of every feature frame)."""
        energy = self._table(self._energy, -math.inf, "time")
        if energy is None or self.geom is None or len(energy["time"]) < 2:
            return None
        t1 = float(energy["time"][-1])
        t0 = max(t1 - self.seconds, float(energy["time"][0]))
        summary = Summary(self.geom, self.n_balls, self.radii, t0, whole_run=False, regime=regime)
        events = self._table(self._events, t0, "t_start")
        if events is not None:
            summary.events(events)
        frames = self._table(self._frames, t0, "time") if regime else None
        if frames is not None:
            summary.frames(frames)
        energy = {k: v[energy["time"] >= t0] for k, v in energy.items()}
        summary.energy(rebased(energy, {k: energy[k][0] for k in CUMULATIVE}))
        return summary.result(t1)
