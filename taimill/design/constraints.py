"""What a maker needs of a designed jar, checked before any run (a candidate that fails
is pruned without running):

- it is a valid jar: the jar loader's own checks (taimill.model.jars.load_jar);
- the bowl fits the mill's station: its curved wall is the reference jar's circle;
- its volume lies within `tolerance` (a fraction) of the nominal (the reference jar's);
- every corner's fillet is at least the ball radius, so a ball touches a corner at one
  point (the wall normal stays continuous under it);
- no insert is thinner than `min_wall`: an insert is the solid a flat or lifter adds
  inside the bore, its thickness the diameter of the largest circle inside it.

Each violation is one line with the value and the allowed range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from taimill.model import geometry, rules

GRID_MM = 0.2  #: sampling step (mm) of the insert-thickness measure


@dataclass(frozen=True)
class Limits:
    """The maker's constraints (m, m³, fraction)."""

    radius: float  #: the curved wall's radius (the reference jar's)
    volume: float  #: nominal inner volume
    tolerance: float  #: allowed |V / V_nominal - 1|
    ball_radius: float
    min_wall: float


def violations(jar, limits: Limits) -> list[str]:
    """Every constraint `jar` (taimill.model.jars.Jar) breaks, one line each; [] if none."""
    out = []
    circle = next(v["radius"] for kind, v in jar.primitives if kind == "circle")
    if abs(circle - limits.radius) > 1e-9:
        out.append(f"curved wall radius = {circle * 1e3:g} mm: must be the station's {limits.radius * 1e3:g} mm")
    ratio = jar.volume / limits.volume
    if abs(ratio - 1) > limits.tolerance:
        out.append(f"volume = {jar.volume * 1e6:.4g} ml ({ratio:.1%} of the nominal {limits.volume * 1e6:.4g} ml): "
                   f"allowed range [{(1 - limits.tolerance) * limits.volume * 1e6:.4g}, "
                   f"{(1 + limits.tolerance) * limits.volume * 1e6:.4g}] ml")
    if not rules.ball_fits_corners(limits.ball_radius, jar):
        out.append(f"fillet_mm = {jar.fillet * 1e3:g}: must be ≥ the ball radius {limits.ball_radius * 1e3:g} mm")
    thin = thinnest_insert(jar.profile, circle)
    if thin is not None and thin < limits.min_wall:
        out.append(f"thinnest insert = {thin * 1e3:.3g} mm: must be ≥ {limits.min_wall * 1e3:g} mm (--min-wall)")
    return out


def thinnest_insert(profile: geometry.Profile, radius: float) -> float | None:
    """Thickness (m) of the thinnest insert between the profile and the circle of
    `radius`: for each angular run where the profile lies inside the circle, twice the
    largest distance of a solid point in that run to both the profile and the circle
    (grid of GRID_MM). None for a plain circle."""
    outline = profile.outline
    depth = radius - np.hypot(*outline.T)
    inside = depth > 1e-7
    if not inside.any():
        return None
    angle = np.arctan2(outline[:, 1], outline[:, 0])
    runs = _runs(inside)
    step = GRID_MM * 1e-3
    axis = np.arange(-radius, radius + step, step)
    x, y = np.meshgrid(axis, axis)
    p = np.column_stack([x.ravel(), y.ravel()])
    r = np.hypot(p[:, 0], p[:, 1])
    p, r = p[r < radius], r[r < radius]
    phi, _ = geometry.profile_sdf(profile, p)
    solid = phi < 0
    p, r, phi = p[solid], r[solid], phi[solid]
    t = np.minimum(-phi, radius - r)
    theta = np.arctan2(p[:, 1], p[:, 0])
    thickness = []
    for i0, i1 in runs:
        a0, a1 = angle[i0], angle[i1]
        span = (a1 - a0) % (2 * np.pi)
        within = ((theta - a0) % (2 * np.pi)) <= span
        thickness.append(2 * float(t[within].max()) if within.any() else 0.0)
    return min(thickness)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the cyclic runs of True in `mask`."""
    n = len(mask)
    if mask.all():
        return [(0, n - 1)]
    start = int(np.argmin(mask))  # a False: runs do not wrap past it
    order = np.roll(np.arange(n), -start)
    out, first, prev = [], None, None
    for i in order:
        if mask[i] and first is None:
            first = i
        if not mask[i] and first is not None:
            out.append((first, prev))
            first = None
        prev = i
    if first is not None:
        out.append((first, prev))
    return out
