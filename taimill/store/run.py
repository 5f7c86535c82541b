"""Zarr v3 storage of a run: `ZarrSink` writes the stream of `taimill.store.sinks`, `open_run` reads it.

Layout of one run group (docs/outputs.md):

    attrs: schema_version, config, n_balls, radii (m), status, summary, analysis_window (s)
    trajectory/  time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s
    events/      one 1-D array per `EVENT_COLUMNS` entry
    energy/      one 1-D array per `ENERGY_COLUMNS` entry

Crash safety (zarr 3.1, tests/test_store.py): every key is written atomically, but an append resizes an
array before its data lands. So each table group carries an attribute `n_valid`, written
only after every array of the table holds its rows; readers slice to it and a restarted
writer trims back to it (`trim_to_valid`). A SIGKILL at any moment leaves a readable store.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import zarr

from taimill.schema import (DRIVE_FIELDS, ENERGY_COLUMNS, EVENT_COLUMNS, FRAME_COLUMNS, MECHANISM_COLUMNS, PER_BALL,
                            VELOCITY_CONVENTION)

SCHEMA_VERSION = 2
# Columns a version-1 store lacks (read as absent from such a store): the frame's
# drive and the dissipation by mechanism.
ADDED_IN_2 = frozenset(DRIVE_FIELDS) | frozenset(MECHANISM_COLUMNS)


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

    Rows are buffered until the buffer reaches a chunk boundary, then written in
    chunk-aligned pieces; at most one chunk of rows stays buffered between calls."""

    def __init__(self, parent: zarr.Group, name: str, columns: dict[str, Column], chunk: int):
        self.name, self.columns, self.chunk = name, columns, chunk
        self.group = parent.create_group(
            name, overwrite=True, attributes={"n_valid": 0, "description": TABLE_DESCRIPTIONS[name]}
        )
        self.arrays = {k: self._create(k, c) for k, c in columns.items()}
        self.committed = 0
        self.pending: dict[str, list[np.ndarray]] = {k: [] for k in columns}
        self.n_pending = 0

    def _create(self, name: str, c: Column) -> zarr.Array:
        return self.group.create_array(
            name,
            shape=(0, *c.row_shape),
            chunks=(self.chunk, *c.row_shape),
            dtype=c.dtype,
            fill_value=np.nan if c.dtype.startswith("f") else 0,
            dimension_names=c.dims,
            attributes={"units": c.units, "description": c.description},
        )

    def add(self, block: dict) -> None:
        """Validate and buffer one block; write whatever completes a chunk."""
        rows = self._validated(block)
        for k, v in rows.items():
            self.pending[k].append(v)
        self.n_pending += len(next(iter(rows.values())))
        total = self.committed + self.n_pending
        self._write(total // self.chunk * self.chunk - self.committed)

    def flush(self) -> None:
        """Write and commit every buffered row."""
        self._write(self.n_pending)

    def _validated(self, block: dict) -> dict[str, np.ndarray]:
        check_columns(block, self.columns, self.name)
        rows = {}
        for k, c in self.columns.items():
            v = np.asarray(block[k])
            try:  # astype copies: the caller may reuse its arrays while rows wait here
                rows[k] = v.astype(c.dtype, casting="same_kind")
            except TypeError as e:
                raise ValueError(f"{self.name} column {k!r}: {e}") from None
            if v.ndim != 1 + len(c.row_shape) or v.shape[1:] != c.row_shape:
                expected = ("rows", *c.row_shape)
                raise ValueError(f"{self.name} column {k!r}: shape {v.shape}, expected {expected}")
        if len({v.shape[0] for v in rows.values()}) > 1:
            lengths = {k: v.shape[0] for k, v in rows.items()}
            raise ValueError(f"{self.name} block: columns differ in length {lengths}")
        return rows

    def _write(self, n: int) -> None:
        """Append the first `n` buffered rows to every array, then commit them."""
        if n <= 0:
            return
        for k, arr in self.arrays.items():
            data = np.concatenate(self.pending[k])
            arr.append(data[:n], axis=0)
            self.pending[k] = [data[n:]]
        self.n_pending -= n
        self.committed += n
        self.group.attrs["n_valid"] = self.committed


class ZarrSink:
    """Sink writing one run into a zarr v3 group (layout and crash safety: module doc).

    `path_or_group`: a path is opened with mode "w" (a fresh run overwrites it); a
    `zarr.Group` (e.g. one subgroup per sweep point) gets the run's tables, replacing any
    it held. `frame_chunk` rows per chunk for trajectory and energy, `event_chunk` for
    events; rows reach the disk when a chunk fills, on `flush()` and on `finish`."""

    def __init__(self, path_or_group, *, frame_chunk: int = 1024, event_chunk: int = 65536):
        if isinstance(path_or_group, zarr.Group):
            self.group = path_or_group
        else:
            self.group = zarr.open_group(path_or_group, mode="w")
        self.chunks = {"trajectory": frame_chunk, "events": event_chunk, "energy": frame_chunk}
        self.tables: dict[str, _TableWriter] = {}

    def start(self, config: dict, n_balls: int, radii: np.ndarray) -> None:
        """Write the run attributes (config, radii in m) and create the empty tables."""
        radii = np.asarray(radii, dtype=float)
        if radii.shape != (n_balls,):
            raise ValueError(f"radii of shape {radii.shape}, expected ({n_balls},)")
        self.group.attrs.update(
            {
                "schema_version": SCHEMA_VERSION,
                "config": plain(config),
                "n_balls": int(n_balls),
                "radii": radii.tolist(),
                "status": "running",
                "conventions": VELOCITY_CONVENTION,
            }
        )
        self.tables = {
            name: _TableWriter(self.group, name, columns, self.chunks[name])
            for name, columns in layout(n_balls).items()
        }

    def frames(self, block: dict[str, np.ndarray]) -> None:
        """Append frames: time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s."""
        self.tables["trajectory"].add(block)

    def events(self, block: dict[str, np.ndarray]) -> None:
        """Append collision events, one array per `EVENT_COLUMNS` entry."""
        self.tables["events"].add(block)

    def energy(self, block: dict[str, np.ndarray]) -> None:
        """Append energy-ledger rows, one array per `ENERGY_COLUMNS` entry (J, time in s)."""
        self.tables["energy"].add(block)

    def flush(self) -> None:
        """Write and commit every buffered row of every table."""
        for table in self.tables.values():
            table.flush()

    def finish(self, summary: dict, status: str) -> None:
        """Flush, then record `summary`, `status` ("complete", "unstable: …", …) and
        the summary's `analysis_window` ([start, end], s) as the store's own."""
        self.flush()
        attrs = {"summary": plain(summary, "summary"), "status": status}
        if "analysis_window" in summary:
            attrs["analysis_window"] = plain(summary["analysis_window"], "analysis_window")
        self.group.attrs.update(attrs)


def committed_rows(group: zarr.Group, table: str) -> int:
    """Committed row count (`n_valid`) of a table; 0 if the writer died before creating it."""
    return int(group[table].attrs.get("n_valid", 0)) if table in group else 0


def _read_table(group: zarr.Group, table: str, columns: dict[str, Column], version: int | None = None
                ) -> dict[str, np.ndarray]:
    if version is not None and version < 2 and table in group:
        columns = {k: c for k, c in columns.items() if k not in ADDED_IN_2 or k in group[table]}
    n = committed_rows(group, table)
    if n == 0:
        return {k: np.zeros((0, *c.row_shape), dtype=c.dtype) for k, c in columns.items()}
    out = {}
    for k in columns:
        arr = group[table][k]
        if arr.shape[0] < n:
            raise ValueError(f"{table}/{k} has {arr.shape[0]} rows but n_valid = {n}: corrupt store")
        out[k] = arr[:n]
    return out


def _as_group(path_or_group, mode: str) -> zarr.Group:
    if isinstance(path_or_group, zarr.Group):
        return path_or_group
    return zarr.open_group(path_or_group, mode=mode)


class RunStore:
    """Read-only view of a run written by `ZarrSink`, each table sliced to its `n_valid`.

    Works on the store of a killed writer: uncommitted rows are ignored, and attributes
    the writer never reached read as None."""

    def __init__(self, group: zarr.Group):
        self.group = group
        self.attrs = group.attrs.asdict()

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
        """Ball radii (m)."""
        return np.asarray(self.attrs.get("radii", []), dtype=float)

    @cached_property
    def frames(self) -> dict[str, np.ndarray]:
        """time (F,) s; position, velocity, spin (F, N, 3) m, m/s, rad/s (velocities
        relative to the jar frame, see `conventions`); the jar frame's drive per frame:
        plate_angle, jar_angle (rad), plate_speed, jar_spin (rad/s)."""
        return self._table("trajectory")

    @cached_property
    def events(self) -> dict[str, np.ndarray]:
        """One array per `EVENT_COLUMNS` entry."""
        return self._table("events")

    @cached_property
    def energy(self) -> dict[str, np.ndarray]:
        """One array per `ENERGY_COLUMNS` entry (J, time in s)."""
        return self._table("energy")

    def _table(self, name: str) -> dict[str, np.ndarray]:
        return _read_table(self.group, name, layout(self.n_balls)[name], self.schema_version)


def open_run(path_or_group) -> RunStore:
    """Open a run store (path opened read-only, or a `zarr.Group`) for reading."""
    return RunStore(_as_group(path_or_group, "r"))


def trim_to_valid(path_or_group) -> None:
    """Shrink every array of every table back to the table's `n_valid` rows, dropping
    what a killed writer appended without committing (before re-running into the store)."""
    group = _as_group(path_or_group, "r+")
    for table, columns in layout(0).items():
        if table not in group:
            continue
        n = committed_rows(group, table)
        arrays = [group[table][k] for k in columns if k in group[table]]
        for arr in arrays:
            if arr.shape[0] > n:
                arr.resize((n, *arr.shape[1:]))
