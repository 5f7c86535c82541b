"""The simulation side of the app, run by one Textual thread worker: advances the
LiveMill in ≈ 10 ms kernel launches (a running kernel holds the GIL) and reports only
through messages (`post`): a frame after every stretch of running (paced to
FRAMES_PER_S, see `pace`), the window
readouts every READOUT_PERIOD. The UI thread talks to it through `paused` and `steps`
and changes the mill through the LiveMill's locked setters.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque

from taimill.errors import SimulationUnstable
from taimill.tui.history import SERIES
from taimill.tui.messages import FrameReady, ReadoutsReady, SimFault
from taimill.tui.window import WindowStats

FRAMES_PER_S = 13.0  # frames posted per wall s: the simulation runs between them
# for as long as that allows. Fixed 45 ms stretches drew 16 frames/s at 3.8x real time
# on the Xeon machine (13-14 frames/s on a slower one); paced to 13 frames/s, 4.1x.
FIRST_STRETCH = 0.045  # wall s of the first stretch, before a cycle is measured
STRETCH_BOUNDS = (0.02, 0.2)  # wall s: the pacing stays within these
YIELD = 0.006  # wall s the worker sleeps after each frame: the GIL to the UI thread to draw it
READOUT_PERIOD = 1.0  # wall s between window summaries (≈ 15 ms of NumPy, 60 with the regime)
REGIME_EVERY = 3  # readouts per regime classification (the dearest figure)
HISTORY = 120  # readouts kept for the sparklines (two minutes)


class SimulationLoop:
    """mill: a LiveMill built in the main thread; window: s of simulated time the
    readouts cover."""

    def __init__(self, mill, window: float, paused: bool = False):
        self.mill, self.window_seconds = mill, window
        self.paused = paused
        self.steps: deque = deque()  # step requests from the UI (deque ops are atomic)
        self.history = {k: deque(maxlen=HISTORY) for k in ("sim_seconds", *SERIES)}  # s, window ends
        self.stopped = threading.Event()  #: clear while run() may be running
        self.stopped.set()
        self.window = None
        self._regime: dict = {}
        self.new_window()

    def new_window(self):
        """A fresh readout window (after a reset or rebuild: time starts over)."""
        if self.window is not None:
            self.mill.remove_sink(self.window)
        self.window = WindowStats(self.window_seconds)
        self.mill.add_sink(self.window)
        for h in self.history.values():
            h.clear()

    def run(self, post, cancelled):
        """The worker's body: post(message) is thread-safe, cancelled() ends the loop.
        The caller clears `stopped` before starting the thread."""
        try:
            self._run(post, cancelled)
        finally:
            self.stopped.set()

    def _run(self, post, cancelled):
        mill = self.mill
        last_readout, readouts = 0.0, 0
        rate = deque(maxlen=40)  # (wall, sim) samples for the real-time factor
        stretch, last_frame, mean_cycle = FIRST_STRETCH, None, None
        while not cancelled():
            stepped = False
            try:
                if self.steps:
                    self.steps.popleft()
                    mill.advance(steps=mill.spec.frame_every)
                    stepped = True
                elif self.paused:
                    rate.clear()
                    last_frame = None  # a pause is not a cycle to pace by
                    time.sleep(0.02)
                    continue
                else:
                    mill.advance(wall_budget=stretch)
            except SimulationUnstable as err:
                self.paused = True
                post(SimFault(str(err)))
                continue
            now = time.perf_counter()
            if not stepped:
                stretch, mean_cycle = pace(stretch, now - last_frame if last_frame is not None else None, mean_cycle)
            last_frame = now
            rate.append((now, mill.time))
            post(self.frame(realtime(rate)))
            time.sleep(YIELD)
            if stepped or now - last_readout >= READOUT_PERIOD:
                last_readout, readouts = now, readouts + 1
                post(self.readouts(regime=stepped or readouts % REGIME_EVERY == 0))

    def frame(self, realtime: float = math.nan) -> FrameReady:
        s = self.mill.state()
        return FrameReady(s["time"], s["position"], s["psi"], s["plate"], s["jar"], realtime)

    def readouts(self, regime: bool = True) -> ReadoutsReady:
        """The window figures; the regime, when not asked for, is the last one computed."""
        values = self.window.result(regime) or {}
        if regime:
            self._regime = {k: v for k, v in values.items() if k.startswith("regime") or k in ("wall_lag", "slip_ratio")}
        values = self._regime | values
        if "sim_seconds" in values:  # one point per readout in every series, on one time axis
            for k, h in self.history.items():
                h.append(values.get(k, math.nan))
        return ReadoutsReady(values, {k: list(h) for k, h in self.history.items()})


def pace(stretch: float, cycle: float | None, mean_cycle: float | None) -> tuple[float, float | None]:
    """(next stretch of simulation in wall s, new mean cycle) given this stretch and the
    wall time of the whole cycle it was part of (simulating, drawing, the readouts;
    None: unknown). The mean cycle is an exponential average over ≈ 10 cycles, so the
    readout's occasional long cycle does not cut the stretches after it; the stretch
    moves a fifth of the way to a mean cycle of 1/FRAMES_PER_S, within STRETCH_BOUNDS.
    The drawing costs what it costs; the simulation gets the rest of the interval."""
    if cycle is None:
        return stretch, mean_cycle
    mean_cycle = cycle if mean_cycle is None else 0.9 * mean_cycle + 0.1 * cycle
    lo, hi = STRETCH_BOUNDS
    return min(hi, max(lo, stretch + 0.2 * (1.0 / FRAMES_PER_S - mean_cycle))), mean_cycle


def realtime(rate: deque) -> float:
    """Simulated s per wall s over the (wall, sim) samples, nan under 0.2 s of them."""
    (w0, t0), (w1, t1) = rate[0], rate[-1]
    return (t1 - t0) / (w1 - w0) if w1 - w0 > 0.2 and t1 >= t0 else math.nan
