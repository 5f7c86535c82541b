"""The jar as a closed triangle surface (STL) from its profile (taimill.model.geometry).

The side wall is the profile's boundary pieces cut into straight facets, extruded from
the floor (z = 0) to the lid (z = height); floor and lid are fans about the jar axis
(every profile is star-shaped about it). A line piece is exact; an arc of radius ρ cut
into chords of angle Δ (their ends on the arc) deviates from it by at most the
sagitta ρ(1 − cos Δ/2), on the side of the chord: into the jar for the curved wall and
the fillets, out of it for a lifter. Δ keeps the sagitta below `tolerance`;
`wall_deviation` measures the result with the exact signed distance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from taimill.model.geometry import LINE, Profile, profile_sdf

TOLERANCE = 10e-6  #: m, largest distance of the faceted wall from the true surface


@dataclass(frozen=True)
class JarMesh:
    polygon: np.ndarray  #: (M, 2) side-wall vertices, counter-clockwise, m
    height: float  #: m
    triangles: np.ndarray  #: (T, 3, 3) m, jar frame
    deviation: float  #: m, largest measured distance of the wall from the true profile

    @property
    def side_facets(self) -> int:
        return len(self.polygon)


def _arc_angles(row) -> tuple[np.ndarray, float, float]:
    """(start angle, signed sweep) of an ARC row, its centre and radius."""
    c, rho = row[1:3], row[3]
    e0, m = row[8:10], row[5:7]
    a0 = math.atan2(e0[1] - c[1], e0[0] - c[0])
    half = math.atan2(m[1], m[0]) - a0
    half = (half + math.pi) % (2 * math.pi) - math.pi
    if abs(abs(half) - math.pi) < 1e-12 or row[7] <= -1 + 1e-12:  # a full circle
        half = math.pi
    return np.array(c), float(rho), a0, 2.0 * half


def wall_polygon(profile: Profile, tolerance: float = TOLERANCE) -> np.ndarray:
    """Vertices (M, 2) of the faceted side wall, in the order of the profile's pieces."""
    pts = []
    for row in profile.pieces:
        if row[0] == LINE:
            pts.append(row[1:3].copy())
            continue
        c, rho, a0, sweep = _arc_angles(row)
        sag = min(0.95 * tolerance, rho)  # chords inscribed in the arc: its sagitta
        step = 2.0 * math.acos(1.0 - sag / rho)
        n = max(1, math.ceil(abs(sweep) / step))
        ang = a0 + sweep * np.arange(n) / n
        pts.extend(np.column_stack([c[0] + rho * np.cos(ang), c[1] + rho * np.sin(ang)]))
    return np.array(pts)


def wall_deviation(profile: Profile, polygon: np.ndarray, samples: int = 16) -> float:
    """Largest |signed distance| (m) of points along the polygon's edges from the profile."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    t = np.linspace(0.0, 1.0, samples + 1)
    p = (a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
    return float(np.abs(profile_sdf(profile, p)[0]).max())


def jar_mesh(profile: Profile, height: float, tolerance: float = TOLERANCE) -> JarMesh:
    """The closed surface of a jar: side wall, floor (z = 0) and lid (z = height)."""
    poly = wall_polygon(profile, tolerance)
    a, b = poly, np.roll(poly, -1, axis=0)
    z0, z1 = np.zeros((len(a), 1)), np.full((len(a), 1), height)
    A0, B0 = np.hstack([a, z0]), np.hstack([b, z0])
    A1, B1 = np.hstack([a, z1]), np.hstack([b, z1])
    centre0, centre1 = np.zeros((len(a), 3)), np.tile([0.0, 0.0, height], (len(a), 1))
    side = np.concatenate([np.stack([A0, B0, B1], 1), np.stack([A0, B1, A1], 1)])
    floor = np.stack([centre0, B0, A0], 1)  # normals point out of the jar (−z)
    lid = np.stack([centre1, A1, B1], 1)  # (+z)
    tris = np.concatenate([side, floor, lid])
    return JarMesh(poly, height, tris, wall_deviation(profile, poly))


def write_stl(path, triangles: np.ndarray, name: str = "jar") -> None:
    """ASCII STL of (T, 3, 3) triangles (m), with outward facet normals."""
    n = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    lines = [f"solid {name}"]
    for tri, nn in zip(triangles, n):
        lines.append(f"  facet normal {nn[0]:.9e} {nn[1]:.9e} {nn[2]:.9e}")
        lines.append("    outer loop")
        lines.extend(f"      vertex {v[0]:.12e} {v[1]:.12e} {v[2]:.12e}" for v in tri)
        lines.append("    endloop")
        lines.append("  endfacet")
    lines.append(f"endsolid {name}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def read_stl(path) -> np.ndarray:
    """(T, 3, 3) triangles of an ASCII STL (the ones written here, or a LIGGGHTS mesh dump)."""
    verts = [list(map(float, line.split()[1:4])) for line in open(path) if line.lstrip().startswith("vertex")]
    return np.array(verts).reshape(-1, 3, 3)
