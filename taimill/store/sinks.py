"""The one stream a simulation emits, and the sinks that consume it.

A run produces three tables, appended in blocks while it runs (sinks, not special cases: zarr,
rerun and the TUI consume the same stream through this one interface):

- frames   — `time` (F,) s; `position`, `velocity` (F, N, 3) m, m/s in the jar frame;
             `spin` (F, N, 3) rad/s, absolute spin in jar-frame components.
- events   — one row per collision event (docs/outputs.md), columns listed in `EVENT_COLUMNS`.
- energy   — one row per frame: `time` and the cumulative energy ledger (J), columns in
             `ENERGY_COLUMNS`.

Sinks see NumPy arrays and plain dicts only (no taichi here: only physics/ imports it).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from taimill.schema import ENERGY_COLUMNS, EVENT_COLUMNS, FRAME_FIELDS



def empty_events() -> dict[str, np.ndarray]:
    return {k: np.zeros(0, dtype=v[0]) for k, v in EVENT_COLUMNS.items()}


class Sink(Protocol):
    """What every consumer of a run implements. Calls come in this order:
    `start` once, then any interleaving of `frames`/`events`/`energy`, then `finish`
    once (also after a failure, with `status` saying what happened)."""

    def start(self, config: dict, n_balls: int, radii: np.ndarray) -> None: ...

    def frames(self, block: dict[str, np.ndarray]) -> None: ...

    def events(self, block: dict[str, np.ndarray]) -> None: ...

    def energy(self, block: dict[str, np.ndarray]) -> None: ...

    def finish(self, summary: dict, status: str) -> None: ...


class NullSink:
    """Discards everything (tests, benchmarks)."""

    def start(self, config, n_balls, radii):
        pass

    def frames(self, block):
        pass

    def events(self, block):
        pass

    def energy(self, block):
        pass

    def finish(self, summary, status):
        pass


class MemorySink:
    """Keeps everything in memory, concatenated on demand (tests, analysis of short runs)."""

    def __init__(self):
        self.config: dict | None = None
        self.summary: dict | None = None
        self.status: str | None = None
        self._frames: list[dict] = []
        self._events: list[dict] = []
        self._energy: list[dict] = []
        self.last_spectra = None  #: the runner's spectra at its last drain

    def start(self, config, n_balls, radii):
        self.config = config
        self.radii = np.asarray(radii)

    def frames(self, block):
        self._frames.append(block)

    def events(self, block):
        self._events.append(block)

    def energy(self, block):
        self._energy.append(block)

    def spectra(self, spectra):
        self.last_spectra = spectra

    def finish(self, summary, status):
        self.summary, self.status = summary, status

    @staticmethod
    def _cat(blocks, names):
        if not blocks:
            return None
        return {k: np.concatenate([b[k] for b in blocks]) for k in names}

    @property
    def frame_table(self):
        return self._cat(self._frames, FRAME_FIELDS)

    @property
    def event_table(self):
        return self._cat(self._events, EVENT_COLUMNS) or empty_events()

    @property
    def energy_table(self):
        return self._cat(self._energy, ENERGY_COLUMNS)


class Relay:
    """Passes the stream to `self.sink` unchanged; a wrapper overrides only the calls it
    changes."""

    def __init__(self, sink: Sink):
        self.sink = sink

    def start(self, config, n_balls, radii):
        self.sink.start(config, n_balls, radii)

    def frames(self, block):
        self.sink.frames(block)

    def events(self, block):
        self.sink.events(block)

    def energy(self, block):
        self.sink.energy(block)

    def spectra(self, spectra):
        if hasattr(self.sink, "spectra"):
            self.sink.spectra(spectra)

    def finish(self, summary, status):
        self.sink.finish(summary, status)


class FanOut:
    """Sends the stream to several sinks."""

    def __init__(self, *sinks: Sink):
        self.sinks = sinks

    def start(self, config, n_balls, radii):
        for s in self.sinks:
            s.start(config, n_balls, radii)

    def frames(self, block):
        for s in self.sinks:
            s.frames(block)

    def events(self, block):
        for s in self.sinks:
            s.events(block)

    def energy(self, block):
        for s in self.sinks:
            s.energy(block)

    def spectra(self, spectra):
        for s in self.sinks:
            if hasattr(s, "spectra"):
                s.spectra(spectra)

    def finish(self, summary, status):
        for s in self.sinks:
            s.finish(summary, status)
