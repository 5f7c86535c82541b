"""Zarr v3 store of a sweep: one run store per point plus a table of per-point summaries.

Layout:

    attrs:   kind = "sweep", schema_version, sweep (what was asked: preset, overrides,
             axes, replicas — a re-run with the same request resumes), content (what
             the request resolved to: sha256 and parts, see below), plan (per point:
             key, overrides, values), refine (metric, rounds, peaks; after --refine)
    points/p00000, p00001, …   each a normal run store written by store.ZarrSink(group):
                               store.open_run(group) and the analysis work on it
    table/   one 1-D array per column, one row per planned point: `point`, the swept
             values (jar, balls, pair, plate_rpm, ratio, seed, replica), the radii behind
             K_c (plate_radius, jar_radius, ball_radius, m), every scalar of the point's
             summary (integers as i8, other numbers as f8, text as strings), and `done`.

Crash safety (as the run store, run.py): only the process running the sweep writes, and
`writing` makes sure of it (a lock beside the store, taimill.store.output). A point's row
is written after its group is finished, and `done` last; readers use rows with `done`.
A killed sweep re-run with the same request skips every finished point (a point whose
group finished but whose row was not yet marked is re-indexed from the group's summary;
a point group that is damaged is re-run) and re-runs the rest, which is seeded and so
gives the same result, but only if the request still resolves to the same content: the
`content` attribute holds the sha256 of every planned point's resolved configuration
(taimill.runs.sweep.content: the preset's, jar, pair and material files' values, not
their bytes) and the parts that name a change (the preset's, each swept jar's and
pair's); a changed one is refused, naming the part and keys that changed (a store
written before content was recorded resumes unchecked). With overwrite an existing
store is replaced only when the new
sweep has finished (built beside it, then swapped in). Reading names damaged parts
(StoreError): unreadable metadata or chunks, a missing array, group or point.
"""

from __future__ import annotations

import contextlib
import json
import math
from pathlib import Path

import numpy as np
import zarr
from zarr.codecs import ZstdCodec

from taimill.errors import ConfigError, StoreError
from taimill.store.output import Output
from taimill.store.chunks import location, read_rows, why
from taimill.store.layout import CHECKSUM, plain
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink

SCHEMA_VERSION = 1
VALUE_COLUMNS = ("jar", "balls", "pair", "plate_rpm", "ratio", "seed", "replica",
                 "plate_radius", "jar_radius", "ball_radius", "duration")
TABLE_CHUNK = 4096
# The table's arrays: zarr's default compressor (Zstandard), then the CRC-32C of the run
# stores (store.layout.CHECKSUM), so a changed byte is named on read; tables of sweeps
# begun before it carry no checksum and read as before.
TABLE_CODECS = (ZstdCodec(level=0, checksum=False), CHECKSUM)


def point_key(overrides: dict) -> str:
    """Canonical identity of a point: its preset overrides as sorted JSON."""
    return json.dumps(plain(overrides), sort_keys=True)


def is_sweep(path) -> bool:
    """True if `path` is a sweep store (a zarr group with kind = "sweep")."""
    try:
        return zarr.open_group(path, mode="r").attrs.get("kind") == "sweep"
    except (OSError, ValueError):  # missing path, a file, an array (zarr's errors subclass both)
        return False


def _any_done(path) -> bool:
    """Whether a (partial) sweep store holds a finished point."""
    try:
        return bool(np.any(zarr.open_group(path, mode="r")["table"]["done"][:]))
    except Exception:
        return False


@contextlib.contextmanager
def writing(path, request: dict, content: dict | None = None, *, overwrite: bool = False, inputs=()):
    """The store for `request` at `path` (`SweepStore.create`), locked for this process
    while the block runs (a second writer is refused, naming this one). An existing
    path that is not a sweep store, or is one of the command's `inputs` or holds one,
    is refused, --overwrite or not (output.Output). Without overwrite an existing store
    of the same request and `content` is resumed in place. With it an
    existing store stays untouched until the block ends without error: the new sweep
    is built beside it (SWEEP.partial-PID.zarr) and then swapped in. A sweep that fails
    or is interrupted leaves the old store as it was and keeps the partial one beside it
    if it finished a point (else deletes it); the error says where things are."""
    with Output(path, overwrite=overwrite, reuse=True, what="sweep", kind="sweep store", ours=is_sweep,
                keep=_any_done, inputs=inputs) as out:
        yield SweepStore.create(out.build, request, content, overwrite=out.replacing)
        out.commit()


