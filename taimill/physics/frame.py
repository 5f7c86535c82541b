"""The jar frame (docs/model.md): drive ramps and the frame's motion, as Taichi functions.

The jar frame turns with the absolute jar spin w about its axis, whose centre runs on
a circle of radius R_p at the plate speed Ω. Its turning is handled exactly, as a
change of basis (`to_spinning`/`from_spinning`): over a step the velocity relative to
the non-rotating frame centred on the jar is kicked and drifted, then both are
re-expressed in the jar basis turned by the exact ramp angle Δφ_jar. That is the
exact flow of the centrifugal, Coriolis and Euler terms of docs/model.md (an explicit
Coriolis/centrifugal step turns the secular free-flight motion into an O(√dt) error:
8 mm after 1 s at K = -2.6). What remains a force term is the translation of the
jar centre, Ω²R_p(cosψ, sinψ, 0) - Ω̇R_p(-sinψ, cosψ, 0), and gravity.
"""

from taimill.physics.ti import ti

Drive = ti.types.struct(
    om=ti.f64, om_dot=ti.f64,  # Ω (rad/s), Ω̇ (rad/s²) at the step's start
    w=ti.f64, w_next=ti.f64,  # absolute jar spin at the step's start and end, rad/s
    cpsi=ti.f64, spsi=ti.f64,  # cos ψ, sin ψ; ψ = φ_plate - φ_jar
    cturn=ti.f64, sturn=ti.f64,  # cos, sin of the jar's turn over the step, Δφ_jar
)


@ti.func
def ramp_at(p, t):
    """(speed, acceleration, angle) of a ramp p = (t0, start, end, T, phase0) at t.
    Twin of taimill.model.frame.Ramp.at."""
    tau = ti.max(t - p[0], 0.0)
    s = ti.min(tau / p[3], 1.0)
    delta = p[2] - p[1]
    speed = p[1] + delta * s * s * (3.0 - 2.0 * s)
    accel = 0.0
    if tau < p[3]:
        accel = delta * 6.0 * s * (1.0 - s) / p[3]
    return speed, accel, p[4] + p[1] * tau + delta * p[3] * ramp_integral(s, tau / p[3])


@ti.func
def ramp_integral(s, x):
    """∫₀ˣ step: P(s) = s³ - s⁴/2 while ramping, then x - 1/2."""
    r = x - 0.5
    if x < 1.0:
        r = s * s * s - 0.5 * s * s * s * s
    return r


@ti.func
def ramp_turn(p, t, dt):
    """Angle turned over [t, t + dt], without subtracting two large angles."""
    t0 = ti.max(t - p[0], 0.0) / p[3]
    t1 = ti.max(t + dt - p[0], 0.0) / p[3]
    return p[1] * dt + (p[2] - p[1]) * p[3] * (ramp_integral(ti.min(t1, 1.0), t1) - ramp_integral(ti.min(t0, 1.0), t0))


@ti.func
def steady(p, t):
    """A ramp p has reached its end speed by t: its angle grows by end·dt a step."""
    return t - p[0] >= p[3]


@ti.func
def psi_at(plate, jar, t):
    """ψ = φ_plate - φ_jar at t, rad."""
    _, _, phi_p = ramp_at(plate, t)
    _, _, phi_j = ramp_at(jar, t)
    return phi_p - phi_j


@ti.func
def drive_turning(plate, jar, t, dt, cturn, sturn, cpsi, spsi):
    """The drive over the step [t, t + dt] given the step's trigonometry: cturn, sturn
    of the jar's turn ramp_turn(jar, t, dt) and cpsi, spsi of ψ(t) (the caller keeps
    both from earlier steps where it can, engine.drive)."""
    om, om_dot, _ = ramp_at(plate, t)
    w, _, _ = ramp_at(jar, t)
    w_next, _, _ = ramp_at(jar, t + dt)
    return Drive(om=om, om_dot=om_dot, w=w, w_next=w_next, cpsi=cpsi, spsi=spsi, cturn=cturn, sturn=sturn)


@ti.func
def translation_acceleration(dr, rp):
    """Fictitious acceleration of the jar centre's circular motion, jar basis, m/s²."""
    return ti.Vector([
        dr.om * dr.om * rp * dr.cpsi + dr.om_dot * rp * dr.spsi,
        dr.om * dr.om * rp * dr.spsi - dr.om_dot * rp * dr.cpsi,
        0.0,
    ])


@ti.func
def to_non_rotating(v, x, w):
    """Jar-frame velocity → velocity relative to the non-rotating frame at the jar
    centre (same basis): v + w ẑ × x."""
    return ti.Vector([v[0] - w * x[1], v[1] + w * x[0], v[2]])


@ti.func
def from_non_rotating(u, x, w):
    return ti.Vector([u[0] + w * x[1], u[1] - w * x[0], u[2]])


@ti.func
def turn_basis(a, dr):
    """Components of a fixed vector in the jar basis after the basis turned by Δφ_jar."""
    return ti.Vector([dr.cturn * a[0] + dr.sturn * a[1], -dr.sturn * a[0] + dr.cturn * a[1], a[2]])


@ti.func
def wall_velocity_ground(p, dr, rp):
    """Ground-frame velocity of the jar point p (jar-frame components): the jar centre's
    Ω R_p (-sinψ, cosψ, 0) plus the spin w ẑ × p."""
    return ti.Vector([-dr.om * rp * dr.spsi - dr.w * p[1], dr.om * rp * dr.cpsi + dr.w * p[0], 0.0])
