"""The jar frame (SPEC §2): drive ramps and the fictitious accelerations, as Taichi
functions. The integrator treats them as one more force term (STYLE rule 4); only the
Coriolis term, which does no work, is applied as an exact-norm rotation so that an
explicit step does not pump energy into free flight."""

import taichi as ti


@ti.func
def ramp_at(p, t):
    """(speed, acceleration, angle) of a ramp p = (t0, start, end, T, phase0) at t.
    Twin of frame_np.Ramp.at."""
    tau = ti.max(t - p[0], 0.0)
    s = ti.min(tau / p[3], 1.0)
    delta = p[2] - p[1]
    speed = p[1] + delta * s * s * (3.0 - 2.0 * s)
    accel = 0.0
    integral = tau / p[3] - 0.5
    if tau < p[3]:
        accel = delta * 6.0 * s * (1.0 - s) / p[3]
        integral = s * s * s - 0.5 * s * s * s * s
    return speed, accel, p[4] + p[1] * tau + delta * p[3] * integral


Drive = ti.types.struct(
    om=ti.f64, om_dot=ti.f64, w=ti.f64, w_dot=ti.f64,  # Ω, Ω̇, w, ẇ (rad/s, rad/s²)
    cpsi=ti.f64, spsi=ti.f64,  # cos ψ, sin ψ; ψ = φ_plate - φ_jar
)


@ti.func
def drive_at(plate, jar, t):
    """The drive of one step from the Ω and w ramps, trigonometry done once."""
    om, om_dot, phi_p = ramp_at(plate, t)
    w, w_dot, phi_j = ramp_at(jar, t)
    psi = phi_p - phi_j
    return Drive(om=om, om_dot=om_dot, w=w, w_dot=w_dot, cpsi=ti.cos(psi), spsi=ti.sin(psi))


@ti.func
def frame_acceleration(x, dr, rp, g):
    """Per unit mass, all jar-frame terms but Coriolis (SPEC §2): translation of the jar
    centre Ω²R_p(cosψ, sinψ, 0) - Ω̇R_p(-sinψ, cosψ, 0), centrifugal w²(x, y, 0),
    Euler ẇ(y, -x, 0), gravity (0, 0, -g)."""
    om, om_dot, w, w_dot = dr.om, dr.om_dot, dr.w, dr.w_dot
    c, sn = dr.cpsi, dr.spsi
    return ti.Vector([
        om * om * rp * c + om_dot * rp * sn + w * w * x[0] + w_dot * x[1],
        om * om * rp * sn - om_dot * rp * c + w * w * x[1] - w_dot * x[0],
        -g,
    ])


@ti.func
def coriolis_step(v, w, dt):
    """Apply dv/dt = 2w(v_y, -v_x, 0) over dt by the implicit midpoint rule: a rotation
    by -2·atan(w dt) that keeps |v| exactly (explicit Euler would grow it by (2w dt)²
    per step)."""
    a = w * dt
    q = 1.0 / (1.0 + a * a)
    c, sn = (1.0 - a * a) * q, 2.0 * a * q
    return ti.Vector([c * v[0] + sn * v[1], -sn * v[0] + c * v[1], v[2]])


@ti.func
def spin_step(s, w, dt):
    """The jar basis turns by w dt: absolute spin components rotate by -w dt (Cayley
    form, exact norm; its angle error (w dt)³/12 per step is far below round-off of
    the contact torques)."""
    a = 0.5 * w * dt
    q = 1.0 / (1.0 + a * a)
    c, sn = (1.0 - a * a) * q, -2.0 * a * q
    return ti.Vector([c * s[0] - sn * s[1], sn * s[0] + c * s[1], s[2]])


@ti.func
def wall_velocity_ground(p, dr, rp):
    """Ground-frame velocity of the jar point p (jar-frame components): the jar centre's
    Ω R_p (-sinψ, cosψ, 0) plus the spin w ẑ × p."""
    return ti.Vector([-dr.om * rp * dr.spsi - dr.w * p[1], dr.om * rp * dr.cpsi + dr.w * p[0], 0.0])
