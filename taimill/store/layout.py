"""What a run store holds (zarr v3, docs/outputs.md): its tables and their columns,
the codecs of every array, and the values a writer and a reader share.

One run group:

    attrs: schema_version, config, n_balls, status, summary, analysis_window (s)
    radii        (N,) ball radii, m (schema 2 and older: attrs.radii)
    trajectory/  time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s
    events/      one 1-D array per `EVENT_COLUMNS` entry
    energy/      one 1-D array per `ENERGY_COLUMNS` entry
    spectra/     the events' energy spectra over the analysis window (store/spectra.py),
                 written when the run ends, and rewritten in place at every commit
                 by a run that stores no event rows (config events_output = "spectra")
    journal/     while the writer runs: NNNNNNNN.npz, the rows committed since the last
                 whole chunk of each table

`taimill.store.writer.ZarrSink` writes it, crash-safe; `taimill.store.run.open_run`
reads and checks it.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from zarr.codecs import BloscCodec, Crc32cCodec

from taimill.schema import DRIVE_FIELDS, ENERGY_COLUMNS, EVENT_COLUMNS, FRAME_COLUMNS, MECHANISM_COLUMNS, PER_BALL

SCHEMA_VERSION = 3
# Columns a version-1 store lacks (read as absent from such a store): the frame's
# drive and the dissipation by mechanism.
ADDED_IN_2 = frozenset(DRIVE_FIELDS) | frozenset(MECHANISM_COLUMNS)
# Rows committed between whole chunks (taimill.store.writer): one .npz per commit in this group.
JOURNAL = "journal"
JOURNAL_DESCRIPTION = ("rows committed since the last whole chunk of each table, one NumPy .npz per commit "
                       "(TABLE/start, TABLE/COLUMN); readers append them after n_valid; deleted when the writer finishes")
# Trajectory and energy rows per chunk when the sink is not told (ZarrSink): about
# FRAME_CHUNK_SECONDS of simulated frames at the run's trajectory_rate, within these
# bounds. zarr costs ≈ 2 ms per chunk of every array whatever its size (scripts/bench.py
# --only dense): at 10⁵ frames/s, 1024-row chunks of the 30-odd frame and ledger arrays
# cost 70 µs per frame, ten times the simulation; 65536-row chunks ≈ 2 µs. The sink now
# stores chunks itself (`chunks._ChunkWriter`), but readers still pay zarr's cost per chunk and
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
# that `chunks.read_rows` names. Stores written before it carry no checksum and read as before.
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


def is_unstarted_store(path) -> bool:
    """True if `path` is a zarr group that holds nothing: its zarr.json alone, without
    attributes (what an older taimill left when a run was refused after its store was
    created, e.g. balls that do not fit; replacing it loses nothing)."""
    try:
        entries = [e.name for e in Path(path).iterdir()]
        meta = json.loads((Path(path) / "zarr.json").read_text())
        return entries == ["zarr.json"] and meta.get("node_type") == "group" and not meta.get("attributes")
    except (OSError, ValueError, AttributeError, TypeError):
        return False


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