class SweepStore:
    """A sweep store open for writing (`create`, `writing`) or reading (`open_sweep`)."""

    def __init__(self, root: zarr.Group, where: str | None = None):
        self.root = root
        self.where = where or location(root)

    # ---------------------------------------------------------------- opening
    @classmethod
    def create(cls, path, request: dict, content: dict | None = None, *, overwrite: bool = False) -> "SweepStore":
        """A new store for `request`, or the existing one for the same request and
        content (resume; module doc). An existing store of another sweep needs
        overwrite; anything else at `path` is the caller's to refuse (`writing`)."""
        path = Path(path)
        request = plain(request)
        if is_sweep(path) and not overwrite:
            old = open_sweep(path, mode="r+")
            if old.request != request:
                changed = sorted(k for k in set(request) | set(old.request) if request.get(k) != old.request.get(k))
                raise ConfigError("command line", "--out", str(path),
                                  f"holds a different sweep ({', '.join(changed)} differ); pass --overwrite to replace it, or resume it with the same arguments")
            before = old.root.attrs.get("content")
            if content is not None and before is not None and before.get("sha256") != content["sha256"]:
                raise StoreError(path, "resume", f"{changes(before, plain(content))}; pass --overwrite to start the "
                                 "sweep again, or restore what changed to resume it")
            return old
        root = zarr.open_group(path, mode="w")
        root.attrs.update({"kind": "sweep", "schema_version": SCHEMA_VERSION, "sweep": request, "plan": []}
                          | ({"content": plain(content)} if content is not None else {}))
        root.create_group("points")
        table = root.create_group("table", attributes={"description": "one row per planned point; rows with done = true are valid"})
        table.create_array("done", shape=(0,), chunks=(TABLE_CHUNK,), dtype=bool, fill_value=False, dimension_names=("point",),
                           compressors=TABLE_CODECS)
        return cls(root)

    @property
    def request(self) -> dict:
        return self.root.attrs.get("sweep", {})

    @property
    def plan(self) -> list[dict]:
        return self.root.attrs.get("plan", [])

    # ---------------------------------------------------------------- planning
    def add_points(self, points: list[dict]) -> list[int]:
        """Indices of `points` ({overrides, values}) in the plan, appending new ones."""
        plan = self.plan
        index = {p["key"]: i for i, p in enumerate(plan)}
        out = []
        for p in points:
            key = point_key(p["overrides"])
            if key not in index:
                index[key] = len(plan)
                plan.append({"key": key, "overrides": plain(p["overrides"]), "values": plain(p["values"])})
            out.append(index[key])
        table = self.root["table"]
        for name in table.array_keys():  # grow first: new rows read as fill (not done)
            if table[name].shape[0] < len(plan):
                table[name].resize((len(plan),))
        self.root.attrs["plan"] = plan
        return out

    def done(self) -> set[int]:
        """Finished points; re-indexes points whose group finished before their row
        (only when the store is open for writing: a reader of a sweep still being
        written by another process just sees the rows committed so far)."""
        flags = self.root["table"]["done"][:]
        if self.root.store.read_only:
            return {int(i) for i in np.flatnonzero(flags)}
        finished = {int(i) for i in np.flatnonzero(flags)}
        points = self.root["points"]
        for i in range(len(self.plan)):
            name = _name(i)
            if i in finished or name not in points:
                continue
            try:
                run = open_run(points[name])
            except StoreError:
                continue  # damaged: run it again
            if run.summary is not None and run.status not in (None, "running") and not run.status.startswith("failed"):
                self._write_row(i, run.summary)
                finished.add(i)
        return finished

    # ---------------------------------------------------------------- writing
    def write_point(self, result) -> None:
        """Store one sweep_exec.PointResult: its run group, then its table row."""
        group = self.root["points"].require_group(_name(result.index))
        sink = ZarrSink(group, commit_every=math.inf)  # all rows at once: no journal commits
        sink.start(result.config, result.n_balls, result.radii)
        if result.tables is not None:
            for table, write in (("frames", sink.frames), ("events", sink.events), ("energy", sink.energy)):
                if result.tables[table] is not None:
                    write(result.tables[table])
        if getattr(result, "spectra", None) is not None:
            sink.spectra(result.spectra)
        sink.finish(result.summary, result.status)
        self._write_row(result.index, result.summary)

    def _write_row(self, i: int, summary: dict) -> None:
        row = {"point": i, **scalars(summary), **self.plan[i]["values"]}  # the swept values as asked
        table = self.root["table"]
        n = len(self.plan)
        for name, value in row.items():
            if name not in table:
                dtype, fill = (str, "") if isinstance(value, str) else ("i8", -1) if isinstance(value, int) else ("f8", np.nan)
                table.create_array(name, shape=(n,), chunks=(TABLE_CHUNK,), dtype=dtype, fill_value=fill,
                                   dimension_names=("point",), compressors=TABLE_CODECS)
            table[name][i] = value
        table["done"][i] = True

    def set_refine(self, info: dict) -> None:
        self.root.attrs["refine"] = plain(info)

    # ---------------------------------------------------------------- reading
    def table(self) -> dict[str, np.ndarray]:
        """Columns over the finished points, in plan order (StoreError names a damaged column)."""
        t = self._member("table")
        done = self._column("done")
        rows = np.flatnonzero(done)
        try:
            names = sorted(t.array_keys())
        except Exception as err:
            raise StoreError(self.where, "table", f"metadata unreadable ({why(err)})") from None
        out = {}
        for name in names:
            if name != "done":
                column = self._column(name)
                if len(column) != len(done):
                    raise StoreError(self.where, f"table/{name}", f"{len(column)} rows, but done has {len(done)}")
                out[name] = np.asarray(column)[rows]
        return out

    def _member(self, path: str):
        try:
            return self.root[path]
        except KeyError:
            raise StoreError(self.where, path, "missing") from None
        except Exception as err:
            raise StoreError(self.where, path, f"metadata unreadable ({why(err)})") from None

    def _column(self, name: str) -> np.ndarray:
        arr = self._member(f"table/{name}")
        if not isinstance(arr, zarr.Array) or arr.ndim != 1:
            raise StoreError(self.where, f"table/{name}", "not a 1-D array")
        return read_rows(arr, arr.shape[0], self.where, f"table/{name}")

    def point(self, i: int):
        """The run store (store.RunStore) of point i, checked (StoreError names damage)."""
        return open_run(self._member(f"points/{_name(i)}"))

    def spectra(self, i: int):
        """The energy spectra (taimill.model.spectra.Spectra) of point i, or None."""
        return self.point(i).spectra

    @property
    def refine(self) -> dict | None:
        return self.root.attrs.get("refine")


