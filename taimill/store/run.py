"""Zarr v3 storage of a run: `ZarrSink` writes the stream of `taimill.store.sinks`, `open_run` reads it.

Layout of one run group (docs/outputs.md):

    attrs: schema_version, config, n_balls, status, summary, analysis_window (s)
    radii        (N,) ball radii, m (schema 2 and older: attrs.radii)
    trajectory/  time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s
    events/      one 1-D array per `EVENT_COLUMNS` entry
    energy/      one 1-D array per `ENERGY_COLUMNS` entry
    spectra/     the events' energy spectra over the analysis window (store/spectra.py),
                 written when the run ends, and at every commit by a run that stores
                 no event rows (config events_output = "spectra")
    journal/     while the writer runs: NNNNNNNN.npz, the rows committed since the last
                 whole chunk of each table

Crash safety (zarr 3.1, tests/test_store.py, tests/test_faults.py): every key is written
atomically, but an array is resized before its data lands (while the writer runs, to
up to twice its committed rows: `_TableWriter`). So each table group carries an
attribute `n_valid`, written only after every array of the table holds its rows;
readers slice to it and a restarted writer trims back to it (`trim_to_valid`); a
writer that finishes leaves every array `n_valid` rows long. Rows reach the arrays in
whole chunks, encoded and stored by the sink (`_ChunkWriter`). Between chunks, the
sink commits whenever a ledger block brings the simulated time `commit_every` (0.2 s)
past the last commit, i.e. after every launch of a run (1 s simulated, runner.LAUNCH_SECONDS): the rows not yet in the
arrays since the last commit, of every table, go to ONE journal file (`TABLE/start`,
`TABLE/COLUMN` in a NumPy .npz, written atomically); readers append the journal's rows
after `n_valid`. A dense trajectory's launch ends where a chunk ends
(`FRAME_CHUNK_ROWS`), so its commits journal only events.
Appending a sub-chunk block to each of the 47 arrays instead would cost a resize and a
chunk rewrite per array, ≈ 0.2 s per commit, as long as the launch itself (zarr's cost
per call); the journal costs ≈ 4 ms. Segments whose rows all reached the arrays are
deleted, the journal when the writer finishes. A SIGKILL at any moment thus leaves a
readable store missing at most the launch under way. (Tables commit one by one: a
writer killed between a launch's frame chunk and its ledger chunk leaves the
trajectory a launch ahead, and readers take the frames both tables hold:
`RunStore._cut_to_whole_frames`.) A write the operating system
refuses (a full disk) raises `StoreWriteError` naming the store; what was committed
before stays readable.

Reading checks what it reads (`RunStore.check`): attributes of the wrong type, a table or
array missing from a store whose writer finished, chunks missing below `n_valid`, a chunk
or journal file that does not decode, a chunk that fails its CRC-32C (`CHECKSUM`), tables
that disagree with the summary, or arrays that contradict the stored config (ball count,
radii, frame count) raise `StoreError` naming the store and the part, instead of reading
as fill values or as a complete run. A journal left in a store whose writer finished is
named in a warning and not read.
"""

from __future__ import annotations

import asyncio
import io
import json
import math
import os
import sys
import uuid
import zipfile
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import google_crc32c  # zarr's own dependency (its Crc32cCodec): the writer appends the same checksum
import numcodecs.blosc
import numpy as np
import zarr
from zarr.codecs import BloscCodec, BytesCodec, Crc32cCodec
from zarr.core.buffer import default_buffer_prototype
from zarr.core.sync import sync
from zarr.storage import LocalStore

from taimill.errors import StoreError, StoreWriteError
from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.model.spectra import from_rows
from taimill.store.spectra import GROUP as SPECTRA, read_spectra, write_spectra
from taimill.schema import (DRIVE_FIELDS, ENERGY_COLUMNS, EVENT_COLUMNS, FRAME_COLUMNS, MECHANISM_COLUMNS, PER_BALL,
                            VELOCITY_CONVENTION)

SCHEMA_VERSION = 3
FRAME_CHUNK_BYTES = 16 << 20  # trajectory chunks hold at most this many bytes per array (≥ 1 frame)
# A mill whose frame is larger than this per array (above ≈ 44 000 balls) gets one frame
# per trajectory chunk: the sink keeps one chunk of rows per array in memory, and a
# 6-frame chunk of 10⁵ balls is 43 MB for position, velocity and spin together (≈ 430 B
# a ball: peak RSS of `taimill run` at 10⁵ balls, 11 steps, 408 → 374 MB).
LARGE_FRAME_BYTES = 1 << 20
# Columns a version-1 store lacks (read as absent from such a store): the frame's
# drive and the dissipation by mechanism.
ADDED_IN_2 = frozenset(DRIVE_FIELDS) | frozenset(MECHANISM_COLUMNS)
# Simulated seconds between commits (module doc): below a run's 1 s launch, so that
# every launch of `taimill run` commits.
COMMIT_SECONDS = 0.2
# Rows committed between whole chunks (module doc): one .npz per commit in this group.
JOURNAL = "journal"
JOURNAL_DESCRIPTION = ("rows committed since the last whole chunk of each table, one NumPy .npz per commit "
                       "(TABLE/start, TABLE/COLUMN); readers append them after n_valid; deleted when the writer finishes")
