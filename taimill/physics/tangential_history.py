"""Tangential spring with history, Taichi twin of taimill.model.contact.tangential_history
(the physics and its sources are described there)."""

from taimill.physics.ti import ti


@ti.func
def history_force(slip, nrm, fn, u, mu_s, mu_d, v_s, v_d, kt, xi, inv_mass_t, dt):
    """history: (F_t, ξ', stored energy) in the tangential sub-models' signature; the
    Coulomb cap is μ_d |F_n| (μ_s, v_s, v_d unused)."""
    x = xi + slip * dt
    x -= x.dot(nrm) * nrm
    k = kt * ti.sqrt(u)
    f = -k * x
    cap = mu_d * ti.abs(fn)
    mag = f.norm()
    if mag > cap:
        if mag > 0.0:
            f *= cap / mag
            x = -f / k
        else:
            f = ti.Vector([0.0, 0.0, 0.0])
    return f, x, 0.5 * k * x.dot(x)
