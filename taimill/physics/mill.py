"""One mill as plain data (`MillSpec`), built from a preset or by hand (tests,
calibration), and written into slot b of an Engine's fields."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from taimill.params import Friction, NormalLaw, Preset
from taimill.physics import state as S
from taimill.physics.frame_np import Ramp
from taimill.physics.placement import random_placement
from taimill.geometry import Profile


@dataclass(frozen=True)
class MillSpec:
    radius: np.ndarray  #: (N,) m
    mass: np.ndarray  #: (N,) kg
    position: np.ndarray  #: (N, 3) m, jar frame
    velocity: np.ndarray  #: (N, 3) m/s, jar frame
    spin: np.ndarray  #: (N, 3) rad/s, absolute
    profile: Profile  #: jar cross-section (taimill.geometry)
    height: float  #: m
    ball_ball: NormalLaw
    ball_wall: NormalLaw
    friction: Friction
    plate: Ramp  #: Ω(t)
    jar: Ramp  #: w(t), absolute jar spin
    plate_radius: float  #: m
    gravity: float  #: m/s²
    dt: float  #: s
    steps: int  #: steps to run
    frame_every: int  #: steps between frames

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
    every = max(1, int(round(1.0 / (p.trajectory_rate * p.dt))))
    frames = max(1, int(round((duration if duration is not None else p.duration) / (every * p.dt))))
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
        plate=Ramp(0.0, 0.0, p.plate_omega, p.ramp_time),
        jar=Ramp(0.0, 0.0, p.jar_spin, p.ramp_time),
        plate_radius=p.plate_radius,
        gravity=p.gravity,
        dt=p.dt,
        steps=frames * every + 1,  # the last step taken is a frame step: frames at both ends
        frame_every=every,
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


def write_mill(F, b: int, spec: MillSpec):
    """Load spec into slot b of the fields F and reset its state and buffers."""
    n = spec.n
    if n > F.N:
        raise ValueError(f"mill has {n} balls, fields hold {F.N}")
    pieces = spec.profile.pieces
    if len(pieces) > S.MAX_PIECES:
        raise ValueError(f"at most {S.MAX_PIECES} profile pieces, the jar has {len(pieces)}")
    F.n_balls[b] = n
    F.dt[b] = spec.dt
    F.gravity[b] = spec.gravity
    F.plate_radius[b] = spec.plate_radius
    F.height[b] = spec.height
    F.plate_ramp[b] = spec.plate.as_tuple()
    F.jar_ramp[b] = spec.jar.as_tuple()
    F.frame_every[b] = spec.frame_every
    F.target[b] = spec.steps
    for ct, law in enumerate((spec.ball_ball, spec.ball_wall)):
        F.law[b, ct] = law.law_id
        F.law_k[b, ct] = law.k
        F.law_n[b, ct] = law.n
        F.law_c[b, ct] = law.c
        F.law_d[b, ct] = law.d
    set_friction(F, b, spec.friction)
    F.n_pieces[b] = len(pieces)
    rows = F.piece.to_numpy()
    rows[b, : len(pieces)] = pieces
    F.piece.from_numpy(rows)
    lo, h, dim = grid_for(spec)
    if np.prod(dim) > F.grid_cells:
        raise ValueError(f"grid of {np.prod(dim)} cells, fields hold {F.grid_cells}")
    F.grid_lo[b] = lo
    F.grid_h[b] = float(h.min())
    F.grid_dim[b] = dim
    F.skin[b] = skin_for(spec)
    F.rebuild[b] = 1

    pad = np.zeros((F.N - n, 3))
    for field, value in ((F.x, spec.position), (F.v, spec.velocity), (F.s, spec.spin)):
        arr = field.to_numpy()
        arr[b] = np.vstack([value, pad])
        field.from_numpy(arr)
    for field, value in ((F.r, spec.radius), (F.m, spec.mass), (F.inv_i, 1.0 / spec.inertia)):
        arr = field.to_numpy()
        arr[b] = np.concatenate([value, np.ones(F.N - n)])
        field.from_numpy(arr)
    for field in (F.f, F.tau):
        arr = field.to_numpy()
        arr[b] = 0.0
        field.from_numpy(arr)
    for field in (F.drive_work, F.dissipated, F.elastic, F.drive_step, F.diss_step):
        arr = field.to_numpy()
        arr[b] = 0.0
        field.from_numpy(arr)
    sm = F.slot_mask.to_numpy()
    sm[b] = 0
    F.slot_mask.from_numpy(sm)
    F.step[b] = 0
    F.status[b] = S.OK
    F.bad_ball[b] = -1
    F.n_events[b] = 0
    F.n_frames[b] = 0


def set_friction(F, b: int, fr: Friction):
    """Friction is live-tunable: it is field data the next step reads."""
    F.mu_s[b], F.mu_d[b], F.v_s[b], F.v_d[b] = fr.mu_s, fr.mu_d, fr.v_s, fr.v_d
