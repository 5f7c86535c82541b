"""The response at one contact: force, friction and rolling torque of the contact
model compiled for its contact type, and what its owner books of it (dissipation and
stored energy). Pure functions of the contact's local quantities and the mill's
coefficients."""

from taimill.physics.laws import ROLLING, TANGENTIAL, elastic_energy, normal_force
from taimill.physics.ti import ti


@ti.func
def respond(model: ti.template(), F: ti.template(), b, ct: ti.template(), u, udot, slip, nrm, m_eff, inv_mass_t,
            dt, xi):
    """(F_n, elastic F_n, friction force, tangential history, its stored energy) of the
    ContactModel `model` (compiled in); xi: the contact's tangential history."""
    fn, fel = normal_force(model.normal, u, udot, F.model.law_k[b, ct], F.model.law_c[b, ct], F.model.law_d[b, ct], m_eff)
    ft, xi_new, e_t = TANGENTIAL[model.tangential.name](slip, nrm, fn, u, F.model.mu_s[b, ct], F.model.mu_d[b, ct], F.model.v_s[b, ct],
                                                        F.model.v_d[b, ct], F.model.law_kt[b, ct], xi, inv_mass_t, dt)
    return fn, fel, ft, xi_new, e_t


@ti.func
def contact_response(F: ti.template(), b, ct: ti.template(), u, nrm, vrel, m_eff, inv_mass_t, dt, xi):
    """Force on the first body at a contact of type ct (0 ball-ball, 1 ball-wall) with
    overlap u, unit normal nrm (first body → second), relative contact-point velocity
    vrel, tangential history xi (zero for a new contact; kept only by history models).
    Returns (force, u̇, slip, F_n, elastic F_n, friction force, new tangential history,
    its stored energy). The contact model is the engine's only one for ct (F.models[ct],
    compiled in), or, when a batch mixes models, the one F.model.variant[b, ct] picks among
    them. Rolling resistance (if on) is added by the caller, who knows the spins; its
    work is booked with the friction work (the shear part of the contact's dissipation)."""
    udot = vrel.dot(nrm)
    slip = vrel - udot * nrm
    fn, fel, e_t = 0.0, 0.0, 0.0
    ft = ti.Vector([0.0, 0.0, 0.0])
    xi_new = xi
    if ti.static(len(F.models[ct]) == 1):
        fn, fel, ft, xi_new, e_t = respond(F.models[ct][0], F, b, ct, u, udot, slip, nrm, m_eff, inv_mass_t, dt, xi)
    else:
        for v in ti.static(range(len(F.models[ct]))):
            if F.model.variant[b, ct] == v:
                fn, fel, ft, xi_new, e_t = respond(F.models[ct][v], F, b, ct, u, udot, slip, nrm, m_eff, inv_mass_t,
                                                   dt, xi)
    return -fn * nrm + ft, udot, slip, fn, fel, ft, xi_new, e_t


@ti.func
def stored_energy(F: ti.template(), b, ct: ti.template(), u, fel):
    """Energy (J) in the spring of a contact of type ct with overlap u, elastic force fel."""
    el = 0.0
    if ti.static(len(F.models[ct]) == 1):
        el = elastic_energy(u, fel, ti.static(F.models[ct][0].normal.n))
    else:
        for v in ti.static(range(len(F.models[ct]))):
            if F.model.variant[b, ct] == v:
                el = elastic_energy(u, fel, ti.static(F.models[ct][v].normal.n))
    return el


@ti.func
def rolling_response(F: ti.template(), b, ct: ti.template(), spin_rel, nrm, fn, fel, u, r_eff, inv_inertia, dt, m_r):
    """(torque on the first body, work it removes over the step, new rolling history,
    its stored energy) of the rolling model of contact type ct; m_r: the contact's
    rolling history. The caller calls it only while F.model.mu_r[b, ct] > 0."""
    tq = ti.Vector([0.0, 0.0, 0.0])
    d, e_r = 0.0, 0.0
    m_new = m_r
    if ti.static(len(F.models[ct]) == 1):
        tq, d, m_new, e_r = ROLLING[F.models[ct][0].rolling.name](spin_rel, nrm, fn, fel, u, F.model.law_kt[b, ct],
                                                                 F.model.mu_r[b, ct], r_eff, m_r, inv_inertia, dt)
    else:
        for v in ti.static(range(len(F.models[ct]))):
            if F.model.variant[b, ct] == v:
                tq, d, m_new, e_r = ROLLING[F.models[ct][v].rolling.name](spin_rel, nrm, fn, fel, u, F.model.law_kt[b, ct],
                                                                         F.model.mu_r[b, ct], r_eff, m_r, inv_inertia, dt)
    return tq, d, m_new, e_r


@ti.func
def contact_energy(F: ti.template(), b, ct: ti.template(), u, udot, slip, fn, fel, ft, m_eff, inv_mass_t, dt):
    """What a contact's owner books of its response (contact_response): (normal
    dissipation, friction dissipation, stored elastic energy U). Dissipation over the
    step, (F - F_el) u̇ (damper and clamp) and -F_t · slip (friction), with u̇ and slip at
    mid-step as this contact's own impulse changes them: start-of-step values overstate
    it, most for stiff near-stick friction. (Only the owner's visit computes it: 3 %
    of a bed's force pass.)"""
    udot_mid = udot - 0.5 * fn * dt / m_eff
    dn = (fn - fel) * udot_mid * dt
    dtf = (-ft.dot(slip) - 0.5 * ft.norm_sqr() * inv_mass_t * dt) * dt
    return dn, dtf, stored_energy(F, b, ct, u, fel)
