"""Reading a run store (taimill.store.layout): `open_run` opens it and checks what it
reads (`RunStore.check`): attributes of the wrong type, a table or array missing from a
store whose writer finished, chunks missing below `n_valid`, a chunk or journal file
that does not decode, a chunk that fails its CRC-32C (`layout.CHECKSUM`), tables that
disagree with the summary, or arrays that contradict the stored config (ball count,
radii, frame count) raise `StoreError` naming the store and the part, instead of
reading as fill values or as a complete run; so do a missing or damaged part of the
spectra when they are read (`RunStore.spectra`, store.spectra.read_spectra), and a
finished store whose writer stored spectra but has none. A journal left in a store
whose writer finished is named in a warning and not read. The writer
(taimill.store.writer) says how a store stays readable after a kill: readers slice
each table to its `n_valid` and append the journal's rows. A store read while its
writer commits is read again when the writer changed it under the reader (a journal
segment folded into the arrays and deleted, spectra rewritten).
"""

from __future__ import annotations

import io
import json
import math
import os
import sys
import time
from functools import cached_property
from pathlib import Path

import numpy as np
import zarr
from zarr.core.buffer import default_buffer_prototype
from zarr.core.sync import sync

from taimill.errors import StoreError
from taimill.model import rules
from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.model.spectra import MEASURES, from_rows
from taimill.store.chunks import _chunk_key, location, read_rows, why
from taimill.store.layout import (
    ADDED_IN_2,
    FLUSHED,
    JOURNAL,
    SCHEMA_VERSION,
    Column,
    layout,
)
from taimill.store.spectra import GROUP as SPECTRA
from taimill.store.spectra import Busy, read_spectra


def committed_rows(group: zarr.Group, table: str) -> int:
    """Committed row count of a table: its `n_valid` and the journal's rows after them;
    0 if the writer died before creating it. StoreError for a damaged store."""
    return RunStore(group).check().rows.get(table, 0)


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


# Reads of a store whose writer changed it meanwhile (a journal segment folded into the
# arrays and deleted after it was listed, spectra rewritten while read): tries, and the
# seconds waited before each retry, so that a writer's commit (milliseconds) ends.
READ_TRIES = (0.0, 0.005, 0.02, 0.05, 0.1, 0.2)
# The spectra a writer rewrites in place (store.spectra): read again every SPECTRA_WAIT
# s until read whole; read as they are once their generation stayed odd STALLED_SECONDS
# (a writer killed while rewriting), or after SPECTRA_PATIENCE s.
SPECTRA_WAIT, STALLED_SECONDS, SPECTRA_PATIENCE = 0.005, 0.2, 5.0


