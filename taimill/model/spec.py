"""One mill as plain data (`MillSpec`), built from a preset or by hand (tests,
calibration), with the Verlet skin and hash grid that suit it. The physics package
writes it into an engine's fields (`taimill.physics.mill.write_mill`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from taimill.model import rules
from taimill.model.contact.model import ContactModel
from taimill.model.contact.registry import contact_model
from taimill.model.frame import Ramp
from taimill.model.geometry import Profile
from taimill.model.mechanisms import IMPACT_AGE, STRESS_MIN_UN
from taimill.model.materials import Friction
from taimill.model.contact_sets import NormalLaw
from taimill.model.preset import Preset
from taimill.model.placement import random_placement


@dataclass(frozen=True)
class MillSpec:
    radius: np.ndarray  #: (N,) m
    mass: np.ndarray  #: (N,) kg
    position: np.ndarray  #: (N, 3) m, jar frame
    velocity: np.ndarray  #: (N, 3) m/s, jar frame
    spin: np.ndarray  #: (N, 3) rad/s, absolute
    profile: Profile  #: jar cross-section (taimill.model.geometry)
    height: float  #: m
    ball_ball: NormalLaw
    ball_wall: NormalLaw
    friction: Friction  #: of ball-ball contacts
    plate: Ramp  #: Ω(t)
    jar: Ramp  #: w(t), absolute jar spin
    plate_radius: float  #: m
    gravity: float  #: m/s²
    dt: float  #: s
    steps: int  #: steps to run
    frame_every: int  #: steps between frames
    stress_min_un: float = STRESS_MIN_UN  #: m/s, impacts start at least this fast
    impact_age: float = IMPACT_AGE  #: s, older contacts are persistent
    wall_friction: Friction | None = None  #: of ball-wall contacts; None: `friction`
    spectra_from: float = 0.0  #: s, events starting from this time enter the energy spectra

    @property
    def frictions(self) -> tuple[Friction, Friction]:
        """(ball-ball, ball-wall) friction, in contact-type order."""
        return self.friction, self.wall_friction or self.friction

    @property
    def contact_models(self) -> tuple[ContactModel, ContactModel]:
        """(ball-ball, ball-wall) compositions of sub-models the kernels must hold."""
        return tuple(contact_model(law.model, fr.tangential, fr.rolling)
                     for law, fr in zip((self.ball_ball, self.ball_wall), self.frictions))

    @property
    def n(self):
        return len(self.radius)

    @property
    def inertia(self):
        return 0.4 * self.mass * self.radius**2

    @property
    def bounding_radius(self):
        return self.profile.bounding_radius

    def replace(self, **kw) -> "MillSpec":
        return dataclasses.replace(self, **kw)


def from_preset(p: Preset, duration: float | None = None) -> MillSpec:
    n = p.balls.count
    x0 = p.initial_positions
    if x0 is None:
        x0 = random_placement(n, p.balls.radius, p.jar.profile, p.jar.height, p.seed, p.source)
    every = rules.frame_every(p.trajectory_rate, p.dt)
    frames = rules.frame_intervals(p.trajectory_rate, p.dt, duration if duration is not None else p.duration)
    plate, jar = p.drive.start_up()
    return MillSpec(
        radius=np.full(n, p.balls.radius),
        mass=np.full(n, p.balls.mass),
        position=np.asarray(x0, dtype=float),
        velocity=np.zeros((n, 3)),
        spin=np.zeros((n, 3)),
        profile=p.jar.profile,
        height=p.jar.height,
        ball_ball=p.ball_ball,
        ball_wall=p.ball_wall,
        friction=p.friction,
        plate=plate,
        jar=jar,
        plate_radius=p.plate_radius,
        gravity=p.gravity,
        dt=p.dt,
        steps=frames * every + 1,  # the last step taken is a frame step: frames at both ends
        frame_every=every,
        wall_friction=p.wall_friction,
        spectra_from=p.analysis_start,
    )


def skin_for(spec: MillSpec) -> float:
    """Verlet skin (m): a tenth of the largest radius; lists then last ~100 steps."""
    return 0.1 * float(spec.radius.max())


def grid_for(spec: MillSpec):
    """(lower corner, cell edge, dims) of the hash grid covering the jar: the edge is at
    least the largest interaction reach, 2 r_max + skin, and coarser where a big, sparse
    domain (a drop-test plate) would need more than max(4096, 8 N) cells."""
    h = (2.0 * float(spec.radius.max()) + skin_for(spec)) * 1.0001
    R = spec.bounding_radius
    box = np.array([2 * R, 2 * R, spec.height])
    cap = max(4096, 8 * spec.n)
    h = max(h, float(np.prod(box + h) / cap) ** (1 / 3))
    ext = box + h
    dim = np.maximum(1, np.floor(ext / h)).astype(int)
    while np.prod(dim) > cap:
        dim = np.maximum(1, dim // 2)
    lo = np.array([-R, -R, 0.0]) - 0.5 * h
    return lo, ext / dim, dim  # cells stretched to fill the box: edge ≥ h


def grid_cells_for(spec: MillSpec) -> int:
    return int(np.prod(grid_for(spec)[2]))
