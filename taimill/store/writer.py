"""`ZarrSink`: writes the stream of `taimill.store.sinks` into a run store
(taimill.store.layout), so that a kill at any moment leaves it readable.

Crash safety (zarr 3.1, tests/test_store.py, tests/test_faults.py): every key is written
atomically, but an array is resized before its data lands (while the writer runs, to
up to twice its committed rows: `chunks._TableWriter`). So each table group carries an
attribute `n_valid`, written only after every array of the table holds its rows;
readers slice to it and a restarted writer trims back to it (`run.trim_to_valid`); a
writer that finishes leaves every array `n_valid` rows long. Rows reach the arrays in
whole chunks, encoded and stored by the sink (`chunks._ChunkWriter`). Between chunks, the
sink commits whenever a ledger block brings the simulated time `commit_every` (0.2 s)
past the last commit, i.e. after every launch of a run (1 s simulated, runner.LAUNCH_SECONDS): the rows not yet in the
arrays since the last commit, of every table, go to ONE journal file (`TABLE/start`,
`TABLE/COLUMN` in a NumPy .npz, written atomically); readers append the journal's rows
after `n_valid`. A dense trajectory's launch ends where a chunk ends
(`layout.FRAME_CHUNK_ROWS`), so its commits journal only events.
Appending a sub-chunk block to each of the 47 arrays instead would cost a resize and a
chunk rewrite per array, ≈ 0.2 s per commit, as long as the launch itself (zarr's cost
per call); the journal costs ≈ 4 ms. Segments whose rows all reached the arrays are
deleted, the journal when the writer finishes. A SIGKILL at any moment thus leaves a
readable store missing at most the launch under way. A run that keeps no event rows
also rewrites its spectra at every commit, in place and between two updates of their
`generation`, so that a reader never meets them half-written (store.spectra). (Tables commit one by one: a
writer killed between a launch's frame chunk and its ledger chunk leaves the
trajectory a launch ahead, and readers take the frames both tables hold:
`RunStore._cut_to_whole_frames`.) A write the operating system
refuses (a full disk) raises `StoreWriteError` naming the store; what was committed
before stays readable.
"""

from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np
import zarr
from zarr.core.sync import sync

from taimill.errors import StoreWriteError
from taimill.schema import VELOCITY_CONVENTION
from taimill.store.chunks import _TableWriter, location, put_npz
from taimill.store.layout import (CODECS, JOURNAL, JOURNAL_DESCRIPTION, SCHEMA_VERSION, expected_frames,
                                  frame_chunk_rows, layout, plain)
from taimill.store.spectra import GROUP as SPECTRA, SpectraWriter

FRAME_CHUNK_BYTES = 16 << 20  # trajectory chunks hold at most this many bytes per array (≥ 1 frame)
# A mill whose frame is larger than this per array (above ≈ 44 000 balls) gets one frame
# per trajectory chunk: the sink keeps one chunk of rows per array in memory, and a
# 6-frame chunk of 10⁵ balls is 43 MB for position, velocity and spin together (≈ 430 B
# a ball: peak RSS of `taimill run` at 10⁵ balls, 11 steps, 408 → 374 MB).
LARGE_FRAME_BYTES = 1 << 20
# Simulated seconds between commits (module doc): below a run's 1 s launch, so that
# every launch of `taimill run` commits.
COMMIT_SECONDS = 0.2


