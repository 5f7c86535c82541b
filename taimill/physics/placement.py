"""Seeded random non-overlapping initial placement of the balls (jar frame, m)."""

from __future__ import annotations

import numpy as np

from taimill.errors import ConfigError

GAP = 1e-4  # m, clearance between balls and to the walls at t = 0


LATTICE_ABOVE = 2000  # balls; beyond this random sequential addition is too slow


def random_placement(count: int, radius: float, jar_radius: float, height: float, seed: int, source="preset") -> np.ndarray:
    """Random sequential addition inside the cylinder bounding the profile; the same
    seed gives the same placement on every machine (NumPy PCG64). Large counts take a
    seeded random subset of a cubic lattice instead."""
    if count > LATTICE_ABOVE:
        return lattice_placement(count, radius, jar_radius, height, seed, source)
    rng = np.random.default_rng(seed)
    rmax = jar_radius - radius - GAP
    zlo, zhi = radius + GAP, height - radius - GAP
    pos = np.empty((count, 3))
    cell = 2 * radius + GAP
    placed = 0
    for _ in range(2000 * count + 10000):
        if placed == count:
            break
        rho = rmax * np.sqrt(rng.random())
        phi = 2 * np.pi * rng.random()
        p = np.array([rho * np.cos(phi), rho * np.sin(phi), zlo + (zhi - zlo) * rng.random()])
        if placed and (np.sum((pos[:placed] - p) ** 2, axis=1) < cell * cell).any():
            continue
        pos[placed] = p
        placed += 1
    if placed < count:
        raise ConfigError(source, "balls.count", count, f"could not place more than {placed} balls without overlap")
    return pos


def lattice_placement(count, radius, jar_radius, height, seed, source="preset"):
    """A seeded random subset of the cubic lattice of pitch 2r + GAP inside the jar."""
    pitch = 2 * radius + GAP
    rmax = jar_radius - radius - GAP
    g = np.arange(-rmax, rmax + 1e-12, pitch)
    z = np.arange(radius + GAP, height - radius - GAP + 1e-12, pitch)
    X, Y, Z = np.meshgrid(g, g, z, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= rmax]
    if len(pts) < count:
        raise ConfigError(source, "balls.count", count, f"at most {len(pts)} balls fit on the start lattice")
    pick = np.sort(np.random.default_rng(seed).choice(len(pts), count, replace=False))
    return pts[pick]