# Trajectory and energy rows per chunk when the sink is not told (ZarrSink): about
# FRAME_CHUNK_SECONDS of simulated frames at the run's trajectory_rate, within these
# bounds. zarr costs ≈ 2 ms per chunk of every array whatever its size (scripts/bench.py
# --only dense): at 10⁵ frames/s, 1024-row chunks of the 30-odd frame and ledger arrays
# cost 70 µs per frame, ten times the simulation; 65536-row chunks ≈ 2 µs. The sink now
# stores chunks itself (`_ChunkWriter`), but readers still pay zarr's cost per chunk and
# each chunk is a file: 8192- or 16384-row chunks at 10⁵ frames/s cost the writer more
# in file creation than they save in journal rows (replayed stream, 2 cores).
# The upper bound is the runner's frame buffer (physics.runner.FRAME_CAPACITY): a
# dense trajectory's launch fills that buffer exactly, 32768 frames, so each launch
# ends a chunk and its commit journals no frame or ledger rows (65536-row chunks put
# every other launch's 32768 rows in the journal, uncompressed: 0.5 of 2.3 s CPU for
# 3 s at 10⁵ frames/s, Xeon machine).
FRAME_CHUNK_SECONDS = 0.5
FRAME_CHUNK_ROWS = (1024, 32768)
# Every array: LZ4 after byte shuffling (Blosc), for floating-point columns faster and
# smaller than zarr's default Zstandard (trajectories: 1.4 vs 3.1 µs per frame of 12
# balls, compression 1.31 vs 1.08).
COMPRESSOR = BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")
# Last in every array's codec chain (schema 3 stores written since issue 36): a CRC-32C
# of the compressed chunk, 4 bytes, checked by zarr on every read. Blosc decodes many
# flipped bytes into other numbers without a word; a checksum turns them into an error
# that `read_rows` names. Stores written before it carry no checksum and read as before.
CHECKSUM = Crc32cCodec()
CODECS = (COMPRESSOR, CHECKSUM)
# Statuses whose writer called finish() after flushing everything: the tables hold
# every row the summary counted.
FLUSHED = ("complete", "interrupted", "unstable")


@dataclass(frozen=True)
class Column:
    """One stored array: per-row shape, dtype, unit and meaning, zarr dimension names."""

    dtype: str
    units: str
    description: str
    dims: tuple[str, ...]
    row_shape: tuple[int, ...] = ()


def _frame_columns(n_balls: int) -> dict[str, Column]:
    vec = ("frame", "ball", "xyz")
    return {k: Column(dtype, unit, text, vec, (n_balls, 3)) if k in PER_BALL else Column(dtype, unit, text, ("frame",))
            for k, (dtype, unit, text) in FRAME_COLUMNS.items()}


def _flat_columns(table: dict[str, tuple[str, str, str]], dim: str) -> dict[str, Column]:
    return {k: Column(dtype, unit, text, (dim,)) for k, (dtype, unit, text) in table.items()}


def layout(n_balls: int) -> dict[str, dict[str, Column]]:
    """Table group name -> its columns, for a run of `n_balls` balls."""
    return {
        "trajectory": _frame_columns(n_balls),
        "events": _flat_columns(EVENT_COLUMNS, "event"),
        "energy": _flat_columns(ENERGY_COLUMNS, "frame"),
    }


TABLE_DESCRIPTIONS = {
    "trajectory": "ball states and the jar frame's angles and speeds at the output frame rate; velocities relative to the jar frame (attribute conventions)",
    "events": "one row per collision event (docs/outputs.md)",
    "energy": "cumulative energy ledger (J), one row per frame",
}


def plain(value, where: str = "config"):
    """`value` as JSON-able Python: numpy scalars/arrays, tuples and paths converted."""
    if isinstance(value, dict):
        return {str(k): plain(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, (np.ndarray, np.generic)):
        return plain(value.tolist(), where)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"{where}: cannot store {type(value).__name__} as JSON")


def check_columns(block: dict, expected, table: str) -> None:
    """Raise ValueError naming the missing and unexpected columns of `block`."""
    missing = sorted(set(expected) - set(block))
    extra = sorted(set(block) - set(expected))
    if missing or extra:
        raise ValueError(f"{table} block: missing columns {missing}, unexpected columns {extra}")


