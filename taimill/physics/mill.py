"""Writes a mill (`taimill.model.spec.MillSpec`) into slot b of an engine's fields, and
changes the parts of a running mill that are field data the next step reads (drive
ramps, time step and clock, friction): outside `physics`, a mill's fields change only
through these."""

import numpy as np

from taimill.model.frame import Ramp
from taimill.model.geometry import PIECE_COLUMNS, piece_bounds
from taimill.model import spectra as SP
from taimill.model.materials import Friction
from taimill.model.spec import MillSpec, grid_for, skin_for
from taimill.physics import state as S
from taimill.physics.ti import ti


def write_mill(F, b: int, spec: MillSpec):
    """Load spec into slot b of the fields F and reset its state and buffers."""
    n = spec.n
    if n > F.N:
        raise ValueError(f"mill has {n} balls, fields hold {F.N}")
    pieces = spec.profile.pieces
    missing = [m.name for ct, m in enumerate(spec.contact_models) if m not in F.models[ct]]
    if missing:
        raise ValueError(f"the engine's kernels are not compiled for the contact model {missing[0]}")
    if len(pieces) > S.MAX_PIECES:
        raise ValueError(f"at most {S.MAX_PIECES} profile pieces, the jar has {len(pieces)}")
    F.model.n_balls[b] = n
    F.model.dt[b] = spec.dt
    F.model.gravity[b] = spec.gravity
    F.model.plate_radius[b] = spec.plate_radius
    F.model.height[b] = spec.height
    set_drive(F, b, spec.plate, spec.jar)
    F.model.frame_every[b] = spec.frame_every
    F.state.turn_trig[b] = (float("inf"), 1.0, 0.0)  # no turn is inf: computed at the first step (NaN would not do: Taichi compares floats ordered)
    F.state.psi_rec[b] = (float("inf"), 1.0, 0.0)  # no step's: computed at the first step
    F.state.psi_rot[b] = (float("inf"), 1.0, 0.0)
    F.model.target[b] = spec.steps
    F.model.stress_un[b] = spec.stress_min_un
    F.model.impact_age[b] = spec.impact_age
    F.model.spectra_from[b] = spec.spectra_from
    for ct, (law, model) in enumerate(zip((spec.ball_ball, spec.ball_wall), spec.contact_models)):
        F.model.variant[b, ct] = F.models[ct].index(model)
        F.model.law_k[b, ct] = law.k
        F.model.law_c[b, ct] = law.c
        F.model.law_d[b, ct] = law.d
        F.model.law_kt[b, ct] = law.kt
    for ct, fr in enumerate(spec.frictions):
        set_friction(F, b, fr, ct)
    F.model.n_pieces[b] = len(pieces)
    lo, h, dim = grid_for(spec)
    if np.prod(dim) > F.grid_cells:
        raise ValueError(f"grid of {np.prod(dim)} cells, fields hold {F.grid_cells}")
    F.spatial.grid_lo[b] = lo
    F.spatial.grid_h[b] = float(h.min())
    F.spatial.grid_dim[b] = dim
    F.spatial.skin[b] = skin_for(spec)
    F.spatial.rebuild[b] = 1
    # one kernel for every per-ball row and the profile rows: a to_numpy/from_numpy pair
    # per field compiled two kernels per field (Taichi's copies are specialised on the
    # field), 36 in all, ≈ 0.8 s CPU of a 10⁵-ball set-up, and copied the whole [B, N]
    # field twice to change one mill's rows
    _load_mill(F, b, n, len(pieces), np.ascontiguousarray(pieces, dtype=np.float64),
               np.ascontiguousarray(piece_bounds(pieces), dtype=np.float64),
               *(np.ascontiguousarray(a, dtype=np.float64) for a in
                 (spec.position, spec.velocity, spec.spin, spec.radius, spec.mass, 1.0 / spec.inertia,
                  SP.EDGES, SP.SCALE)))
    F.state.step[b] = 0
    F.contacts.history_shift[b] = 0
    F.state.status[b] = S.OK
    F.state.bad_ball[b] = -1
    F.out.n_events[b] = 0
    F.out.n_frames[b] = 0


def set_friction(F, b: int, fr: Friction, ct: int):
    """Friction of contact type ct (0 ball-ball, 1 ball-wall) of mill b: μ_s, μ_d, the
    slip speeds v_s, v_d (m/s) and the rolling resistance μ_r. Live-tunable: it is
    field data the next step reads."""
    F.model.mu_s[b, ct], F.model.mu_d[b, ct], F.model.v_s[b, ct], F.model.v_d[b, ct], F.model.mu_r[b, ct] = fr.mu_s, fr.mu_d, fr.v_s, fr.v_d, fr.mu_r