class ZarrSink:
    """Sink writing one run into a zarr v3 group (layout and crash safety: module doc).

    `path_or_group`: a path is opened with mode "w" (a fresh run overwrites it); a
    `zarr.Group` (e.g. one subgroup per sweep point) gets the run's tables, replacing any
    it held. `frame_chunk` rows per chunk for trajectory and energy (default: from the
    config's trajectory_rate, `frame_chunk_rows`), `event_chunk` for events; a trajectory
    chunk holds at most FRAME_CHUNK_BYTES per array (a frame of 10⁵ balls is 2.4 MB: a
    1024-frame chunk would be written whole at every commit). Rows reach the disk when a chunk fills, when a ledger block brings the
    simulated time `commit_every` seconds past the last commit (every table is then
    committed), on `flush()` and on `finish`. An OSError while writing (a full disk)
    raises `StoreWriteError`; `finish` after it only tries to record the status."""

    def __init__(self, path_or_group, *, frame_chunk: int | None = None, event_chunk: int = 65536,
                 commit_every: float = COMMIT_SECONDS):
        self.failed: str | None = None
        if isinstance(path_or_group, zarr.Group):
            self.group = path_or_group
            self.where = location(path_or_group)
        else:
            self.where = str(path_or_group)
            with self._writing("zarr.json"):
                self.group = zarr.open_group(path_or_group, mode="w")
        self.frame_chunk, self.event_chunk = frame_chunk, event_chunk
        self.commit_every = commit_every
        self.t_commit = -math.inf
        self.tables: dict[str, _TableWriter] = {}
        self.journaled: dict[str, int] = {}  #: rows of each table that are in the arrays or the journal
        self.segments: list[tuple[str, dict[str, int]]] = []  #: journal keys and their end row per table
        self.seq = 0
        self.last_spectra = None
        self.spectra_out: SpectraWriter | None = None  #: made by `start`
        self.event_rows = 0  #: event rows received: none, and the spectra are committed with the tables

    @contextmanager
    def _writing(self, part: str):
        """An OSError of the file system inside becomes StoreWriteError(part)."""
        try:
            yield
        except OSError as err:
            self.failed = f"{part}: {err.strerror or err}"
            raise StoreWriteError(self.where, part, f"write failed ({err.strerror or err}); "
                                  "the rows committed before are readable") from err

    def start(self, config: dict, n_balls: int, radii: np.ndarray) -> None:
        """Write the run attributes (config, radii in m) and create the empty tables."""
        radii = np.asarray(radii, dtype=float)
        if radii.shape != (n_balls,):
            raise ValueError(f"radii of shape {radii.shape}, expected ({n_balls},)")
        with self._writing("attrs"):
            self.group.attrs.update(
                {
                    "schema_version": SCHEMA_VERSION,
                    "config": plain(config),
                    "n_balls": int(n_balls),
                    "status": "running",
                    "conventions": VELOCITY_CONVENTION,
                }
            )
        with self._writing("radii"):
            self.group.create_array("radii", data=radii, overwrite=True, dimension_names=("ball",), compressors=CODECS,
                                    attributes={"units": "m", "description": "ball radii"})
        frames = self.frame_chunk or frame_chunk_rows(config.get("trajectory_rate"))
        chunks = {"trajectory": frames, "events": self.event_chunk, "energy": frames}
        frame_bytes = 24 * max(1, n_balls)  # one frame of one trajectory array
        cap = 1 if frame_bytes > LARGE_FRAME_BYTES else FRAME_CHUNK_BYTES // frame_bytes
        chunks["trajectory"] = max(1, min(chunks["trajectory"], cap))
        frames = expected_frames(config)
        rows = {"trajectory": frames, "events": 0, "energy": frames}
        for name, columns in layout(n_balls).items():
            with self._writing(name):
                self.tables[name] = _TableWriter(self.group, name, columns, chunks[name], rows[name])
        self.journaled = {name: 0 for name in self.tables}
        with self._writing(JOURNAL):
            for old in (JOURNAL, SPECTRA):  # a group reused for a new run
                if old in self.group:
                    del self.group[old]
        self.spectra_out = SpectraWriter(self.group, CODECS)

    def _add(self, table: str, block: dict) -> None:
        with self._writing(table):
            self.tables[table].add(block)

    def frames(self, block: dict[str, np.ndarray]) -> None:
        """Append frames: time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s."""
        self._add("trajectory", block)

    def events(self, block: dict[str, np.ndarray]) -> None:
        """Append collision events, one array per `EVENT_COLUMNS` entry."""
        self.event_rows += len(block["t_start"])
        self._add("events", block)

    def energy(self, block: dict[str, np.ndarray]) -> None:
        """Append energy-ledger rows, one array per `ENERGY_COLUMNS` entry (J, time in s);
        commits every table when due (class doc). A launch sends its events, frames and
        ledger rows in this order, so each commit holds whole launches."""
        self._add("energy", block)
        t = np.asarray(block["time"])
        if len(t) and float(t[-1]) >= self.t_commit + self.commit_every:
            self.commit()
            self.t_commit = float(t[-1])

    def commit(self) -> None:
        """Make every row received so far durable at the cost of one file: the rows not
        yet in whole chunks of the arrays go to one journal segment (module doc)."""
        if self.last_spectra is not None and self.event_rows == 0:  # a run storing spectra only
            with self._writing(SPECTRA):
                self.spectra_out.write(self.last_spectra)
        starts = {name: max(self.journaled[name], t.committed) for name, t in self.tables.items()}
        tails = {name: t.tail(starts[name]) for name, t in self.tables.items()}
        ends = {name: starts[name] + len(next(iter(rows.values()))) for name, rows in tails.items()}
        if ends == starts:
            return
        parts = {}
        for name, rows in tails.items():
            parts[f"{name}/start"] = np.asarray(starts[name], dtype=np.int64)
            parts.update({f"{name}/{k}": v for k, v in rows.items()})
        with self._writing(JOURNAL):
            if self.seq == 0:
                self.group.create_group(JOURNAL, overwrite=True, attributes={"description": JOURNAL_DESCRIPTION})
            self.seq += 1
            key = f"{self.group.path}/{JOURNAL}/{self.seq:08d}.npz".lstrip("/")
            put_npz(self.group.store, key, parts)
        self.journaled = ends
        self.segments.append((key, ends))
        self._prune()

    def _prune(self) -> None:
        """Delete the journal segments whose rows all reached the arrays."""
        keep = []
        for key, ends in self.segments:
            if all(end <= self.tables[name].committed for name, end in ends.items()):
                try:
                    sync(self.group.store.delete(key))
                    continue
                except OSError:
                    pass
            keep.append((key, ends))
        self.segments = keep

    def flush(self) -> None:
        """Write every buffered row into the arrays and commit it (n_valid); the journal
        is then no longer needed and deleted."""
        for name, table in self.tables.items():
            with self._writing(name):
                table.flush()
        if self.seq:
            with self._writing(JOURNAL):
                del self.group[JOURNAL]
            self.seq, self.segments = 0, []
        self.journaled = {name: t.committed for name, t in self.tables.items()}

    def spectra(self, spectra) -> None:
        """The run's energy spectra so far (taimill.model.spectra), written at finish."""
        self.last_spectra = spectra

    def finish(self, summary: dict, status: str) -> None:
        """Flush, then record `summary`, `status` ("complete", "unstable: …", …) and
        the summary's `analysis_window` ([start, end], s) as the store's own. After a
        failed write only the status is recorded ("failed: …"), if the disk lets it."""
        if self.failed is None:
            try:
                self.flush()
                if self.last_spectra is not None:
                    with self._writing(SPECTRA):
                        self.spectra_out.write(self.last_spectra)
                attrs = {"summary": plain(summary, "summary"), "status": status}
                if "analysis_window" in summary:
                    attrs["analysis_window"] = plain(summary["analysis_window"], "analysis_window")
                with self._writing("attrs"):
                    self.group.attrs.update(attrs)
                return
            except StoreWriteError:
                self._record_failure(status)
                raise
        self._record_failure(status)

    def _record_failure(self, status: str) -> None:
        try:
            self.group.attrs["status"] = f"failed: {self.failed}" if self.failed else status
        except Exception:  # the disk still refuses: the status stays "running", also not complete
            pass
