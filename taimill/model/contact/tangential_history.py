"""Tangential spring with history (Mindlin / Cundall–Strack), as LIGGGHTS' `tangential
history` with `tangential_damping off`: the contact points' relative tangential
displacement ξ is accumulated over the contact's life, projected onto the current
tangent plane each step, and pulls back with F_t = −k_t ξ, k_t = 8 G* √(R_eff u)
(Mindlin 1949). Where |F_t| would exceed μ F_n (μ = the pair's μ_d; F_n the total normal
force) the contact slides: F_t is scaled to μ F_n and ξ to the displacement that gives
it. The spring stores ½ k_t |ξ|², returned so that the energy ledger keeps it apart from
what is dissipated."""

from __future__ import annotations

import numpy as np

from taimill.model.contact.tangential import Tangential


def history_force(slip, nrm, f_n, u, mu, kt, xi, dt):
    """(F_t (N), ξ' (m), stored energy (J)) after one step of slip velocity `slip` (m/s)
    at overlap u (m) with normal nrm; kt (N/m^1.5) = 8 G* √R_eff, xi the previous ξ."""
    nrm = np.asarray(nrm, dtype=float)
    xi = np.asarray(xi, dtype=float) + np.asarray(slip, dtype=float) * dt
    xi = xi - xi.dot(nrm) * nrm
    k = kt * np.sqrt(u)
    f = -k * xi
    cap = mu * abs(f_n)
    mag = np.linalg.norm(f)
    if mag > cap:
        if mag > 0.0:
            f = f * (cap / mag)
            xi = -f / k
        else:
            f = np.zeros(3)
    return f, xi, 0.5 * k * xi.dot(xi)


HISTORY = Tangential("history", history_force, ("mu_d",), history=True)