def open_sweep(path, mode: str = "r") -> SweepStore:
    if not is_sweep(path):
        raise ConfigError("command line", "sweep store", str(path), "is not a sweep store (made by taimill sweep --out)")
    store = SweepStore(zarr.open_group(path, mode=mode), str(path))
    plan = store.root.attrs.get("plan")
    if not isinstance(plan, list) or not all(isinstance(p, dict) and {"key", "overrides", "values"} <= set(p) for p in plan):
        raise StoreError(path, "attrs.plan", "not a list of planned points (key, overrides, values)")
    return store


def changes(before: dict, now: dict, shown: int = 3) -> str:
    """What differs between two `content` attributes, for the refusal to resume:
    "preset P changed since the sweep started: balls.count 12 → 24, …" for the first
    part that changed (parts: label → {key: value}); the points as a whole otherwise."""
    old_parts, new_parts = before.get("parts", {}), now.get("parts", {})
    for label in dict.fromkeys([*new_parts, *old_parts]):
        a, b = old_parts.get(label, {}), new_parts.get(label, {})
        keys = [k for k in dict.fromkeys([*b, *a]) if a.get(k, "(none)") != b.get(k, "(none)")]
        if keys:
            text = ", ".join(f"{k} {_short(a.get(k, '(none)'))} → {_short(b.get(k, '(none)'))}" for k in keys[:shown])
            more = f" and {len(keys) - shown} more" if len(keys) > shown else ""
            return f"{label} changed since the sweep started: {text}{more}"
    return "the resolved configuration of the planned points changed since the sweep started"


def _short(v) -> str:
    text = v if isinstance(v, str) else f"{v:.6g}" if isinstance(v, float) else json.dumps(v, ensure_ascii=False)
    return text if len(text) <= 40 else text[:39] + "…"


def scalars(summary: dict) -> dict:
    """The summary's scalar entries (int, float, str), for the table, plus the
    dissipation by mechanism as dissipated_power_KIND_CLASS_PART (W), the regime
    criteria (regime maps read them) and the stress events' energy spectra as
    spectrum_MEASURE_STAT (J; STAT mean, median, p90)."""
    out = {}
    flat = {f"dissipated_power_{k}_{c}_{p}": w for k, cls in summary.get("dissipation_by_mechanism", {}).items()
            for c, parts in cls.items() for p, w in parts.items()}
    flat |= {f"spectrum_{m}_{stat}": d[stat] for m, d in (summary.get("spectra") or {}).items()
             if isinstance(d, dict) for stat in ("mean", "median", "p90") if stat in d}
    for k, v in (summary | flat | summary.get("regime_criteria", {})).items():
        if isinstance(v, bool) or v is None:
            continue
        if isinstance(v, (int, np.integer)):
            out[k] = int(v)
        elif isinstance(v, (float, np.floating)):
            out[k] = float(v)
        elif isinstance(v, str):
            out[k] = v
    return out


def _name(i: int) -> str:
    return f"p{i:05d}"