class _Moved(Exception):
    """The writer of a live store changed what `check` was reading: read it again."""


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
        the summary of a writer that flushed everything. A store whose writer folded a
        journal segment into the arrays while it was read is read again, from its
        attributes on; after the last try the rows past the change are left out."""
        for i, wait in enumerate(READ_TRIES):
            try:
                return self._check(settled=i == len(READ_TRIES) - 1)
            except _Moved:
                time.sleep(wait)
                self._reopen()
        raise AssertionError("unreachable: the last try is settled")

    def _reopen(self) -> None:
        """Forget what was read: the group's attributes as they are now."""
        self.group = zarr.open_group(self.group.store, path=self.group.path, mode="r")
        self.attrs = self.group.attrs.asdict()
        self.n_valid, self.rows, self.columns, self.journal_rows, self.warnings = {}, {}, {}, {}, []

    def _check(self, settled: bool) -> "RunStore":
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
        if finished and self.spectra_kept and SPECTRA not in self.group:
            self._bad(SPECTRA, "missing (its writer finished, so it was there)")
        self.rows = dict(self.n_valid)
        self._fold_journal(stale=str(self.status).startswith(FLUSHED) and self.summary is not None, settled=settled)
        if not finished and not settled and self._n_valid_moved():
            raise _Moved
        if not finished and not self.attrs.get("energy_source"):
            self._cut_to_whole_frames()
        self._check_summary()
        self._check_config()
        return self

    def _check_config(self) -> None:
        """The arrays against the stored config: the balls' count and radius, and the
        frames that its duration and trajectory_rate give (rules.frame_intervals, with a
        frame at both ends), within one frame. A killed run has fewer (its status says
        so); only more frames than possible, or fewer in a complete run, are damage. A
        live recording (live_start_time) lasts as long as it was recorded, an import
        (energy_source) as its dumps: no frame count."""
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
        frames = rules.frame_intervals(rate, dt, duration) + 1
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

    def _n_valid_moved(self) -> bool:
        """True if a table's n_valid changed since this reader read it: its writer
        committed rows into the arrays meanwhile, and may have deleted the journal that
        held them before this reader listed it (an empty listing shows no gap). Seen at a
        run's end, whose flush writes every row into the arrays and deletes the journal:
        a read then had 249 fewer frames than the read before it."""
        try:
            fresh = zarr.open_group(self.group.store, path=self.group.path, mode="r")
            return any((fresh[table].attrs.get("n_valid", 0) if table in fresh else 0) != n
                       for table, n in self.n_valid.items())
        except Exception:  # half-written metadata: the writer is at it
            return True

    def _fold_journal(self, stale: bool = False, settled: bool = True) -> None:
        """Rows of the journal segments that continue each table after its n_valid
        (module doc). A segment gone when read, or past a gap, was folded into the
        arrays and deleted by the writer after this reader read n_valid: `_Moved`,
        unless `settled` (then it and every row after it are left out). `stale`: the
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
            except FileNotFoundError:
                raw = None
            except Exception as err:
                self._bad(part, f"unreadable ({why(err)})")
            if raw is None:  # listed, then deleted: its rows reached the arrays
                if not settled:
                    raise _Moved
                continue
            try:
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
                if start > n and not settled:
                    raise _Moved
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
        if self.rows_kept and isinstance(total, int) and total != self.rows["events"]:
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

    @property
    def rows_kept(self) -> bool:
        """The run kept one row per event (else only their spectra: outputs.events)."""
        return (self.config or {}).get("events_output", "rows") == "rows"

    @property
    def spectra_kept(self) -> bool:
        """The writer stores the spectra group: a run that keeps no event rows at every
        commit, any run of a taimill with spectra when it finishes (its summary has them)."""
        return not self.rows_kept or "spectra" in (self.summary or {})

    @cached_property
    def spectra(self):
        """The run's energy spectra (taimill.model.spectra.Spectra): the stored group,
        checked (`store.spectra.read_spectra`: StoreError names a missing or damaged
        part), else binned from the event rows over the analysis window (a store of a
        taimill before spectra, or of a run killed before it wrote them). A run that
        kept neither raises StoreError saying so."""
        if not self.rows:
            self.check()
        stored = self._stored_spectra()
        if stored is not None:
            self._check_spectra(stored)
            return stored
        if not self.rows_kept:
            self._bad(SPECTRA, "missing: the run keeps no event rows (outputs.events = \"spectra\") and committed no "
                               "spectra (stopped before its first commit), so there is nothing to bin them from; "
                               "run it again with this version of taimill")
        if "events" not in self.group:
            self._bad(SPECTRA, "missing, and no event rows to bin them from (a run stopped before its first commit): "
                               "run it again with this version of taimill")
        window = self.analysis_window
        start = float(window[0]) if window else float((self.config or {}).get("analysis_start", 0.0))
        frames = self.column("trajectory", "time") if self.rows.get("trajectory") else np.zeros(0)
        end = float(window[1]) if window else float(frames[-1]) if len(frames) else start
        return from_rows(self.events, start, max(start, end), STRESS_MIN_UN)

    def _stored_spectra(self):
        """read_spectra, again while its writer rewrites them (a commit: milliseconds),
        then as they are: a generation left odd that long is a writer killed while
        rewriting; one that kept changing for SPECTRA_PATIENCE s, a writer committing
        faster than they are read."""
        last, stalled, deadline = None, 0.0, time.monotonic() + SPECTRA_PATIENCE
        while True:
            settled = stalled >= STALLED_SECONDS or time.monotonic() > deadline
            try:
                return read_spectra(self.group, self.where, settled=settled)
            except Busy as busy:
                stalled = stalled + SPECTRA_WAIT if busy.generation == last else 0.0
                last = busy.generation
                time.sleep(SPECTRA_WAIT)

    def _check_spectra(self, sp) -> None:
        """The stored spectra against the summary of a writer that finished: its stress
        events per measure (a store written before every spectra chunk was stored reads
        a chunk missing in every array as zero events)."""
        said = (self.summary or {}).get("spectra") if str(self.status).startswith(FLUSHED) else None
        if not isinstance(said, dict):
            return
        for q, measure in enumerate(MEASURES):
            n = (said.get(measure) or {}).get("events") if isinstance(said.get(measure), dict) else None
            got = int(sp.count[:, 0, q].sum())
            if isinstance(n, int) and n != got:
                self._bad(f"{SPECTRA}/count", f"{got} stress events ({measure}), but the summary counts {n}")

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


def holds_a_frame(path) -> bool:
    """True if `path` is a run store taimill wrote that committed anything: a frame in
    the trajectory's arrays, or a journal segment (a launch's rows). What a run stopped
    early keeps; one stopped before its first commit (Ctrl-C while compiling or in the
    first launch, a fault at the first step) holds nothing a reader can use and is
    removed, so that its retry does not meet it. Read from the files themselves, not
    through `open_run`: the finished writer of such a store recorded a summary, and the
    reader calls a finished store without tables damaged (the store was kept so, and
    read as unreadable)."""
    from taimill.store.layout import is_run_store

    if not is_run_store(path):
        return False
    root = Path(path)
    if any((root / JOURNAL).glob("*.npz")):
        return True
    try:
        meta = json.loads((root / "trajectory" / "zarr.json").read_text())
        return int((meta.get("attributes") or {}).get("n_valid", 0)) > 0
    except (OSError, ValueError, TypeError):
        return False
