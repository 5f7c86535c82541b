"""EPSD2 rolling resistance, Taichi twin of taimill.model.contact.rolling_epsd2 (the
physics and its sources are described there)."""

from taimill.physics.ti import ti


@ti.func
def epsd2_torque(spin_rel, nrm, fn, fel, u, kt, mu_r, r_eff, m_r, inv_inertia, dt):
    """epsd2: (torque on the first body, work it removes over the step, M', stored
    energy) in the rolling sub-models' signature."""
    w_r = spin_rel - spin_rel.dot(nrm) * nrm
    kr = kt * ti.sqrt(u) * r_eff * r_eff
    m = m_r + kr * dt * w_r
    cap = mu_r * r_eff * ti.abs(fn)
    mag = m.norm()
    if mag > cap:
        m *= cap / mag
    tq = -m
    return tq, (-tq.dot(w_r) - 0.5 * tq.norm_sqr() * inv_inertia * dt) * dt, m, 0.5 * m.norm_sqr() / kr