def set_drive(F, b: int, plate: Ramp, jar: Ramp):
    """The drive of mill b from its ramps' t0 on: the plate speed Ω(t) and the jar's
    absolute spin w(t) (rad/s, with their angles in rad), which every step evaluates."""
    F.model.plate_ramp[b] = plate.as_tuple()
    F.model.jar_ramp[b] = jar.as_tuple()


def set_clock(F, b: int, dt: float, step: int, frame_every: int):
    """The time step dt (s) of mill b, its step counter (the kernels' time is t =
    step·dt, s, so a new dt comes with the step that keeps t) and the steps between
    trajectory frames (which a new dt changes). The contacts' history block stays the
    one the next step would have read (pool.history_block: the step's parity)."""
    shift = int(F.contacts.history_shift[b]) + int(F.state.step[b]) - step
    F.contacts.history_shift[b] = shift % 2
    F.model.dt[b] = dt
    F.state.step[b] = step
    F.model.frame_every[b] = frame_every


@ti.kernel
def _load_mill(F: ti.template(), b: ti.i32, n: ti.i32, n_pieces: ti.i32, pieces: ti.types.ndarray(ndim=2),
               bounds: ti.types.ndarray(ndim=2), x: ti.types.ndarray(ndim=2), v: ti.types.ndarray(ndim=2),
               s: ti.types.ndarray(ndim=2), r: ti.types.ndarray(ndim=1), m: ti.types.ndarray(ndim=1),
               inv_i: ti.types.ndarray(ndim=1), edges: ti.types.ndarray(ndim=1), scale: ti.types.ndarray(ndim=1)):
    """Rows of mill b: its profile pieces, its n balls (rows ≥ n: zero state, unit
    radius, mass and inverse inertia), cleared forces, energies, wall bounds and open
    contacts; empty spectra, and the spectra's bins (the same for every mill)."""
    for k in range(edges.shape[0]):
        F.model.spectrum_edges[k] = edges[k]
    for k in range(scale.shape[0]):
        F.model.spectrum_scale[k] = scale[k]
    for I in ti.grouped(ti.ndrange(*SP.SHAPE)):
        F.out.spectrum_count[b, I[0], I[1], I[2], I[3]] = 0
        F.out.spectrum_fixed[b, I[0], I[1], I[2], I[3]] = 0
    for p in range(n_pieces):
        for c in ti.static(range(PIECE_COLUMNS)):
            F.model.piece[b, p][c] = pieces[p, c]
        for c in ti.static(range(3)):
            F.model.piece_bound[b, p][c] = bounds[p, c]
    for i in range(F.N):
        zero = ti.Vector.zero(ti.f64, 3)
        if i < n:
            F.state.x[b, i] = ti.Vector([x[i, 0], x[i, 1], x[i, 2]])
            F.state.v[b, i] = ti.Vector([v[i, 0], v[i, 1], v[i, 2]])
            F.state.s[b, i] = ti.Vector([s[i, 0], s[i, 1], s[i, 2]])
            F.model.r[b, i] = r[i]
            F.model.m[b, i] = m[i]
            F.model.inv_m[b, i] = 1.0 / m[i]  # reorder._inverse_masses computes it the same way
            F.model.inv_i[b, i] = inv_i[i]
        else:
            F.state.x[b, i] = zero
            F.state.v[b, i] = zero
            F.state.s[b, i] = zero
            F.model.r[b, i] = 1.0
            F.model.m[b, i] = 1.0
            F.model.inv_m[b, i] = 1.0
            F.model.inv_i[b, i] = 1.0
        F.state.f[b, i] = zero
        F.state.tau[b, i] = zero
        F.state.drive_work[b, i] = 0.0
        F.state.dissipated[b, i] = 0.0
        F.state.elastic[b, i] = 0.0
        F.state.drive_step[b, i] = 0.0
        F.state.diss_step[b, i] = 0.0
        for c in ti.static(range(S.NMECH)):
            F.state.mech[b, i, c] = 0.0
        F.state.side_ref[b, i] = ti.Vector([0.0, 0.0, -1.0])  # no bound yet: evaluate the profile first
        F.contacts.slot_mask[b, i] = 0
        F.contacts.slot_closed[b, i] = 0
        if ti.static(F.prev_mask):
            F.contacts.slot_prev[b, i] = 0
        if ti.static(F.reorder):  # rows in the spec's order until the first list build
            F.state.user_of[b, i] = i
            F.state.row_of[b, i] = i
    F.contacts.pool_top[b] = 0  # no row released,
    F.contacts.pool_used[b] = 0  # none handed out: rows 0, 1, … come next
