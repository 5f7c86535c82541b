"""Seeded random non-overlapping initial placement of the balls (jar frame, m)."""

from __future__ import annotations

import numpy as np

from taimill.errors import ConfigError
from taimill.model.geometry import Profile, profile_sdf

GAP = 1e-4  # m, clearance between balls and to the walls at t = 0


LATTICE_ABOVE = 2000  # balls; beyond this random sequential addition is too slow
BATCH = 256  # candidates drawn and wall-checked at once


def random_placement(count: int, radius: float, profile: Profile, height: float, seed: int, source="preset") -> np.ndarray:
    """Random sequential addition inside the jar, each candidate checked against the
    balls in the 27 grid cells around it (O(1) per candidate); the same seed gives the
    same placement on every machine (NumPy PCG64). Large counts take a seeded random subset of a cubic
    lattice instead."""
    if count > LATTICE_ABOVE:
        return lattice_placement(count, radius, profile, height, seed, source)
    rng = np.random.default_rng(seed)
    rmax = profile.bounding_radius - radius - GAP
    zlo, zhi = radius + GAP, height - radius - GAP
    pos = np.empty((count, 3))
    cell = 2 * radius + GAP
    bins: dict[tuple, list[int]] = {}  # grid of edge `cell`: a conflict lies in the 27 cells around
    placed, tries = 0, 200 * count + 10000
    while placed < count and tries > 0:
        # candidates in batches (the same PCG64 stream as one at a time), walls checked
        # on the whole batch, overlaps one candidate after the other
        u = rng.random((min(BATCH, tries), 3))
        tries -= len(u)
        rho, phi = rmax * np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
        cand = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), zlo + (zhi - zlo) * u[:, 2]])
        inside = profile_sdf(profile, cand[:, :2])[0] >= radius + GAP
        for p in cand[inside]:
            if placed == count:
                break
            c = tuple(int(v) for v in np.floor(p / cell))
            near = [k for dz in (-1, 0, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
                    for k in bins.get((c[0] + dx, c[1] + dy, c[2] + dz), ())]
            if near and (np.sum((pos[near] - p) ** 2, axis=1) < cell * cell).any():
                continue
            pos[placed] = p
            bins.setdefault(c, []).append(placed)
            placed += 1
    if placed < count:  # random addition jammed: staggered layers instead
        return lattice_placement(count, radius, profile, height, seed, source)
    return pos


def lattice_placement(count, radius, profile: Profile, height, seed, source="preset"):
    """A seeded random subset of a hexagonal close packing of pitch 2r + GAP inside the
    jar (also the fallback when random addition jams: 24 balls in the 24.1 mm CY jar
    need the staggered layers)."""
    pts = close_packing(radius, profile, height, GAP)
    if len(pts) < count:
        raise ConfigError(source, "balls.count", count, f"at most {len(pts)} balls fit in the jar at the start")
    pick = np.sort(np.random.default_rng(seed).choice(len(pts), count, replace=False))
    return pts[pick]


def bed_placement(count, radius, profile: Profile, height, gap=GAP, source="preset"):
    """The lowest `count` sites of a hexagonal close packing of pitch 2r + gap: a
    dense bed on the floor (a compressed bed with a gap of a few nm; benchmarks)."""
    pts = close_packing(radius, profile, height, gap)
    if len(pts) < count:
        raise ConfigError(source, "balls.count", count, f"at most {len(pts)} balls fit in the jar as a bed")
    return pts[:count]  # layer by layer from the floor


def close_packing(radius, profile: Profile, height, gap):
    """Sites of a hexagonal close packing of pitch 2r + gap inside the jar, layer by
    layer from the floor, each ball `gap` clear of the walls."""
    a = 2 * radius + gap
    dz = a * np.sqrt(2.0 / 3.0)
    R = profile.bounding_radius
    i, j = np.meshgrid(np.arange(-int(R / a) - 2, int(R / a) + 3), np.arange(-int(R / a) - 3, int(R / a) + 4))
    base = np.column_stack([(i + 0.5 * (j % 2)).ravel() * a, j.ravel() * a * np.sqrt(3) / 2])
    layers = []
    z = radius + gap
    k = 0
    while z <= height - radius - gap + 1e-12:
        shift = np.array([0.5 * a, a / (2 * np.sqrt(3))]) * (k % 2)
        xy = base + shift
        layers.append(np.column_stack([xy, np.full(len(xy), z)]))
        z += dz
        k += 1
    pts = np.vstack(layers) if layers else np.zeros((0, 3))
    return pts[profile_sdf(profile, pts[:, :2])[0] >= radius + gap]
