"""Semi-implicit (symplectic) Euler in the jar frame. The integrator knows no force law
(any law plugs in): contact forces come in through f and tau; the frame through frame.py,
whose spin is an exact change of basis and whose translation is a force term:

    u = v + w ẑ×x                       velocity in the non-rotating jar-centred frame
    u ← u + dt (f/m + a_translation - g ẑ),   x ← x + dt u
    x, u, s ← turned into the new jar basis (Δφ_jar),   v = u - w' ẑ×x
    s ← s + dt τ/I before the turn (absolute spin)

and books the step's drive work and dissipation into the ledger, after the frame of
this step was taken (so a frame sees state, stored energy and ledger of one instant).
"""

from taimill.physics import state as S
from taimill.physics.frame import from_non_rotating, to_non_rotating, translation_acceleration, turn_basis
from taimill.physics.neighbours import moved_too_far
from taimill.physics.ti import ti


@ti.func
def frame_acceleration(F: ti.template(), b, dr):
    """The step's acceleration of every ball but the contacts': the jar centre's
    translation and gravity, m/s² (once per step, not per ball)."""
    return translation_acceleration(dr, F.model.plate_radius[b]) - ti.Vector([0.0, 0.0, F.model.gravity[b]])


@ti.func
def integrate(F: ti.template(), b, i, dr, dt, a_frame):
    """One step of ball i; a_frame = frame_acceleration of this step. The contact
    acceleration is f times the stored 1/m (a multiplication instead of a division: 5 %
    of a 12-ball step; it differs from f/m in the last bit)."""
    x = F.state.x[b, i]
    u = to_non_rotating(F.state.v[b, i], x, dr.w)
    u += dt * (F.state.f[b, i] * F.model.inv_m[b, i] + a_frame)
    x = turn_basis(x + dt * u, dr)
    u = turn_basis(u, dr)
    F.state.x[b, i] = x
    F.state.v[b, i] = from_non_rotating(u, x, dr.w_next)
    F.state.s[b, i] = turn_basis(F.state.s[b, i] + dt * F.model.inv_i[b, i] * F.state.tau[b, i], dr)
    # one writer per ball: a plain read-modify-write (`+=` on a field is an atomic,
    # a locked instruction even in a serial loop)
    F.state.drive_work[b, i] = F.state.drive_work[b, i] + F.state.drive_step[b, i]
    F.state.dissipated[b, i] = F.state.dissipated[b, i] + F.state.diss_step[b, i]
    if moved_too_far(F, b, i):
        F.spatial.rebuild[b] = 1
    check_ball(F, b, i, x)


@ti.func
def check_ball(F: ti.template(), b, i, x):
    """Flag a non-finite or runaway state (NaN fails every comparison). A ball that
    tunnelled through a wall is caught by the contact loop (contacts.py)."""
    if not (ti.abs(x[0]) < 1e3 and ti.abs(x[1]) < 1e3 and ti.abs(x[2]) < 1e3):
        F.state.status[b] = S.NONFINITE
        F.state.bad_ball[b] = S.user_id(F, b, i)
