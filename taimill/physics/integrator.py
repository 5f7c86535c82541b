"""Semi-implicit (symplectic) Euler in the jar frame. The integrator knows no force law
(STYLE rule 4): contact forces come in through f and tau, the frame through frame.py.

    v ← coriolis(v + dt (f/m + a_frame)),   x ← x + dt v,
    s ← R_z(-w dt)(s + dt τ/I)   (absolute spin, components in the turning jar basis)
"""

import taichi as ti

from taimill.physics import state as S
from taimill.physics.frame import coriolis_step, frame_acceleration, spin_step
from taimill.physics.neighbours import moved_too_far


@ti.func
def integrate(F: ti.template(), b, i, dr, dt):
    x, v = F.x[b, i], F.v[b, i]
    a = F.f[b, i] / F.m[b, i] + frame_acceleration(x, dr, F.plate_radius[b], F.gravity[b])
    v = coriolis_step(v + dt * a, dr.w, dt)
    x = x + dt * v
    F.v[b, i] = v
    F.x[b, i] = x
    F.s[b, i] = spin_step(F.s[b, i] + dt * F.inv_i[b, i] * F.tau[b, i], dr.w, dt)
    if moved_too_far(F, b, i):
        F.rebuild[b] = 1
    check_ball(F, b, i, x)


@ti.func
def check_ball(F: ti.template(), b, i, x):
    """Flag a non-finite or runaway state (NaN fails every comparison). A ball that
    tunnelled through a wall is caught by the contact loop (contacts.py)."""
    if not (ti.abs(x[0]) < 1e3 and ti.abs(x[1]) < 1e3 and ti.abs(x[2]) < 1e3):
        F.status[b] = S.NONFINITE
        F.bad_ball[b] = i
