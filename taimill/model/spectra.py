"""Energy spectra of collision events: how many events per second fall in each
logarithmic bin of energy, for four energy measures, per contact kind and class
(docs/outcome.md). The kernel adds each event to its mill's spectra when the event
closes (taimill.physics.events); `from_rows` bins stored event rows the same way, to
the bit. This module holds the binning both use and the container they fill.

Axes of the arrays `count` and `fixed` (int64):

    kind      2   0 ball-ball, 1 ball-wall (the event table's `kind`)
    class     2   0 stress event (onset normal speed u̇n ≥ the stress threshold),
                  1 other contact (below it: rests, rolls, grazing re-contacts)
    measure   4   MEASURES: dissipated normal, dissipated friction, and the thesis'
                  kinematic stress energy ½ m_e u̇² at onset, normal and tangential
    bin       NBIN  0: below EDGES[0] (zero included), k: [EDGES[k-1], EDGES[k]),
                  NBIN - 1: at or above EDGES[-1]

`count` holds events; `fixed` their energy in fixed point: each event adds
floor(e · SCALE[bin] + 0.5) with SCALE[bin] = 2²⁴ / (the bin's lower edge), a relative
resolution of 2⁻²⁴ per event whatever the order of addition, so that spectra are the
same to the bit in every launch mode and thread count. `energy()` converts back to J.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

KINDS = ("ball_ball", "ball_wall")
CLASSES = ("stress", "other")
MEASURES = ("dissipated_normal", "dissipated_friction", "se_normal", "se_tangential")
MEASURE_TEXT = {
    "dissipated_normal": "energy dissipated by the normal damper during the event",
    "dissipated_friction": "energy dissipated by friction (shear) during the event",
    "se_normal": "kinematic stress energy ½ m_e u̇n² at onset (the thesis' SE, normal part)",
    "se_tangential": "kinematic stress energy ½ m_e u̇t² at onset (the thesis' SE, tangential part)",
}
# J: 10 bins a decade from 1 pJ (below any event that matters: a 1 mm steel bead at
# 1 mm/s carries 2·10⁻¹² J) to 100 J (above any planetary mill: a 40 mm steel ball at
# 20 m/s carries 54 J)
DECADES = (-12, 2)
PER_DECADE = 10
EDGES = 10.0 ** (np.arange(DECADES[0] * PER_DECADE, DECADES[1] * PER_DECADE + 1) / PER_DECADE)
NBIN = len(EDGES) + 1
FIXED_BITS = 24
LOWER = np.concatenate([[EDGES[0]], EDGES])  #: J, the energy each bin's fixed point counts in (bin 0: EDGES[0])
SCALE = float(1 << FIXED_BITS) / LOWER  #: 1/J, per bin
SHAPE = (len(KINDS), len(CLASSES), len(MEASURES), NBIN)


def bin_index(e: np.ndarray) -> np.ndarray:
    """Bin of each energy (J): the number of edges at or below it (the kernel's search)."""
    return np.searchsorted(EDGES, np.asarray(e, dtype=float), side="right")


def to_fixed(e: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """An event's energy in its bin's fixed point (module doc), as the kernel adds it."""
    return np.floor(np.asarray(e, dtype=float) * SCALE[bins] + 0.5).astype(np.int64)


def event_energies(rows: dict) -> dict[str, np.ndarray]:
    """The four measures of each event row (J), computed as the kernel computes them."""
    m, un, ut = (np.asarray(rows[k], dtype=float) for k in ("m_eff", "un", "ut"))
    half_m = 0.5 * m
    return {"dissipated_normal": np.asarray(rows["dissipated_normal"], dtype=float),
            "dissipated_friction": np.asarray(rows["dissipated_friction"], dtype=float),
            "se_normal": half_m * (un * un), "se_tangential": half_m * (ut * ut)}


@dataclass
class Spectra:
    """Event spectra of one run over its window [start, end) (s): events whose onset
    t_start lies in it. `stress_un`: the class threshold on u̇n (m/s)."""

    start: float
    end: float
    stress_un: float
    count: np.ndarray = field(default_factory=lambda: np.zeros(SHAPE, dtype=np.int64))
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(SHAPE, dtype=np.int64))

    @property
    def seconds(self) -> float:
        return self.end - self.start

    def energy(self) -> np.ndarray:
        """J per (kind, class, measure, bin): the events' energy summed."""
        return self.fixed * (LOWER / float(1 << FIXED_BITS))

    def add_rows(self, rows: dict) -> "Spectra":
        """Bin event rows (the event table's columns) of this window, as the kernel does."""
        t = np.asarray(rows["t_start"], dtype=float)
        keep = t >= self.start
        if np.isfinite(self.end):
            keep &= t < self.end
        kind = np.asarray(rows["kind"])[keep].astype(np.intp)
        cls = np.where(np.asarray(rows["un"], dtype=float)[keep] >= self.stress_un, 0, 1)
        energies = event_energies(rows)
        for q, name in enumerate(MEASURES):
            e = energies[name][keep]
            bins = bin_index(e)
            np.add.at(self.count, (kind, cls, q, bins), 1)
            np.add.at(self.fixed, (kind, cls, q, bins), to_fixed(e, bins))
        return self

    def __eq__(self, other) -> bool:
        return (isinstance(other, Spectra) and (self.start, self.end, self.stress_un) ==
                (other.start, other.end, other.stress_un)
                and np.array_equal(self.count, other.count) and np.array_equal(self.fixed, other.fixed))


def from_rows(rows: dict, start: float, end: float, stress_un: float) -> Spectra:
    """Spectra of stored event rows over [start, end) s."""
    return Spectra(start, end, stress_un).add_rows(rows)
