"""EPSD2 rolling resistance (Iwashita & Oda 1998; Wensrich & Katterfeld 2012), as
LIGGGHTS' `rolling_friction epsd2`: an elastic–perfectly-plastic spring torque on the
relative rolling ω_r (the relative spin without its twist about the normal),
M ← M + k_r ω_r dt with k_r = k_t R_eff² (k_t = 8 G* √(R_eff u), the tangential
stiffness), capped at μ_r R_eff |F_n| (F_n the total normal force); the torque on the
first body is −M. No dashpot. The spring stores ½ |M|²/k_r, returned so that the
energy ledger keeps it apart from what is dissipated. The stored M is not rotated with
the contact (as in LIGGGHTS)."""

from __future__ import annotations

import math

import numpy as np

from taimill.model.contact.rolling import Rolling, rolling_velocity


def epsd2_torque(spin_rel, normal, f_n, u, kt, mu_r, r_eff, m_r, inv_inertia, dt):
    """(torque on the first body (N m), work it removes over the step (J), M' (N m),
    stored energy (J)); inv_inertia = Σ 1/I of the bodies (a wall: 1/I_ball)."""
    w_r = rolling_velocity(spin_rel, normal)
    kr = kt * math.sqrt(u) * r_eff * r_eff
    m = np.asarray(m_r, dtype=float) + kr * dt * w_r
    cap = mu_r * r_eff * abs(f_n)
    mag = np.linalg.norm(m)
    if mag > cap:
        m = m * (cap / mag)
    tq = -m
    work = (-tq.dot(w_r) - 0.5 * tq.dot(tq) * inv_inertia * dt) * dt
    return tq, work, m, 0.5 * m.dot(m) / kr


def _epsd2_dt(inertia, mu_r, r_eff, f_n):
    """No bound of its own: k_r = k_t R_eff² turns the relative rolling at
    ω² = k_r Σ 1/I, 1.25 k_t/m for two equal balls and 2.5 k_t/m on a wall (I = 2/5 m r²),
    slower than the tangential spring on the same contact (3.5 and 7 k_t/m), whose
    frequency is 1.7× the normal contact's for steel: at the automatic 24 steps per
    contact ω dt ≈ 0.2, far below the explicit limit 2."""
    return math.inf


EPSD2 = Rolling("epsd2", epsd2_torque, _epsd2_dt, history=True)
