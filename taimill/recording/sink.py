"""`RerunSink`: a run as a rerun recording (.rrd), from the same stream the zarr store
consumes (sinks.py; docs/outputs.md, rerun recording; layout in recording_scene.py).

Bulk data goes through `send_columns` in batches of about BATCH_SECONDS simulated
seconds (per-frame `log` tops out near 3000 frames/s): ball frames on `sim_time` (s) and
`step` (time step index), every collision event at its own t_start, and the scalar
series at the frame times. Events are reported when a contact ends, so a window's
statistics are written once the stream has moved STAT_LAG past it; an event longer than
that (a ball resting or rolling on the wall) counts in the windows written after it
arrives. Histograms of onset speeds cover the periods (k-1)·P … k·P, P =
`histogram_every`, and a last partial period at the end.

The sink may start mid-run (the TUI records on demand): windows then begin at the
first recorded frame. The lab view replays the preset's drive (taimill.model.drive);
live speed changes made in the TUI are not in the config and so not in that view.
"""

from __future__ import annotations

import functools
import math
import shutil
from pathlib import Path

import numpy as np
import rerun as rr

from taimill.errors import StoreWriteError
from taimill.recording import scene
from taimill.recording import stats
from taimill.model.drive import Drive
from taimill.schema import ENERGY_COLUMNS

BATCH_SECONDS = 1.0  # simulated seconds of frames sent per batch
BATCH_POINTS = 2_000_000  # … or fewer frames once this many ball positions wait
STAT_LAG = 0.1  # s a window waits for contacts still open at its end (2 launches)
STAT_WINDOW = 1.0  # s, sliding window of the scalar series
EVENT_KEYS = ("t_start", "kind", "x", "y", "z", "un", "ut", "se_n", "se_t")
LEDGER_KEYS = tuple(ENERGY_COLUMNS)


FULL_BYTES = 1 << 16  #: free space below which a failed write is put down to a full disk
# s a flush may go without the file growing before the writer is taken to have stopped:
# rerun's flush waits without end by default, and on a full disk its file writer once
# never answered (one test run in many hung there). A slow disk still grows the file.
FLUSH_STALL_SECONDS = 30.0
FLUSH_TIMED_OUT = "Flush timed out"  # the start of rerun's message when a flush's wait ran out


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return -1


def flush_while_growing(rec, path: Path, stall: float = FLUSH_STALL_SECONDS) -> None:
    """rec.flush(), waiting as long as `path` grows; a RuntimeError once it has not grown
    for `stall` seconds (FLUSH_STALL_SECONDS)."""
    size = _size(path)
    while True:
        try:
            rec.flush(timeout_sec=stall)
            return
        except RuntimeError as err:
            if not str(err).startswith(FLUSH_TIMED_OUT):
                raise
        now = _size(path)
        if now == size:
            raise RuntimeError(f"the recording's writer stopped: the file did not grow for {stall:g} s")
        size = now


def _refusals(method):
    """A write rerun's file writer could not do (it says only "File-writer thread shut
    down prematurely", and logs the cause) as StoreWriteError naming the recording;
    after it the sink takes nothing more."""
    @functools.wraps(method)
    def call(self, *args, **kwargs):
        if self.failed:
            return None
        try:
            return method(self, *args, **kwargs)
        except (RuntimeError, OSError) as err:
            self.failed, self.rec = True, None
            try:
                full = shutil.disk_usage(self.path.absolute().parent).free < FULL_BYTES
            except OSError:
                full = False
            why = "No space left on device" if full else getattr(err, "strerror", None) or str(err)
            raise StoreWriteError(self.path, "recording", f"write failed ({why})") from None
    return call


def _cat(blocks: list[dict], keys) -> dict[str, np.ndarray]:
    return {k: np.concatenate([b[k] for b in blocks]) for k in keys}


def _take(table: dict[str, np.ndarray], keep: np.ndarray) -> dict[str, np.ndarray]:
    return {k: v[keep] for k, v in table.items()}


