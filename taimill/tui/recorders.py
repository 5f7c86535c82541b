"""Recording a live run on demand, from the current simulated time on: a rerun
recording (.rrd, `taimill.recording.sink.RerunSink`) or a zarr store (`taimill.store.writer.ZarrSink`).

Times in a recording are the mill's simulated times (a recording started at t = 12 s
starts there). Its summary covers what it received — energy balance counted from its
first row — plus the live changes made while it ran (`live_changes`: speeds and
friction are not in the config, which is the state at the start). A reset or a new
jar / ball count ends every recording (the time or the balls would change under it).
"""

from __future__ import annotations

import math
import threading
import time
from datetime import datetime
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.store.sinks import FanOut, Relay
from taimill.analysis.summary import SummarySink
from taimill.runs.live import compute
from taimill.tui.window import Rebased
from taimill.schema import with_units

SUFFIX = {"rrd": ".rrd", "zarr": ".zarr"}
BATCH_SECONDS = 1.0  # simulated s of blocks the summary takes at once (its cost is per block)


def new_path(out_dir: Path, kind: str) -> Path:
    """out_dir/taimill-YYYYmmdd-HHMMSS[-k].rrd|.zarr, never an existing name."""
    stem = f"taimill-{datetime.now():%Y%m%d-%H%M%S}"
    path, k = out_dir / f"{stem}{SUFFIX[kind]}", 1
    while path.exists():
        k += 1
        path = out_dir / f"{stem}-{k}{SUFFIX[kind]}"
    return path


def file_sink(kind: str, path: Path):
    if kind == "rrd":
        from taimill.recording.sink import RerunSink

        return RerunSink(path)
    from taimill.store.writer import ZarrSink

    return ZarrSink(path)


class Batched(Relay):
    """Buffers the stream for `sink` and passes it on in blocks of ~BATCH_SECONDS."""

    def __init__(self, sink):
        super().__init__(sink)
        self.pending = {"frames": [], "events": [], "energy": []}
        self.t_flush = None

    def frames(self, block):
        self._add("frames", block, block["time"][-1])

    def events(self, block):
        self._add("events", block, None)

    def energy(self, block):
        self._add("energy", block, block["time"][-1])

    def _add(self, table, block, t):
        self.pending[table].append(block)
        if t is not None:
            self.t_flush = t if self.t_flush is None else self.t_flush
            if t - self.t_flush >= BATCH_SECONDS:
                self.flush()
                self.t_flush = t

    def flush(self):
        for table, blocks in self.pending.items():
            if blocks:
                getattr(self.sink, table)({k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]})
            blocks.clear()

    def finish(self, summary, status):
        self.flush()
        self.sink.finish(summary, status)


class RecordingSummary(Relay):
    """Sink: the run summary (docs/outputs.md) of what a recording receives, from its start time on
    (the config's `live_start_time`), energy counted from its first row."""

    def __init__(self):
        super().__init__(None)  # built at start, from the config's start time

    def start(self, config, n_balls, radii):
        self.t_start = float(config["live_start_time"])
        self.summary = SummarySink(self.t_start, math.inf)
        self.sink = Batched(Rebased(self.summary))
        self.sink.start(config, n_balls, radii)

    def finish(self, summary, status):
        pass  # the recording's summary comes from result(), with the live changes

    def result(self, t_end: float, wall: float) -> dict:
        self.sink.flush()
        return self.summary.result(t_end, wall)


class Guarded(Relay):
    """The file's sink until a write fails (a full disk): the failure goes to
    `on_fault(error)` once, in the simulation's thread, instead of stopping the mill,
    and nothing more reaches the file; `finish` then only tries to record the status."""

    def __init__(self, sink, on_fault):
        super().__init__(sink)
        self.on_fault, self.error = on_fault, None

    def _pass(self, name: str, block) -> None:
        if self.error is not None:
            return
        try:
            getattr(self.sink, name)(block)
        except (OSError, ConfigError) as err:  # StoreWriteError is a ConfigError
            self.error = err
            self.on_fault(err)

    def frames(self, block):
        self._pass("frames", block)

    def events(self, block):
        self._pass("events", block)

    def energy(self, block):
        self._pass("energy", block)

    def finish(self, summary, status):
        try:
            self.sink.finish(summary, status if self.error is None else f"failed: {self.error}")
        except (OSError, ConfigError):
            pass  # said once already


class Recording:
    """One recording attached to a LiveMill: the file's sink and its summary. It starts
    at the simulated time the mill had when the sink was attached (`t_start`); a write
    that fails goes to `on_fault(kind, error)` (Guarded)."""

    def __init__(self, kind: str, path: Path, mill, on_fault=None):
        self.kind, self.path = kind, path
        self.wall_start = time.perf_counter()
        self.summary = RecordingSummary()
        self.file = Guarded(file_sink(kind, path), lambda err: on_fault and on_fault(kind, err))
        self.sink = FanOut(self.summary, self.file)
        mill.add_sink(self.sink)
        self.t_start = self.summary.t_start

    def stop(self, mill, status: str = "stopped") -> dict:
        """Detach, then close the file with the summary of what it received."""
        mill.remove_sink(self.sink)
        t = mill.time
        result = self.summary.result(t, time.perf_counter() - self.wall_start)
        result["live_changes"] = [c for c in mill.changes if c["time"] >= self.t_start]
        result["recorded"] = [self.t_start, t]
        result["compute"] = compute()
        result = with_units(result)
        self.file.finish(result, status)
        return result


class Recorders:
    """At most one recording of each kind; `toggle` starts or stops it."""

    def __init__(self, out_dir: Path, on_fault=None):
        self.out_dir = Path(out_dir)
        self.on_fault = on_fault  #: (kind, error) of a recording whose write failed
        self.active: dict[str, Recording] = {}
        self._lock = threading.Lock()  # toggles run in worker threads

    def toggle(self, kind: str, mill) -> str:
        """Start or stop; returns the line for the message bar."""
        with self._lock:
            return self._toggle(kind, mill)

    def _toggle(self, kind: str, mill) -> str:
        if kind in self.active:
            rec = self.active[kind]
            rec.stop(mill)
            del self.active[kind]  # after the file is closed: `active` says what is open
            return f"{kind} recording stopped: {rec.path} (t = {rec.t_start:.3f} … {mill.time:.3f} s)"
        self.out_dir.mkdir(parents=True, exist_ok=True)
        rec = Recording(kind, new_path(self.out_dir, kind), mill, self.on_fault)
        self.active[kind] = rec
        return f"recording {kind} to {rec.path} from t = {rec.t_start:.3f} s"

    def stop(self, kind: str, mill, status: str) -> Path | None:
        """End the recording of `kind` if one is open; its path."""
        with self._lock:
            rec = self.active.pop(kind, None)
            if rec is not None:
                rec.stop(mill, status)
        return rec.path if rec is not None else None

    def stop_all(self, mill, status: str) -> list[Path]:
        paths = []
        with self._lock:
            for kind in list(self.active):
                rec = self.active[kind]
                rec.stop(mill, status)
                del self.active[kind]
                paths.append(rec.path)
        return paths