class _TableWriter:
    """Appends row blocks to the arrays of one table group, committing through `n_valid`.

    Each array has a buffer of one chunk: rows are copied into it once, and a full
    buffer is encoded and stored as that chunk (`_ChunkWriter`), so at most one chunk of
    rows per array waits between calls. A block holding whole chunks from the start of
    one (a dense trajectory's launch) is encoded straight from the block. A flush
    stores the partial chunk too; its buffer stays, and the rows that follow complete
    the same chunk.

    The arrays are created as long as the rows expected (`expected_frames`), and grow
    ahead of their rows, to twice the rows (in whole chunks), whenever a chunk lands
    beyond their shape: a resize rewrites the array's metadata (≈ 1 ms
    each in zarr 3.1, for every array of the table), so a run does a few per array
    instead of one per chunk. Rows past `n_valid` are not data (readers slice to it);
    `flush` leaves each array exactly `n_valid` rows long."""

    def __init__(self, parent: zarr.Group, name: str, columns: dict[str, Column], chunk: int, rows: int = 0):
        """`rows`: the rows expected, in whole chunks: the arrays are created that long
        (no chunk is written), so a run that delivers them resizes only at `flush`."""
        self.name, self.columns, self.chunk = name, columns, chunk
        self.initial_rows = -(-rows // chunk) * chunk
        # every_chunk_stored: chunks equal to the fill value are written too, so a
        # missing chunk below n_valid is damage, not zeros (RunStore.check)
        self.group = parent.create_group(
            name, overwrite=True,
            attributes={"n_valid": 0, "description": TABLE_DESCRIPTIONS[name], "every_chunk_stored": True}
        )
        self.arrays = {k: self._create(k, c) for k, c in columns.items()}
        self.writer = _ChunkWriter.for_arrays(self.arrays)
        self.committed = 0  #: rows in the arrays and counted by n_valid
        self.written = 0  #: rows in the arrays
        self.start = 0  #: table row of the buffers' first row (a multiple of `chunk`)
        self.fill = 0  #: rows in the buffers
        self.buffers: dict[str, np.ndarray] | None = None

    @property
    def n_pending(self) -> int:
        return self.start + self.fill - self.committed

    def _create(self, name: str, c: Column) -> zarr.Array:
        return self.group.create_array(
            name,
            shape=(self.initial_rows, *c.row_shape),
            chunks=(self.chunk, *c.row_shape),
            dtype=c.dtype,
            fill_value=np.nan if c.dtype.startswith("f") else 0,
            dimension_names=c.dims,
            attributes={"units": c.units, "description": c.description},
            config={"write_empty_chunks": True},
            compressors=CODECS,
        )

    def add(self, block: dict) -> None:
        """Validate and buffer one block; write every chunk it completes."""
        rows = self._validated(block)
        n = len(next(iter(rows.values())))
        if self.buffers is None:
            self.buffers = {k: np.empty((self.chunk, *c.row_shape), dtype=c.dtype) for k, c in self.columns.items()}
        done = 0
        while done < n:
            if self.fill == 0 and n - done >= self.chunk:  # a whole chunk: stored from the block, not copied first
                self._store({k: np.ascontiguousarray(v[done:done + self.chunk], dtype=self.columns[k].dtype)
                             for k, v in rows.items()}, self.chunk)
                self.start += self.chunk
                done += self.chunk
                continue
            m = min(n - done, self.chunk - self.fill)
            for k, v in rows.items():
                np.copyto(self.buffers[k][self.fill:self.fill + m], v[done:done + m], casting="same_kind")
            self.fill += m
            done += m
            if self.fill == self.chunk:
                self._write_buffers()
        self._commit()

    def flush(self) -> None:
        """Write and commit every buffered row (a partial chunk stays buffered); the
        arrays are then exactly the committed rows long."""
        if self.n_pending:
            self._write_buffers()
        self._commit(exact=True)

    def tail(self, start: int) -> dict[str, np.ndarray]:
        """The buffered rows from row `start` (counted from the table's first row, at
        least `committed`) on: views of the buffers, valid until the next add."""
        if self.buffers is None:
            return {k: np.zeros((0, *c.row_shape), dtype=c.dtype) for k, c in self.columns.items()}
        return {k: b[start - self.start:self.fill] for k, b in self.buffers.items()}

    def _validated(self, block: dict) -> dict[str, np.ndarray]:
        """The block's columns as arrays, checked against the table (all before any row
        is buffered, so a bad block leaves the table as it was)."""
        check_columns(block, self.columns, self.name)
        rows = {}
        for k, c in self.columns.items():
            v = np.asarray(block[k])
            if not np.can_cast(v.dtype, c.dtype, casting="same_kind"):
                raise ValueError(f"{self.name} column {k!r}: Cannot cast array data from {v.dtype!r} to "
                                 f"{np.dtype(c.dtype)!r} according to the rule 'same_kind'")
            if v.ndim != 1 + len(c.row_shape) or v.shape[1:] != c.row_shape:
                expected = ("rows", *c.row_shape)
                raise ValueError(f"{self.name} column {k!r}: shape {v.shape}, expected {expected}")
            rows[k] = v
        if len({v.shape[0] for v in rows.values()}) > 1:
            lengths = {k: v.shape[0] for k, v in rows.items()}
            raise ValueError(f"{self.name} block: columns differ in length {lengths}")
        return rows

    def _write_buffers(self) -> None:
        """Store the buffers as chunk start // chunk of every array (a partial chunk
        padded with the fill value, as zarr pads it), the arrays grown to hold it.
        The rows are committed by `_commit`, after their data: a writer killed
        meanwhile leaves the last commit readable."""
        if self.fill < self.chunk:
            for k, b in self.buffers.items():
                b[self.fill:] = self.arrays[k].fill_value
        self._store(self.buffers, self.fill)
        if self.fill == self.chunk:
            self.start, self.fill = self.start + self.chunk, 0

    def _store(self, data: dict[str, np.ndarray], rows: int) -> None:
        """Store `data` (one chunk of rows per array, the first `rows` of them data) as
        chunk start // chunk, the arrays grown to hold it."""
        end = self.start + rows
        shape = self.arrays[next(iter(self.arrays))].shape[0]
        if end > shape:
            self._resize(max(end, -(-2 * end // self.chunk) * self.chunk))
        self.writer.write(self.arrays, data, self.start // self.chunk, rows)
        self.written = end

    def _commit(self, exact: bool = False) -> None:
        """Record the rows stored by `_write_buffers` as committed (n_valid); `exact`:
        shrink the arrays to them."""
        if exact and self.arrays[next(iter(self.arrays))].shape[0] != self.written:
            self._resize(self.written)
        if self.written != self.committed:
            self.committed = self.written
            self.group.attrs["n_valid"] = self.committed

    def _resize(self, rows: int) -> None:
        """Every array of the table to `rows` rows, their metadata written concurrently."""
        async def resize_all():
            await asyncio.gather(*(arr.async_array.resize((rows, *arr.shape[1:])) for arr in self.arrays.values()))

        sync(resize_all())


class _ChunkWriter:
    """Stores whole chunks of the table arrays. Arrays whose codecs are this module's
    (little-endian bytes, then `COMPRESSOR`, then optionally `CHECKSUM`) get their chunks encoded here, in one call
    to Blosc each, and stored under their keys (`put_all`): the bytes zarr itself
    stores for that chunk (tests/test_store.py), without zarr's per-chunk cost (≈ 2.5 ms
    of Python per chunk in zarr 3.1, and fresh copies of every chunk). Other arrays
    go through zarr."""

    def __init__(self, encoders):
        self.encoders = encoders  #: per array (its Blosc encoder, checksum?), or None: through zarr

    @classmethod
    def for_arrays(cls, arrays: dict[str, zarr.Array]) -> "_ChunkWriter":
        return cls({k: _blosc_encoder(arr) for k, arr in arrays.items()})

    def write(self, arrays: dict[str, zarr.Array], buffers: dict[str, np.ndarray], index: int, rows: int) -> None:
        """Chunk `index` of every array from its buffer, of which the first `rows` rows
        are data (the rest is the fill value, as zarr pads a partial last chunk)."""
        puts = []
        for k, arr in arrays.items():
            enc, data = self.encoders[k], buffers[k]
            if enc is None:
                lo = index * data.shape[0]
                if arr.shape[0] < lo + rows:
                    arr.resize((lo + rows, *arr.shape[1:]))
                arr[lo:lo + rows] = data[:rows]
                continue
            blosc, checksum = enc
            raw = data if data.dtype.byteorder != ">" else data.astype(data.dtype.newbyteorder("<"))
            chunk = _encode_serial(blosc, raw.reshape(-1).view(np.uint8))
            if checksum:  # what Crc32cCodec appends: the CRC-32C of the bytes before it, little-endian
                chunk += np.uint32(google_crc32c.value(chunk)).astype("<u4").tobytes()
            puts.append((arr.store, _chunk_key(arr, index), chunk))
        put_all(puts)


def _encode_serial(enc, data: np.ndarray) -> bytes:
    """enc.encode(data) by one thread, as zarr encodes (in its worker threads).
    numcodecs lets Blosc use its own threads when called from the main thread, and
    their blocks land in the output in the order they finish: the same data, other
    bytes from run to run (measured on a 17 MB chunk)."""
    saved = numcodecs.blosc.use_threads
    numcodecs.blosc.use_threads = False
    try:
        return enc.encode(data)
    finally:
        numcodecs.blosc.use_threads = saved


def _blosc_encoder(arr: zarr.Array):
    """(the numcodecs Blosc that zarr uses for the chunks of `arr`, whether a CRC-32C
    follows) if its codecs are the bytes codec (little-endian), one BloscCodec and
    optionally Crc32cCodec; else None."""
    try:
        codecs = list(arr.metadata.codecs)
        checksum = bool(codecs) and isinstance(codecs[-1], Crc32cCodec)
        if checksum:
            codecs.pop()
        ok = (len(codecs) == 2 and isinstance(codecs[0], BytesCodec) and isinstance(codecs[1], BloscCodec)
              and (codecs[0].endian is None or codecs[0].endian.value == "little"))
        return (codecs[1]._blosc_codec, checksum) if ok else None
    except Exception:  # another zarr's metadata: let zarr write
        return None


def expected_frames(config: dict) -> int:
    """Frames a run of `config` will write, from its duration (s) and trajectory_rate
    (frames per simulated second); 0 if either is missing. The arrays are sized for
    them up front: growing them costs a metadata write per array, ≈ 12 ms a table (10⁵
    frames/s: 0.07 s of 1.8 s for 3 s simulated)."""
    rate, duration = config.get("trajectory_rate"), config.get("duration")
    ok = all(isinstance(x, (int, float)) and math.isfinite(x) and x > 0 for x in (rate, duration))
    return int(min(rate * duration + 2, 1 << 40)) if ok else 0


def frame_chunk_rows(rate) -> int:
    """Rows per trajectory and energy chunk for frames at `rate` per simulated second:
    a power of two near FRAME_CHUNK_SECONDS of frames, within FRAME_CHUNK_ROWS."""
    lo, hi = FRAME_CHUNK_ROWS
    if not rate or not math.isfinite(rate) or rate <= 0:
        return lo
    return int(min(hi, max(lo, 1 << max(0, math.ceil(math.log2(rate * FRAME_CHUNK_SECONDS))))))


def is_run_store(path) -> bool:
    """True if `path` is a run store taimill wrote: a zarr group whose attributes hold
    the schema_version and config ZarrSink.start writes first (also a killed or
    unfinished run's). Read from zarr.json itself: no zarr error to sort out for a
    folder of other files."""
    try:
        meta = json.loads((Path(path) / "zarr.json").read_text())
        attrs = meta.get("attributes") or {}
        return meta.get("node_type") == "group" and {"schema_version", "config"} <= set(attrs) and "kind" not in attrs
    except (OSError, ValueError, AttributeError, TypeError):
        return False


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
            if JOURNAL in self.group:  # a group reused for a new run
                del self.group[JOURNAL]

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
                write_spectra(self.group, self.last_spectra, CODECS)
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
                        write_spectra(self.group, self.last_spectra, CODECS)
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


def _local_path(store, key: str) -> Path | None:
    """The file of `key` if `store` is a local directory store, else None."""
    root = getattr(store, "root", None)
    if not isinstance(store, LocalStore) or root is None:
        return None
    return Path(root) / key


@contextmanager
def _atomic_file(path: Path):
    """A new file that replaces `path` once written whole (as zarr's LocalStore does:
    a reader or a killed writer sees the old file or the new one). Its directory is
    made if missing (a new chunk row of a 3-D array): asking first would cost a
    system call per file."""
    tmp = path.with_name(f"{path.name}.{uuid.uuid4().hex}.partial")
    try:
        try:
            f = open(tmp, "wb")
        except FileNotFoundError:
            path.parent.mkdir(parents=True, exist_ok=True)
            f = open(tmp, "wb")
        with f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def put_all(items: list[tuple[object, str, bytes]]) -> None:
    """Store each (store, key, bytes). A local store's files are written here, each
    atomically: through zarr each costs ≈ 1 ms of event-loop and thread hand-over
    (measured with 16384-row chunks); others go through zarr, concurrently."""
    remote = []
    for store, key, data in items:
        path = _local_path(store, key)
        if path is None:
            remote.append(store.set(key, default_buffer_prototype().buffer.from_bytes(data)))
            continue
        with _atomic_file(path) as f:
            f.write(data)
    if remote:
        async def gather():
            await asyncio.gather(*remote)

        sync(gather())


def put_npz(store, key: str, arrays: dict[str, np.ndarray]) -> None:
    """Store `arrays` under `key` as a NumPy .npz (what np.savez writes, read by np.load),
    atomically. In a local store the file is written in place of a temporary one,
    each C-contiguous array straight from its memory: np.savez into memory would copy
    every array three times (a journal segment of a dense trajectory is ≈ 20 MB)."""
    path = _local_path(store, key)
    if path is None:
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        sync(store.set(key, default_buffer_prototype().buffer.from_bytes(buf.getvalue())))
        return
    with _atomic_file(path) as raw:
        with zipfile.ZipFile(raw, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, a in arrays.items():
                a = np.asarray(a)
                with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                    header = np.lib.format.header_data_from_array_1_0(a)
                    if a.flags.c_contiguous and not a.dtype.hasobject and len(repr(header)) < 60000:
                        np.lib.format.write_array_header_1_0(f, header)
                        f.write(a.reshape(-1).view(np.uint8))
                    else:
                        np.lib.format.write_array(f, a, allow_pickle=False)


def committed_rows(group: zarr.Group, table: str) -> int:
    """Committed row count of a table: its `n_valid` and the journal's rows after them;
    0 if the writer died before creating it. StoreError for a damaged store."""
    return RunStore(group).check().rows.get(table, 0)


def location(group: zarr.Group) -> str:
    """Where a group is, for messages: its store's directory and its path inside it."""
    root = getattr(group.store, "root", None)
    base = str(root) if root is not None else str(group.store)
    return str(Path(base) / group.path) if group.path else base


def why(err: BaseException) -> str:
    text = " ".join(f"{type(err).__name__}: {err}".split())
    return text if len(text) <= 160 else text[:157] + "..."


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _stored_keys(store, prefix: str) -> set[str]:
    """Every key under `prefix` in a zarr store (one listing)."""
    async def collect():
        return {k async for k in store.list_prefix(prefix)}

    return sync(collect())


def _chunk_key(arr: zarr.Array, i: int) -> str:
    return f"{arr.path}/{arr.metadata.encode_chunk_key((i,) + (0,) * (arr.ndim - 1))}"


def read_rows(arr: zarr.Array, n: int, where: str, part: str) -> np.ndarray:
    """arr[:n]; a chunk that does not decode raises StoreError naming it."""
    try:
        return arr[:n]
    except Exception:
        size = arr.chunks[0]
        for i in range(-(-n // size)):
            try:
                arr[i * size:min(n, (i + 1) * size)]
            except Exception as err:
                # zarr's Crc32cCodec raises ValueError("Stored and computed checksum do not match ...")
                if "checksum" in str(err):
                    raise StoreError(where, part, f"chunk {i} fails its checksum (its bytes changed after "
                                                  "they were written)") from None
                raise StoreError(where, part, f"chunk {i} unreadable ({why(err)})") from None
        raise


_ATTR_TYPES = {"schema_version": int, "n_balls": int, "status": str, "config": dict, "summary": dict,
               "analysis_window": list, "radii": list}


class RunStore:
    """Read-only view of a run written by `ZarrSink`, each table sliced to its `n_valid`.

    Works on the store of a killed writer: uncommitted rows are ignored, and attributes
    the writer never reached read as None. `open_run` checks the store first (`check`)."""

    def __init__(self, group: zarr.Group, where: str | None = None):
        self.group = group
        self.where = where or location(group)
        self.attrs = group.attrs.asdict()
        self.n_valid: dict[str, int] = {}  #: rows committed in the arrays
        self.rows: dict[str, int] = {}  #: rows committed in the arrays and the journal
        self.columns: dict[str, dict[str, Column]] = {}
        self.journal_rows: dict[str, list[dict[str, np.ndarray]]] = {}
        self.warnings: list[str] = []  #: what `check` found odd but not damage (also printed on stderr)

    def _bad(self, part: str, why: str):
        raise StoreError(self.where, part, why)

    def check(self) -> "RunStore":
        """Raise StoreError for what would otherwise read wrongly (module doc): attributes
        of the wrong type; a table or array missing from a store whose writer finished;
        n_valid beyond the arrays; chunks missing below n_valid; tables that disagree with
        the summary of a writer that flushed everything."""
        for key, kind in _ATTR_TYPES.items():
            v = self.attrs.get(key)
            if v is not None and (not isinstance(v, kind) or isinstance(v, bool)):
                self._bad(f"attrs.{key}", f"{_short(v)} is not a {kind.__name__}")
        if self.n_balls < 0:
            self._bad("attrs.n_balls", f"{self.n_balls} is negative")
        part = "radii" if "radii" in self.group else "attrs.radii"
        try:
            radii = self.radii
        except Exception as err:
            self._bad(part, "chunk 0 fails its checksum (its bytes changed after they were written)"
                      if "checksum" in str(err) else f"unreadable ({why(err)})")
        if radii.shape != (self.n_balls,) or not (np.isfinite(radii) & (radii > 0)).all():
            self._bad(part, f"{_short(radii.tolist())} is not {self.n_balls} positive radii (m)")
        window = self.analysis_window
        if window is not None and (len(window) != 2 or not all(isinstance(x, (int, float)) for x in window)):
            self._bad("attrs.analysis_window", f"{_short(window)} is not [start, end] (s)")
        if (self.schema_version or 0) > SCHEMA_VERSION:
            self._bad("attrs.schema_version", f"{self.schema_version}: this taimill reads versions up to {SCHEMA_VERSION}")
        finished = self.summary is not None and not str(self.status).startswith("failed")
        for table, columns in layout(self.n_balls).items():
            self._check_table(table, columns, finished)
        self.rows = dict(self.n_valid)
        self._fold_journal(stale=str(self.status).startswith(FLUSHED) and self.summary is not None)
        if not finished and not self.attrs.get("energy_source"):
            self._cut_to_whole_frames()
        self._check_summary()
        self._check_config()
        return self

    def _check_config(self) -> None:
        """The arrays against the stored config: the balls' count and radius, and the
        frames that its duration and trajectory_rate give (as `model.spec` steps them:
        one every round(1 / (rate dt)) steps, at both ends), within one frame. A killed
        run has fewer (its status says so); only more frames than possible, or fewer in
        a complete run, are damage. A live recording (live_start_time) lasts as long as
        it was recorded, an import (energy_source) as its dumps: no frame count."""
        config = self.config
        if not isinstance(config, dict):
            return
        balls = config.get("balls")
        if isinstance(balls, dict):
            count, radius = balls.get("count"), balls.get("radius")
            if _is_number(count) and count != self.n_balls:
                self._bad("attrs.n_balls", f"{self.n_balls} balls, but the stored config has {count}")
            if _is_number(radius) and radius > 0:
                radii = self.radii
                off = np.flatnonzero(~np.isclose(radii, radius, rtol=1e-9, atol=0.0))
                if off.size:
                    i = int(off[0])
                    self._bad("radii" if "radii" in self.group else "attrs.radii",
                              f"ball {i} has radius {radii[i]:g} m, but the stored config's balls are {radius:g} m"
                              f"{f' ({off.size} balls differ)' if off.size > 1 else ''}")
        if "live_start_time" in config or self.attrs.get("energy_source"):
            return
        rate, duration, dt = config.get("trajectory_rate"), config.get("duration"), config.get("dt")
        if not all(_is_number(x) and math.isfinite(x) and x > 0 for x in (rate, duration, dt)):
            return
        every = max(1, round(1.0 / (rate * dt)))
        frames = max(1, round(duration / (every * dt))) + 1
        n = self.rows.get("trajectory", 0)
        said = f"{duration:g} s at {rate:g} frames/s (dt {dt:g} s) give {frames}"
        if n > frames + 1:
            self._bad("trajectory", f"{n} committed frames, but the stored config's {said}")
        if self.status == "complete" and n < frames - 1:
            self._bad("trajectory", f"{n} committed frames in a complete run, but the stored config's {said}")

    def _cut_to_whole_frames(self) -> None:
        """A frame is committed once its trajectory row and its ledger row are: each
        table commits through its own `n_valid` when a chunk lands, so a writer killed
        between the two leaves one of them up to a launch ahead (a dense trajectory,
        whose every launch lands a chunk; tests/test_store.py). Both are read up to
        the frames they share."""
        n = min(self.rows.get("trajectory", 0), self.rows.get("energy", 0))
        for table in ("trajectory", "energy"):
            if self.rows.get(table, 0) <= n:
                continue
            self.rows[table] = n
            self.n_valid[table] = min(self.n_valid[table], n)
            kept, left = [], n - self.n_valid[table]
            for block in self.journal_rows.get(table, []):
                m = min(left, len(next(iter(block.values()))))
                if m:
                    kept.append({k: v[:m] for k, v in block.items()})
                left -= m
            self.journal_rows[table] = kept

    def _fold_journal(self, stale: bool = False) -> None:
        """Rows of the journal segments that continue each table after its n_valid
        (module doc); a segment past a gap (a writer's deleted segment seen by a
        reader of a live store) and everything after it are left out. `stale`: the
        writer flushed every row into the arrays and deleted its journal, so a segment
        still there is a leftover (a copy over the store, a failed delete): not read,
        and named in a warning line on stderr, as reading on silently would hide it."""
        prefix = f"{self.group.path}/{JOURNAL}/".lstrip("/")
        keys = sorted(k for k in _stored_keys(self.group.store, prefix) if k.endswith(".npz"))
        self.journal_rows = {table: [] for table in self.columns}
        if stale and keys:
            names = ", ".join(k[len(self.group.path):].lstrip("/") for k in keys[:3])
            more = f" and {len(keys) - 3} more" if len(keys) > 3 else ""
            self.warnings.append(f"{self.where}: {names}{more}: stale journal of a writer that finished "
                                 f"({self.status}); its rows are not read")
            print(f"taimill: warning: {self.warnings[-1]}", file=sys.stderr)
            return
        for key in keys:
            part = key[len(self.group.path):].lstrip("/")
            try:
                raw = sync(self.group.store.get(key, prototype=default_buffer_prototype()))
                with np.load(io.BytesIO(raw.to_bytes()), allow_pickle=False) as z:
                    segment = {name: z[name] for name in z.files}
            except Exception as err:
                self._bad(part, f"unreadable ({why(err)})")
            for table, columns in self.columns.items():
                if f"{table}/start" not in segment:
                    continue
                start = int(segment[f"{table}/start"])
                cols = {}
                for k, c in columns.items():
                    v = segment.get(f"{table}/{k}")
                    if v is None or v.dtype != np.dtype(c.dtype) or v.shape[1:] != c.row_shape:
                        self._bad(part, f"{table}/{k}: missing or not rows of shape {c.row_shape}, dtype {c.dtype}")
                    cols[k] = v
                m = len(next(iter(cols.values()))) if cols else 0
                if any(len(v) != m for v in cols.values()):
                    self._bad(part, f"{table}: columns differ in length")
                n = self.rows[table]
                if start > n or start + m <= n:
                    continue  # past a gap, or rows the arrays hold already
                self.journal_rows[table].append({k: v[n - start:] for k, v in cols.items()})
                self.rows[table] = start + m

    def _check_table(self, table: str, columns: dict[str, Column], finished: bool) -> None:
        try:
            present = table in self.group
            g = self.group[table] if present else None
        except Exception as err:
            self._bad(table, f"metadata unreadable ({why(err)})")
        if g is None:
            if finished:
                self._bad(table, "missing (its writer finished, so it was there)")
            self.n_valid[table], self.columns[table] = 0, columns
            return
        n = g.attrs.get("n_valid", 0)
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            self._bad(f"{table}/n_valid", f"{_short(n)} is not a row count")
        every_chunk = g.attrs.get("every_chunk_stored") is True
        keys = None
        self.columns[table] = {}
        for k, c in columns.items():
            part = f"{table}/{k}"
            try:
                arr = g[k]
            except KeyError:
                if (self.schema_version or SCHEMA_VERSION) < 2 and k in ADDED_IN_2:
                    continue  # a version-1 store: readers skip the column
                self._bad(part, "missing")
            except Exception as err:
                self._bad(part, f"metadata unreadable ({why(err)})")
            if not isinstance(arr, zarr.Array) or arr.shape[1:] != c.row_shape or arr.dtype != np.dtype(c.dtype):
                what = f"shape {arr.shape}, dtype {arr.dtype}" if isinstance(arr, zarr.Array) else "a group"
                self._bad(part, f"{what}; expected rows of shape {c.row_shape}, dtype {c.dtype}")
            if arr.shape[0] < n:
                self._bad(part, f"{arr.shape[0]} rows but n_valid = {n}")
            # a missing chunk reads as the fill value: NaN (never written by a run) for
            # floats; for integers only a store that writes every chunk can tell
            if n and (every_chunk or arr.dtype.kind == "f"):
                keys = _stored_keys(self.group.store, f"{g.path}/") if keys is None else keys
                size = arr.chunks[0]
                missing = [i for i in range(-(-n // size)) if _chunk_key(arr, i) not in keys]
                if missing:
                    i = missing[0]
                    self._bad(part, f"chunk {i} missing (rows {i * size}–{min(n, (i + 1) * size) - 1} of the "
                                    f"{n} committed{f'; {len(missing)} chunks missing' if len(missing) > 1 else ''})")
            self.columns[table][k] = c
        self.n_valid[table] = n

    def _check_summary(self) -> None:
        status, s = str(self.status), self.summary
        if s is None or not status.startswith(FLUSHED):
            return
        total = s.get("events_total")
        rows_kept = (self.config or {}).get("events_output", "rows") == "rows"  # else the spectra only
        if rows_kept and isinstance(total, int) and total != self.rows["events"]:
            self._bad("events", f"{self.rows['events']} committed rows, but the summary counts {total} events")
        # a store whose writer had no ledger to write says why in `energy_source` (an
        # import from another DEM code): its empty energy table is not damage
        if self.rows["energy"] != self.rows["trajectory"] and not self.attrs.get("energy_source"):
            self._bad("energy", f"{self.rows['energy']} committed rows for {self.rows['trajectory']} frames")
        sim, dt = s.get("sim_seconds"), s.get("dt")
        if status == "complete" and isinstance(sim, (int, float)) and isinstance(dt, (int, float)):
            n = self.rows["trajectory"]
            if not n:
                self._bad("trajectory", f"no committed frame, but the run is complete at {sim:g} s")
            t = float(self.column("trajectory", "time")[-1])
            if not abs(t - sim) <= 1.5 * dt:
                self._bad("trajectory", f"ends at t = {t:g} s, but the complete run reached {sim:g} s")

    @property
    def schema_version(self) -> int | None:
        return self.attrs.get("schema_version")

    @property
    def config(self) -> dict | None:
        return self.attrs.get("config")

    @property
    def summary(self) -> dict | None:
        return self.attrs.get("summary")

    @property
    def status(self) -> str | None:
        return self.attrs.get("status")

    @property
    def analysis_window(self) -> list[float] | None:
        """[start, end] (s) of the window the writer's summary covers; None before it finished."""
        return self.attrs.get("analysis_window")

    @property
    def n_balls(self) -> int:
        return self.attrs.get("n_balls", 0)

    @property
    def radii(self) -> np.ndarray:
        """Ball radii (m): the `radii` array (schema 2 and older: attrs.radii)."""
        if "radii" in self.group:
            return np.asarray(self.group["radii"][:], dtype=float)
        radii = self.attrs.get("radii", [])
        if not isinstance(radii, list) or not all(isinstance(r, (int, float)) and not isinstance(r, bool) for r in radii):
            raise ValueError(f"{_short(radii)} is not a list of numbers")
        return np.asarray(radii, dtype=float)

    @cached_property
    def frames(self) -> dict[str, np.ndarray]:
        """time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s (velocities
        relative to the jar frame, see `conventions`); the jar frame's drive per frame:
        plate_angle, jar_angle (rad), plate_speed, jar_spin (rad/s)."""
        return self._table("trajectory")

    @cached_property
    def spectra(self):
        """The run's energy spectra (taimill.model.spectra.Spectra): the stored group
        (written when the run ends), else binned from the event rows over the analysis
        window (a run killed before its end), else None."""
        try:
            stored = read_spectra(self.group)
        except (KeyError, ValueError, TypeError) as err:
            self._bad(SPECTRA, f"unreadable ({err})")
        if stored is not None:
            return stored
        if "events" not in self.group:
            return None
        start = float((self.analysis_window or [(self.config or {}).get("analysis_start", 0.0)])[0])
        return from_rows(self.events, start, math.inf, STRESS_MIN_UN)

    @cached_property
    def events(self) -> dict[str, np.ndarray]:
        """One array per `EVENT_COLUMNS` entry."""
        return self._table("events")

    @cached_property
    def energy(self) -> dict[str, np.ndarray]:
        """One array per `ENERGY_COLUMNS` entry (J, time in s)."""
        return self._table("energy")

    def _table(self, name: str) -> dict[str, np.ndarray]:
        if name not in self.rows:
            self.check()
        return {k: self.column(name, k) for k in self.columns[name]}

    def column(self, table: str, name: str) -> np.ndarray:
        """The committed rows of one column: the array's n_valid rows, then the journal's."""
        if table not in self.rows:
            self.check()
        n, c = self.n_valid[table], self.columns[table][name]
        rows = read_rows(self.group[table][name], n, self.where, f"{table}/{name}") if n else np.zeros((0, *c.row_shape), dtype=c.dtype)
        extra = [b[name] for b in self.journal_rows.get(table, [])]
        return np.concatenate([rows, *extra]) if extra else rows


def open_run(path_or_group) -> RunStore:
    """Open a run store (path opened read-only, or a `zarr.Group`) for reading, checked
    (`RunStore.check`): StoreError names what is damaged."""
    if isinstance(path_or_group, zarr.Group):
        return RunStore(path_or_group).check()
    where = str(path_or_group)
    if not os.path.exists(where):
        raise StoreError(where, "store", "no such file or directory")
    try:
        group = zarr.open_group(path_or_group, mode="r")
    except Exception as err:
        raise StoreError(where, "zarr.json", f"not a taimill run store, or its metadata is damaged ({why(err)})") from None
    return RunStore(group, where).check()


def _as_group(path_or_group, mode: str) -> zarr.Group:
    if isinstance(path_or_group, zarr.Group):
        return path_or_group
    return zarr.open_group(path_or_group, mode=mode)


def trim_to_valid(path_or_group) -> None:
    """Shrink every array of every table back to the table's `n_valid` rows, dropping
    what a killed writer appended without committing (before re-running into the store)."""
    group = _as_group(path_or_group, "r+")
    for table, columns in layout(0).items():
        if table not in group:
            continue
        n = int(group[table].attrs.get("n_valid", 0))
        arrays = [group[table][k] for k in columns if k in group[table]]
        for arr in arrays:
            if arr.shape[0] > n:
                arr.resize((n, *arr.shape[1:]))
