"""What the analysis needs to know about a run, read back from its stored config
(NumPy only): the jar profile and its unrolled wall, ball size and mass, the drive."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from taimill.analysis.theory import critical_ratio
from taimill.model.geometry import Profile, build_profile, profile_sdf
from taimill.model.drive import Drive
from taimill.model.frame import Ramp

SIDE, FLOOR, LID = -1, -2, -3  # body_j of wall events (sinks.EVENT_COLUMNS)


@dataclass(frozen=True)
class RunGeometry:
    profile: Profile
    height: float  #: m
    ball_radius: float  #: m (the largest, for accessible regions)
    ball_mass: float  #: kg
    n_balls: int
    plate_radius: float  #: m, R_p
    plate: Ramp  #: Ω(t), rad/s
    jar: Ramp  #: absolute jar spin w(t), rad/s
    analysis_start: float  #: s, a TUI recording's start (`live_start_time`), else the preset's
    duration: float  #: s
    wall_mu_d: float = math.nan  #: ball-wall dynamic friction μ_d (the slip ratio's scale)
    stations: int | None = None  #: jars on the mill's plate, from the config's `mill`; None: not known

    @classmethod
    def from_config(cls, config: dict, radii) -> "RunGeometry":
        jar, balls = config["jar"], config["balls"]
        prims = tuple((kind, dict(p)) for kind, p in jar["primitives"])
        r = float(np.max(radii)) if len(radii) else float(balls["radius"])
        rho = float(balls["material"]["density"])
        plate, spin = Drive.from_config(config).start_up()
        return cls(
            profile=build_profile(prims, float(jar.get("fillet", 0.0))), height=float(jar["height"]),
            ball_radius=r, ball_mass=rho * 4.0 / 3.0 * math.pi * r**3, n_balls=len(radii),
            plate_radius=float(config["plate_radius"]),
            plate=plate,
            jar=spin,
            analysis_start=float(config.get("live_start_time", config.get("analysis_start", 0.0))),
            duration=float(config.get("duration", math.inf)),
            wall_mu_d=float((config.get("wall_friction") or config.get("friction") or {}).get("mu_d", math.nan)),
            stations=stations_of(config),
        )

    @property
    def volume(self) -> float:
        """Jar volume (m³), for the densities of eq 4.1."""
        return self.profile.area * self.height

    @property
    def wall_area(self) -> float:
        """m², the jar's inner surface: side wall, floor and lid."""
        return self.perimeter * self.height + 2.0 * self.profile.area

    @property
    def jar_radius(self) -> float:
        return self.profile.bounding_radius

    @property
    def critical_ratio(self) -> float:
        """K_c (negative) of one frictionless ball of the largest radius in this jar on
        this plate (taimill.analysis.theory.critical_ratio)."""
        return critical_ratio(self.plate_radius, self.jar_radius, self.ball_radius)

    @property
    def ratio(self) -> float:
        """K of the run's target speeds."""
        return self.drive.ratio

    @property
    def drive(self) -> Drive:
        """The run's target speeds."""
        return Drive(self.plate.end, self.jar.end, self.plate.duration)

    def sdf(self, xy):
        """Signed distance to the side wall (m, > 0 inside) and its gradient."""
        return profile_sdf(self.profile, xy)

    @functools.cached_property
    def _unrolled(self):
        """Outline as (polar angle unwrapped, arc length) with s = 0 at angle 0, CCW."""
        xy = self.profile.outline
        ang = np.arctan2(xy[:, 1], xy[:, 0])
        i0 = int(np.argmin(np.abs(ang)))
        xy = np.roll(xy, -i0, axis=0)
        ang = np.unwrap(np.arctan2(xy[:, 1], xy[:, 0]))
        ang -= 2 * math.pi * math.floor(ang[0] / (2 * math.pi) + 0.5)
        seg = np.hypot(*np.diff(np.vstack([xy, xy[:1]]), axis=0).T)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        ang = np.concatenate([ang, [ang[0] + 2 * math.pi]])
        return ang, s

    @property
    def perimeter(self) -> float:
        return float(self._unrolled[1][-1])

    def arc_length(self, xy) -> np.ndarray:
        """Position along the unrolled side wall (m, 0 … perimeter, CCW from the +x axis)
        of points given in the jar frame; the profile is star-shaped, so the polar angle
        picks the wall point uniquely."""
        ang, s = self._unrolled
        a = np.mod(np.arctan2(xy[:, 1], xy[:, 0]) - ang[0], 2 * math.pi) + ang[0]
        return np.interp(a, ang, s)

    def wall_angle(self, s) -> np.ndarray:
        """Polar angle (deg, −180 … 180) of the wall point at arc length s."""
        ang, arc = self._unrolled
        a = np.interp(s, arc, ang)
        return np.degrees(np.mod(a + math.pi, 2 * math.pi) - math.pi)


def stations_of(config: dict) -> int | None:
    """The mill's station count (jars on its plate) from a resolved config's `mill`
    table; None where the config names no mill or no whole count ≥ 1 (never guessed)."""
    mill = config.get("mill")
    n = mill.get("stations") if isinstance(mill, dict) else None
    if isinstance(n, bool) or not isinstance(n, (int, float)) or not math.isfinite(n) or n != int(n) or n < 1:
        return None
    return int(n)


def reach_radius(g: RunGeometry, theta: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Distance from the axis (m) to the edge of the region a ball centre can reach
    (signed distance ≥ r_ball) along each direction theta (rad), by bisection; the
    region is star-shaped about the axis like the profile."""
    u = np.column_stack([np.cos(theta), np.sin(theta)])
    lo, hi = np.zeros(len(theta)), np.full(len(theta), g.jar_radius)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        inside = g.sdf(mid[:, None] * u)[0] >= g.ball_radius
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return lo


def accessible_area(g: RunGeometry, edges: np.ndarray, n_theta: int = 1440) -> np.ndarray:
    """Area (m²) of each radial shell [edges_k, edges_k+1) that ball centres can reach:
    Σ_θ ½ Δθ (min(ρ_reach(θ), r_k+1)² − r_k²)⁺ (exact in r, midpoint rule in θ)."""
    theta = (np.arange(n_theta) + 0.5) * 2 * math.pi / n_theta
    rho = reach_radius(g, theta)
    outer = np.clip(rho[None, :], edges[:-1, None], edges[1:, None])
    return 0.5 * (2 * math.pi / n_theta) * np.sum(outer**2 - edges[:-1, None] ** 2, axis=1)
