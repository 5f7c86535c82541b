"""The `spectra` group of a run store (docs/outputs.md): the run's energy spectra
(taimill.model.spectra) as labelled arrays, readable with `xarray.open_zarr(store,
group="spectra")`.

    attrs:  start, end (s; the window: events starting in it), stress_un (m/s),
            measures (what each measure is), generation (odd while being rewritten)
    count   (kind, class, measure, bin)  events
    energy  (kind, class, measure, bin)  J, their energy summed
    fixed   (kind, class, measure, bin)  the same in fixed point (exact, for checks)
    lower, upper (bin,)  J, each bin's edges (the first: [0, 1 pJ), the last: ≥ 100 J)
    kind, class, measure (coordinates: names)

A run that keeps no event rows rewrites its spectra at every commit while readers
may be reading them (`SpectraWriter`): in place, every chunk stored (a chunk of zeros
too, so a missing chunk is damage, never zero events), between two updates of
`generation` that a reader compares (`read_spectra`, `Busy`). Stores written before
`generation` stored no all-zero chunk and replaced the whole group at each commit;
their missing chunks are told from zeros by what the other arrays hold.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import zarr
from zarr.core.sync import sync

from taimill.errors import StoreError
from taimill.model.spectra import (CLASSES, EDGES, FIXED_BITS, KINDS, LOWER, MEASURE_TEXT, MEASURES, NBIN, SHAPE,
                                   Spectra)
from taimill.store.chunks import why

GROUP = "spectra"
DIMS = ("kind", "class", "measure", "bin")
COUNTS = ("count", "fixed", "energy")  #: the arrays a commit rewrites
COORDS = {"kind": KINDS, "class": CLASSES, "measure": MEASURES}
# Fixed point an event adds in bin k ≥ 1 (e in [EDGES[k-1], EDGES[k])): at least 2^24,
# at most 2^24 × the ratio of the bin's edges (+ rounding); bin 0 ([0, 1 pJ)): at most
# 2^24; the last bin (≥ 100 J) has no upper edge.
_ONE = 1 << FIXED_BITS
_MOST = np.concatenate([[_ONE], np.ceil(_ONE * EDGES[1:] / EDGES[:-1]) + 1, [np.inf]])


class Busy(Exception):
    """The spectra were being rewritten while they were read: read them again."""

    def __init__(self, generation):
        super().__init__(f"spectra being rewritten (generation {generation})")
        self.generation = generation  #: as last seen: odd and unchanging, its writer was killed while rewriting


def _edges() -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate([[0.0], EDGES]), np.concatenate([EDGES, [np.inf]])


def _window(sp: Spectra) -> dict:
    return {"start": float(sp.start), "end": float(sp.end), "stress_un": float(sp.stress_un)}


class SpectraWriter:
    """Writes the spectra group of `parent` at the first `write`, and rewrites its
    counts in place at every later one (module doc), `generation` odd meanwhile."""

    def __init__(self, parent: zarr.Group, codecs):
        self.parent, self.codecs = parent, codecs
        self.group: zarr.Group | None = None
        self.arrays: dict[str, zarr.Array] = {}
        self.generation = 0

    def write(self, sp: Spectra) -> None:
        data = {"count": sp.count, "fixed": sp.fixed, "energy": sp.energy()}
        if self.group is None:
            self._create(sp, data)
            return
        self.generation += 1
        self.group.attrs["generation"] = self.generation
        for name, values in data.items():
            self.arrays[name][...] = values
        self.generation += 1
        self.group.update_attributes(_window(sp) | {"generation": self.generation})  # one write: window and generation

    def _create(self, sp: Spectra, data: dict) -> None:
        self.generation = 1
        g = self.parent.create_group(GROUP, overwrite=True, attributes=_window(sp) | {
            "measures": dict(MEASURE_TEXT), "generation": self.generation,
            "description": "energy spectra of the collision events in the window"})

        def array(name, values, dims, units, text):
            return g.create_array(name, data=np.asarray(values), dimension_names=dims, compressors=self.codecs,
                                  config={"write_empty_chunks": True}, attributes={"units": units, "description": text})

        units = {"count": ("1", "events per bin"), "energy": ("J", "energy of the events per bin, summed"),
                 "fixed": ("2^-24 of the bin's lower edge (bin 0: of 1 pJ)", "the energy in fixed point, exact")}
        self.arrays = {name: array(name, data[name], DIMS, *units[name]) for name in ("count", "energy", "fixed")}
        lower, upper = _edges()
        array("lower", lower, ("bin",), "J", "lower edge of each bin")
        array("upper", upper, ("bin",), "J", "upper edge of each bin")
        for name, values in COORDS.items():
            coord = g.create_array(name, shape=(len(values),), dtype=str, dimension_names=(name,),
                                   compressors=self.codecs, config={"write_empty_chunks": True})
            coord[:] = np.array(values)  # zarr's variable-length strings: fixed-width ones have no zarr v3 spec yet
        self.generation = 2
        g.attrs["generation"] = self.generation
        self.group = g


def read_spectra(parent: zarr.Group, where: str, settled: bool = False) -> Spectra | None:
    """The spectra of a group written by `SpectraWriter`; None if it has none. What
    would read wrongly raises StoreError naming the part (`spectra/count: chunk 0
    missing`): an array or chunk missing, a chunk that does not decode, arrays of
    another shape, counts and energies that contradict each other. Busy while the
    writer rewrites them; `settled`: read them anyway (a writer killed meanwhile left
    its last counts partly rewritten: arrays of two commits, not cross-checked), and
    a group it never finished writing reads as none."""
    first = _generation(parent)
    if isinstance(first, int) and first % 2 and not settled:
        raise Busy(first)
    try:
        sp = _read_group(parent, where, settled)
    except StoreError:
        if not settled and first is not None and _generation(parent) != first:
            raise Busy(_generation(parent)) from None  # read during a rewrite: not damage
        raise
    if not settled and first is not None and (now := _generation(parent)) != first:
        raise Busy(now)
    return sp


def _read_group(parent: zarr.Group, where: str, settled: bool) -> Spectra | None:
    def bad(part, text):
        raise StoreError(where, part, text)

    try:
        if GROUP not in parent:
            return None
        g = parent[GROUP]
        attrs = g.attrs.asdict()
    except Exception as err:
        bad(GROUP, f"metadata unreadable ({why(err)})")
    if not isinstance(g, zarr.Group):
        bad(GROUP, "an array, not a group")
    generation = attrs.get("generation")
    if generation is not None and (not isinstance(generation, int) or isinstance(generation, bool)):
        bad(f"{GROUP}/attrs.generation", f"{generation!r} is not a count")
    writing = generation is not None and generation % 2 == 1
    if writing and not settled:
        raise Busy(generation)
    if writing and generation == 1:
        return None  # killed while creating the group: no spectra were committed
    window = []
    for key in ("start", "end", "stress_un"):
        v = attrs.get(key)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            bad(f"{GROUP}/attrs.{key}", f"{v!r} is not a number")
        window.append(float(v))
    lower, upper = _edges()
    expected = {"count": (SHAPE, "i"), "fixed": (SHAPE, "i"), "energy": (SHAPE, "f"),
                "lower": ((NBIN,), "f"), "upper": ((NBIN,), "f")} | {k: ((len(v),), "T") for k, v in COORDS.items()}
    data, missing = {}, {}
    for name, (shape, kind) in expected.items():
        data[name], missing[name] = _read(g, name, shape, kind, where)
        if missing[name] and (generation is not None or name not in COUNTS):
            bad(f"{GROUP}/{name}", f"chunk {missing[name][0]} missing (read as {'zeros' if kind != 'T' else 'empty'})")
    for name, values in COORDS.items():
        if list(data[name]) != list(values):
            bad(f"{GROUP}/{name}", f"{list(data[name])} are not the {name} names {', '.join(values)}")
    for name, edges in (("lower", lower), ("upper", upper)):
        if not np.array_equal(data[name], edges):
            bad(f"{GROUP}/{name}", "not the bin edges of the spectra (10 a decade from 1 pJ to 100 J)")
    count, fixed, energy = data["count"].astype(np.int64), data["fixed"].astype(np.int64), data["energy"]
    if not (writing and settled):
        _cross_check(count, fixed, energy, missing, bad)
    return Spectra(*window, count, fixed)


def _cross_check(count, fixed, energy, missing, bad) -> None:
    """Counts and energies that no events give: negative, an energy not what its fixed
    point says, a bin's fixed-point energy outside what its events can carry. In a
    store written before every chunk was stored, a missing chunk (read as zeros) of
    one array shows here, and is named."""
    def damaged(name, text):
        gone = [k for k in COUNTS if missing[k]]
        if gone:
            bad(f"{GROUP}/{gone[0]}", f"chunk {missing[gone[0]][0]} missing (read as zeros: {text})")
        bad(f"{GROUP}/{name}", text)

    if (count < 0).any() or (fixed < 0).any():
        damaged("count" if (count < 0).any() else "fixed", "negative numbers")
    if not np.allclose(energy, fixed * (LOWER / float(_ONE)), rtol=1e-12, atol=0.0):
        damaged("energy", "spectra/energy is not the energy spectra/fixed holds")
    low, high = np.zeros(SHAPE, dtype=bool), np.zeros(SHAPE, dtype=bool)
    low[..., 1:] = count[..., 1:] * _ONE > fixed[..., 1:]
    high[..., :-1] = fixed[..., :-1] > count[..., :-1] * _MOST[:-1]
    if low.any() or high.any():
        cell = tuple(int(i) for i in np.argwhere(low | high)[0])
        k, c, m, b = cell
        damaged("fixed", f"{int(count[cell])} {CLASSES[c]} events in bin {b} of {KINDS[k]} {MEASURES[m]} carry "
                         f"{int(fixed[cell])} in fixed point, {'less' if low[cell] else 'more'} than they can")


def _generation(parent: zarr.Group):
    try:
        return parent[GROUP].attrs.get("generation")
    except Exception:
        return None


def _read(g: zarr.Group, name: str, shape: tuple, kind: str, where: str) -> tuple[np.ndarray, list[int]]:
    """The whole array `name` of g and the indices of its chunks not stored (C order)."""
    part = f"{GROUP}/{name}"
    try:
        arr = g[name]
    except KeyError:
        raise StoreError(where, part, "missing") from None
    except Exception as err:
        raise StoreError(where, part, f"metadata unreadable ({why(err)})") from None
    ok = isinstance(arr, zarr.Array) and arr.shape == shape and (
        arr.dtype.kind in ("T", "U", "O") if kind == "T" else arr.dtype.kind == kind or kind == "i" and arr.dtype.kind == "u")
    if not ok:
        what = f"shape {arr.shape}, dtype {arr.dtype}" if isinstance(arr, zarr.Array) else "a group"
        raise StoreError(where, part, f"{what}; expected shape {shape}")
    grid = [range(-(-s // c)) for s, c in zip(arr.shape, arr.chunks)]
    missing = []
    for i, index in enumerate(itertools.product(*grid)):
        key = f"{arr.path}/{arr.metadata.encode_chunk_key(index)}"
        if not sync(arr.store.exists(key)):
            missing.append(i)
    try:
        return np.asarray(arr[...]), missing
    except Exception:
        for i, index in enumerate(itertools.product(*grid)):
            try:
                arr.blocks[index]
            except Exception as err:
                if "checksum" in str(err):
                    raise StoreError(where, part, f"chunk {i} fails its checksum (its bytes changed after they "
                                                  "were written)") from None
                raise StoreError(where, part, f"chunk {i} unreadable ({why(err)})") from None
        raise