class RerunSink:
    """Sink writing a rerun recording to `path` (.rrd) with its default blueprint.

    lab_frame: also record the jar's pose on the plate (lab view). histogram_every:
    period of the onset-speed histograms (s). window: sliding window of the scalar
    series (s)."""

    def __init__(self, path, *, lab_frame: bool = False, histogram_every: float = 1.0, window: float = STAT_WINDOW):
        if not (histogram_every > 0 and window > 0):
            raise ValueError(f"histogram_every = {histogram_every} s and window = {window} s must be > 0")
        self.path = Path(path)
        self.lab_frame, self.period, self.window = lab_frame, histogram_every, window
        self.rec: rr.RecordingStream | None = None
        self.failed = False  #: a write failed: the sink takes nothing more

    # ------------------------------------------------------------ the Sink protocol
    @_refusals
    def start(self, config: dict, n_balls: int, radii: np.ndarray) -> None:
        """Open the file, log the static scenery and set the colour scales. `config`:
        the resolved preset (`Preset.as_dict()`, or its JSON copy in a store); the
        `step` timeline is round(t / config["dt"])."""
        self.config, self.dt = config, float(config["dt"])
        self.n = int(n_balls)
        self.ball_radius = float(np.max(radii))
        outline = scene.jar_outline(config)
        jar_radius = float(np.hypot(*outline.T).max())
        self.speed_ref = scene.speed_scale(config, jar_radius)
        self.se_ref = 0.5 * scene.ball_mass(config) * self.speed_ref**2
        self.luts = {k: scene.lut(name) for k, name in scene.COLORMAPS.items()}
        self.plate, self.jar = Drive.from_config(config).start_up()
        self.rec = rr.RecordingStream("taimill")
        self.rec.save(self.path, default_blueprint=scene.blueprint(self.lab_frame, scene.extent_of(config)))
        self.rec.send_recording_name(f"{config['jar']['name']} {config['pair']} {self.path.stem}")
        scene.log_scenery(self.rec, config, outline, radii, self.lab_frame)
        self._log_info()
        self.frame_blocks: list[dict] = []
        self.event_blocks: list[dict] = []
        self.ledger_blocks: list[dict] = []
        self.history = {k: np.zeros(0) for k in EVENT_KEYS}  # events still inside a window
        self.ledger = {k: np.zeros(0) for k in LEDGER_KEYS}  # rows still needed
        self.t_origin: float | None = None  # first recorded frame
        self.emitted = -math.inf  # last time whose statistics are written
        self.next_histogram = math.nan
        self.first_ledger = None  # (imbalance, drive work) of the first row, J
        self.energy_scale = 0.0  # J, stats.balance_error

    def frames(self, block: dict[str, np.ndarray]) -> None:
        """Buffer frames: time (F,) s; position, velocity (F, N, 3) m, m/s (jar frame)."""
        t = np.asarray(block["time"], dtype=float)
        if not len(t):
            return
        if self.t_origin is None:
            self.t_origin = float(t[0])
            self.next_histogram = (math.floor(self.t_origin / self.period) + 1) * self.period
        self.frame_blocks.append({"time": t.copy(), "position": np.array(block["position"], dtype=np.float32),
                                  "speed": np.linalg.norm(block["velocity"], axis=-1)})

    def events(self, block: dict[str, np.ndarray]) -> None:
        """Buffer collision events (sinks.EVENT_COLUMNS)."""
        if len(block["t_start"]):
            self.event_blocks.append({k: np.array(block[k]) for k in EVENT_KEYS})

    def energy(self, block: dict[str, np.ndarray]) -> None:
        """Buffer ledger rows; send everything once a batch is full."""
        if len(block["time"]):
            self.ledger_blocks.append({k: np.array(block[k], dtype=float) for k in LEDGER_KEYS})
        waiting = sum(len(b["time"]) for b in self.frame_blocks)
        if waiting and (self.frame_blocks[-1]["time"][-1] - self.frame_blocks[0]["time"][0] >= BATCH_SECONDS
                        or waiting * self.n >= BATCH_POINTS):
            self.flush()

    @_refusals
    def finish(self, summary: dict, status: str) -> None:
        """Send what is buffered, every remaining statistic, the summary; close the file."""
        if self.rec is None:
            return
        self.flush(final=True)
        self._log_info(summary, status)
        flush_while_growing(self.rec, self.path)
        self.rec.disconnect()
        self.rec = None

    # ------------------------------------------------------------ sending
    @_refusals
    def flush(self, final: bool = False) -> None:
        """Send buffered frames and events; statistics up to STAT_LAG before the newest
        ledger row (all of them if `final`)."""
        if self.frame_blocks:
            self._send_frames(_cat(self.frame_blocks, ("time", "position", "speed")))
            self.frame_blocks = []
        if self.event_blocks:
            events = _cat(self.event_blocks, EVENT_KEYS)
            self.event_blocks = []
            self._send_events(events)
            self.history = {k: np.concatenate([self.history[k], events[k]]) for k in EVENT_KEYS}
        if self.ledger_blocks:
            rows = _cat(self.ledger_blocks, LEDGER_KEYS)
            self.ledger_blocks = []
            self._send_balance(rows)
            self.ledger = {k: np.concatenate([self.ledger[k], rows[k]]) for k in LEDGER_KEYS}
        if len(self.ledger["time"]) and self.t_origin is not None:
            upto = self.ledger["time"][-1] - (0.0 if final else STAT_LAG)
            self._send_windows(upto)
            self._send_histograms(upto, final)
            self._forget(min(self.emitted, self.next_histogram - self.period))

    def _index(self, t: np.ndarray) -> list[rr.TimeColumn]:
        return [rr.TimeColumn(scene.TIME, duration=t), rr.TimeColumn(scene.STEP, sequence=np.rint(t / self.dt).astype(np.int64))]

    def _send_frames(self, f: dict[str, np.ndarray]) -> None:
        count = len(f["time"])
        colors = scene.shade(self.luts["speed"], f["speed"].ravel() / self.speed_ref)
        self.rec.send_columns(scene.BALLS, indexes=self._index(f["time"]), columns=rr.Points3D.columns(
            positions=f["position"].reshape(-1, 3), colors=colors).partition([self.n] * count))
        if self.lab_frame:
            self._send_pose(f["time"])

    def _send_pose(self, t: np.ndarray) -> None:
        """Jar frame in the lab: axis at R_p (cos φ_p, sin φ_p, 0), turned by φ_jar (docs/model.md)."""
        plate = np.array([self.plate.at(x)[2] for x in t])
        jar = np.array([self.jar.at(x)[2] for x in t])
        rp = self.config["plate_radius"]
        translation = np.column_stack([rp * np.cos(plate), rp * np.sin(plate), np.zeros_like(t)])
        quaternion = np.column_stack([np.zeros_like(t), np.zeros_like(t), np.sin(jar / 2), np.cos(jar / 2)])  # xyzw
        self.rec.send_columns(scene.JAR, indexes=self._index(t),
                              columns=rr.Transform3D.columns(translation=translation, quaternion=quaternion))

    def _send_events(self, e: dict[str, np.ndarray]) -> None:
        """Every event as one point at its contact point and t_start."""
        at = np.column_stack([e["x"], e["y"], e["z"]])
        for kind, path in scene.IMPACTS.items():
            level = scene.log_scale(e["se_" + kind[0]], self.se_ref, scene.SE_DECADES)
            self.rec.send_columns(path, indexes=self._index(e["t_start"]), columns=rr.Points3D.columns(
                positions=at, radii=self.ball_radius * (0.05 + 0.25 * level), colors=scene.shade(self.luts[kind], level)))
        wall = e["kind"] == 1
        if wall.any():
            level = scene.log_scale(e["un"][wall], self.speed_ref, scene.UN_DECADES)
            self.rec.send_columns(scene.CONTACT_MAP, indexes=self._index(e["t_start"][wall]), columns=rr.Points3D.columns(
                positions=at[wall], radii=np.full(int(wall.sum()), 0.06 * self.ball_radius),
                colors=scene.shade(self.luts["contact"], level)))

    def _send_balance(self, rows: dict[str, np.ndarray]) -> None:
        if self.first_ledger is None:
            self.first_ledger = (float(stats.imbalance(rows)[0]), float(rows["drive_work"][0]))
        error, self.energy_scale = stats.balance_error(rows, self.first_ledger, self.energy_scale)
        self._send_series({"energy_balance_error": error}, rows["time"])

    def _send_windows(self, upto: float) -> None:
        t = self.ledger["time"]
        times = t[(t > self.emitted) & (t <= upto) & (t > self.t_origin)]
        if len(times):
            self._send_series(stats.window_rates(self.history, self.ledger, times, self.window, self.t_origin), times)
            self.emitted = float(times[-1])

    def _send_histograms(self, upto: float, final: bool) -> None:
        ends = []
        while self.next_histogram <= upto:
            ends.append(self.next_histogram)
            self.next_histogram += self.period
        last = self.ledger["time"][-1]
        if final and last > self.next_histogram - self.period:
            ends.append(last)  # the last, partial period
        t = self.history["t_start"]
        for end in ends:  # a few rows per run: log (BarChart.columns takes no batch of 1-D tensors)
            self.rec.set_time(scene.TIME, duration=end)
            self.rec.set_time(scene.STEP, sequence=round(end / self.dt))
            inside = (t > end - self.period) & (t <= end)
            for kind, path in scene.HISTOGRAMS.items():
                self.rec.log(path, scene.histogram(kind, stats.onset_histogram(self.history["u" + kind[0]][inside])))
        self.rec.reset_time()

    def _send_series(self, series: dict[str, np.ndarray], times: np.ndarray) -> None:
        for name, values in series.items():
            self.rec.send_columns(f"/stats/{name}", indexes=self._index(times),
                                  columns=rr.Scalars.columns(scalars=values))

    def _forget(self, done: float) -> None:
        """Drop events and ledger rows no future window or histogram reaches."""
        keep_from = done - max(self.window, self.period)
        if math.isfinite(keep_from):
            self.history = _take(self.history, self.history["t_start"] > keep_from)
            keep = self.ledger["time"] >= keep_from
            keep[max(0, np.argmax(keep) - 1)] = True  # one row before, to interpolate at the edge
            self.ledger = _take(self.ledger, keep)

    def _log_info(self, summary: dict | None = None, status: str | None = None) -> None:
        text = scene.info_text(self.config, self.speed_ref, self.se_ref, summary, status)
        self.rec.log(scene.INFO, rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
