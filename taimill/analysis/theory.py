"""Analytic landmarks for one ball in a planetary mill (docs/model.md)."""

from __future__ import annotations

import math


def critical_ratio(plate_radius: float, jar_radius: float, ball_radius: float) -> float:
    """K_c < 0 beyond which a single frictionless ball pressed to the side wall cannot
    detach: K² > R_p / (R_jar - r_ball) (docs/model.md). Radii in m; returns K_c (negative)."""
    return -math.sqrt(plate_radius / (jar_radius - ball_radius))


def pinning_friction(ratio: float, plate_radius: float, jar_radius: float, ball_radius: float) -> float:
    """μ_pin: the least friction coefficient that holds one ball at rest on the side
    wall of a cylindrical jar spinning at K = ratio, gravity aside (docs/regimes.md). At
    rest in the jar frame at angle δ from the direction away from the plate axis it is
    pressed by Ω²(R_p cos δ + K²ρ) and pulled along the wall by Ω² R_p sin δ per unit
    mass (ρ = R_jar − r); the largest ratio over δ is 1/√(a² − 1), a = K²ρ/R_p, at
    cos δ = −1/a. R_p/(K²ρ) = 1/a, the ratio where the plate's pull is tangential
    (δ = 90°), is its limit for large |K|. inf inside the critical ratio (a ≤ 1).
    A ball that can roll is held only if its rolling resistance μ_r reaches μ_pin too."""
    a = ratio**2 * (jar_radius - ball_radius) / plate_radius
    return 1.0 / math.sqrt(a * a - 1.0) if a > 1.0 else math.inf


def pinning_ratio(mu: float, plate_radius: float, jar_radius: float, ball_radius: float) -> float:
    """The K < 0 beyond which friction mu holds one ball (the inverse of pinning_friction)."""
    a = math.sqrt(1.0 + 1.0 / mu**2) if mu > 0 else math.inf
    return -math.sqrt(a * plate_radius / (jar_radius - ball_radius))


def single_ball_hit(plate_radius: float, jar_radius: float, ball_radius: float, plate_omega: float,
                    ratio: float, ball_mass: float) -> dict:
    """Burgio-type energy per hit (Burgio et al. 1991; thesis §1): one ball carried by
    the jar wall without slip until the normal force vanishes, then in free flight
    (straight line in the ground frame, gravity is along the axis) until it meets the
    wall again. Computed exactly for a cylindrical jar rather than with Burgio's
    closed-form approximation and correction factors.

    In the jar frame a ball at rest on the wall at angle δ from the outward direction
    ψ feels Ω²R_p cos δ + w²ρ outwards (ρ = R_jar − r, w = KΩ); it detaches where
    cos δ = −K²ρ/R_p, which exists only for |K| < |K_c|. ψ turns at Ω(1 − K) in the
    jar frame, so a carried ball meets that angle from the side δ < 0.

    Radii in m, Ω in rad/s, mass in kg. Returns the impact's normal and tangential
    speeds (m/s) relative to the wall, their stress energies ½ m u̇² (J, m_e = m_ball),
    the detachment angle δ (deg) and the flight time (s); energies 0 when the ball never
    detaches (rolling)."""
    rho = jar_radius - ball_radius
    w = ratio * plate_omega
    c = -ratio**2 * rho / plate_radius
    none = {"detaches": False, "se_n": 0.0, "se_t": 0.0, "se": 0.0, "un": 0.0, "ut": 0.0,
            "detach_angle_deg": math.nan, "flight_time": math.nan}
    if c <= -1.0 or plate_omega == 0.0:
        return none
    delta = -math.acos(c)
    # ground frame at detachment: plate angle 0, jar frame aligned with the ground
    centre = lambda t: (plate_radius * math.cos(plate_omega * t), plate_radius * math.sin(plate_omega * t))
    centre_v = lambda t: (-plate_radius * plate_omega * math.sin(plate_omega * t), plate_radius * plate_omega * math.cos(plate_omega * t))
    x0 = (plate_radius + rho * math.cos(delta), rho * math.sin(delta))
    cv = centre_v(0.0)
    v0 = (cv[0] - w * (x0[1]), cv[1] + w * (x0[0] - plate_radius))

    def gap(t):  # distance from the jar axis minus ρ: < 0 inside
        cx, cy = centre(t)
        return math.hypot(x0[0] + v0[0] * t - cx, x0[1] + v0[1] * t - cy) - rho

    period = 2.0 * math.pi / abs(plate_omega)
    ts = [period * (k + 1) / 20000.0 for k in range(20000)]
    lo = next((t for t in ts if gap(t) < 0.0), None)
    if lo is None:
        return none
    hi = next((t for t in ts if t > lo and gap(t) >= 0.0), None)
    if hi is None:
        return none
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) < 0.0 else (lo, mid)
    t = hi
    cx, cy = centre(t)
    px, py = x0[0] + v0[0] * t - cx, x0[1] + v0[1] * t - cy
    nx, ny = px / rho, py / rho
    cvx, cvy = centre_v(t)
    ux, uy = v0[0] - (cvx - w * py), v0[1] - (cvy + w * px)
    un = ux * nx + uy * ny
    ut = abs(-ux * ny + uy * nx)
    se_n, se_t = 0.5 * ball_mass * un**2, 0.5 * ball_mass * ut**2
    return {"detaches": True, "se_n": se_n, "se_t": se_t, "se": se_n + se_t, "un": un, "ut": ut,
            "detach_angle_deg": math.degrees(delta), "flight_time": t}
