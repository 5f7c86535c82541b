"""The `spectra` group of a run store (docs/outputs.md): the run's energy spectra
(taimill.model.spectra) as labelled arrays, readable with `xarray.open_zarr(store,
group="spectra")`.

    attrs:  start, end (s; the window: events starting in it), stress_un (m/s),
            measures (what each measure is)
    count   (kind, class, measure, bin)  events
    energy  (kind, class, measure, bin)  J, their energy summed
    fixed   (kind, class, measure, bin)  the same in fixed point (exact, for checks)
    lower, upper (bin,)  J, each bin's edges (the first: [0, 1 pJ), the last: ≥ 100 J)
    kind, class, measure (coordinates: names)
"""

from __future__ import annotations

import numpy as np
import zarr

from taimill.model.spectra import CLASSES, EDGES, KINDS, MEASURE_TEXT, MEASURES, SHAPE, Spectra

GROUP = "spectra"
DIMS = ("kind", "class", "measure", "bin")


def write_spectra(parent: zarr.Group, sp: Spectra, codecs) -> None:
    """Write (replace) the spectra group of `parent`."""
    g = parent.create_group(GROUP, overwrite=True, attributes={
        "start": float(sp.start), "end": float(sp.end), "stress_un": float(sp.stress_un),
        "measures": dict(MEASURE_TEXT), "description": "energy spectra of the collision events in the window"})
    lower = np.concatenate([[0.0], EDGES])
    upper = np.concatenate([EDGES, [np.inf]])

    def array(name, data, dims, units, text):
        g.create_array(name, data=np.asarray(data), dimension_names=dims, compressors=codecs,
                       attributes={"units": units, "description": text})

    array("count", sp.count, DIMS, "1", "events per bin")
    array("energy", sp.energy(), DIMS, "J", "energy of the events per bin, summed")
    array("fixed", sp.fixed, DIMS, "2^-24 of the bin's lower edge (bin 0: of 1 pJ)", "the energy in fixed point, exact")
    array("lower", lower, ("bin",), "J", "lower edge of each bin")
    array("upper", upper, ("bin",), "J", "upper edge of each bin")
    for name, values in (("kind", KINDS), ("class", CLASSES), ("measure", MEASURES)):
        coord = g.create_array(name, shape=(len(values),), dtype=str, dimension_names=(name,), compressors=codecs)
        coord[:] = np.array(values)  # zarr's variable-length strings: fixed-width ones have no zarr v3 spec yet


def read_spectra(parent: zarr.Group) -> Spectra | None:
    """The spectra of a group written by `write_spectra`; None if it has none."""
    if GROUP not in parent:
        return None
    g = parent[GROUP]
    a = g.attrs
    count, fixed = np.asarray(g["count"][...], dtype=np.int64), np.asarray(g["fixed"][...], dtype=np.int64)
    if count.shape != SHAPE or fixed.shape != SHAPE:
        raise ValueError(f"spectra of shape {count.shape}, expected {SHAPE}")
    return Spectra(float(a["start"]), float(a["end"]), float(a["stress_un"]), count, fixed)
