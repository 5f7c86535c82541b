"""Writes a mill (`taimill.model.spec.MillSpec`) into slot b of an engine's fields."""

from __future__ import annotations

import numpy as np

from taimill.model.geometry import piece_bounds
from taimill.model.params import Friction
from taimill.model.spec import MillSpec, grid_for, skin_for
from taimill.physics import state as S


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
    F.turn_trig[b] = (float("inf"), 1.0, 0.0)  # no turn is inf: computed at the first step (NaN would not do: Taichi compares floats ordered)
    F.target[b] = spec.steps
    F.stress_un[b] = spec.stress_min_un
    F.impact_age[b] = spec.impact_age
    for ct, law in enumerate((spec.ball_ball, spec.ball_wall)):
        F.law[b, ct] = law.law_id
        F.law_k[b, ct] = law.k
        F.law_n[b, ct] = law.n
        F.law_c[b, ct] = law.c
        F.law_d[b, ct] = law.d
    for ct, fr in enumerate(spec.frictions):
        set_friction(F, b, fr, ct)
    F.n_pieces[b] = len(pieces)
    rows = F.piece.to_numpy()
    rows[b, : len(pieces)] = pieces
    F.piece.from_numpy(rows)
    rows = F.piece_bound.to_numpy()
    rows[b, : len(pieces)] = piece_bounds(pieces)
    F.piece_bound.from_numpy(rows)
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
    for field in (F.drive_work, F.dissipated, F.elastic, F.drive_step, F.diss_step, F.mech):
        arr = field.to_numpy()
        arr[b] = 0.0
        field.from_numpy(arr)
    ref = F.side_ref.to_numpy()
    ref[b] = (0.0, 0.0, -1.0)  # no bound yet: evaluate the profile first
    F.side_ref.from_numpy(ref)
    sm = F.slot_mask.to_numpy()
    sm[b] = 0
    F.slot_mask.from_numpy(sm)
    F.step[b] = 0
    F.status[b] = S.OK
    F.bad_ball[b] = -1
    F.n_events[b] = 0
    F.n_frames[b] = 0


def set_friction(F, b: int, fr: Friction, ct: int):
    """Friction of contact type ct (0 ball-ball, 1 ball-wall) is live-tunable: it is
    field data the next step reads."""
    F.mu_s[b, ct], F.mu_d[b, ct], F.v_s[b, ct], F.v_d[b, ct], F.mu_r[b, ct] = fr.mu_s, fr.mu_d, fr.v_s, fr.v_d, fr.mu_r
