"""Overlap checks of ball centres on a uniform grid (cell hashing), O(N).

Balls are binned into cubic cells of edge ≥ the largest contact distance, so every
pair closer than that lies in the same or a neighbouring cell. Pairs are formed cell
by cell with NumPy (counting sort, then the 13 forward neighbour offsets and the cell
itself), in chunks so that the pair arrays stay bounded at 10⁶ balls. The test on a
pair is the one a dense distance matrix applies, so the result is exact.
"""

from __future__ import annotations

import numpy as np

CHUNK = 1 << 15  # balls per chunk of pair building (≈ 20 candidate pairs each: ≈ 30 MB of arrays)

# the cell itself and the 13 forward neighbours: each unordered cell pair once
_OFFSETS = [(dx, dy, dz) for dz in (-1, 0, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
            if (dz, dy, dx) >= (0, 0, 0)]


class CellGrid:
    """Ball indices sorted by cell: `order` (N,) and, per occupied cell key in
    ascending order, `keys`, `start`, `count`."""

    def __init__(self, x: np.ndarray, edge: float):
        x = np.asarray(x, dtype=float)
        self.edge = float(edge)
        lo = x.min(axis=0) if len(x) else np.zeros(3)
        c = np.floor((x - lo) / self.edge).astype(np.int64) + 1  # a free layer of cells below
        self.dim = c.max(axis=0) + 2 if len(x) else np.ones(3, np.int64)
        self.cell = self.key(c)
        self.order = np.argsort(self.cell, kind="stable")
        self.keys, self.start, self.count = np.unique(self.cell[self.order], return_index=True, return_counts=True)
        self.coords = c

    def key(self, c):
        d = self.dim
        return (c[..., 2] * d[1] + c[..., 1]) * d[0] + c[..., 0]

    def pairs(self, lo: int = 0, hi: int | None = None):
        """Candidate pairs (i, j), i < j in position of `order`, for the balls
        order[lo:hi]: every pair in the same or neighbouring cells exactly once."""
        hi = len(self.order) if hi is None else hi
        idx = self.order[lo:hi]
        pos = np.arange(lo, hi)
        out_i, out_j = [], []
        for off in _OFFSETS:
            nkey = self.key(self.coords[idx] + np.array(off))
            k = np.searchsorted(self.keys, nkey)
            k = np.minimum(k, len(self.keys) - 1)
            hit = self.keys[k] == nkey
            first = np.where(hit, self.start[k], 0)
            n = np.where(hit, self.count[k], 0)
            if off == (0, 0, 0):  # same cell: only partners after this ball in the sorted order
                n = first + n - pos - 1
                first = pos + 1
            rep = np.repeat(np.arange(len(idx)), n)
            within = np.arange(len(rep)) - np.repeat(np.cumsum(n) - n, n)
            out_i.append(idx[rep])
            out_j.append(self.order[np.repeat(first, n) + within])
        return np.concatenate(out_i), np.concatenate(out_j)

    def chunks(self):
        for lo in range(0, len(self.order), CHUNK):
            yield self.pairs(lo, min(lo + CHUNK, len(self.order)))


def first_overlap(x: np.ndarray, radius) -> tuple[int, int] | None:
    """A pair (i, j), i < j, of balls whose centres are closer than r_i + r_j, or None.
    `radius` is one radius or one per ball (m)."""
    x = np.asarray(x, dtype=float)
    r = np.broadcast_to(np.asarray(radius, dtype=float), (len(x),))
    if len(x) < 2:
        return None
    grid = CellGrid(x, 2.0 * float(r.max()))
    for i, j in grid.chunks():
        gap = np.linalg.norm(x[i] - x[j], axis=-1)
        bad = np.flatnonzero(gap < r[i] + r[j])
        if len(bad):
            a, b = int(i[bad[0]]), int(j[bad[0]])
            return min(a, b), max(a, b)
    return None


def overlapping_pairs(x: np.ndarray, radius) -> np.ndarray:
    """Every pair (i, j), i < j, closer than r_i + r_j, as an (M, 2) array sorted by rows."""
    x = np.asarray(x, dtype=float)
    r = np.broadcast_to(np.asarray(radius, dtype=float), (len(x),))
    if len(x) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    grid = CellGrid(x, 2.0 * float(r.max()))
    found = []
    for i, j in grid.chunks():
        bad = np.linalg.norm(x[i] - x[j], axis=-1) < r[i] + r[j]
        found.append(np.sort(np.column_stack([i[bad], j[bad]]), axis=1))
    pairs = np.concatenate(found)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
