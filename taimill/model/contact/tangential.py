"""Tangential sub-models: the friction force at a contact, from the slip velocity of
the contact points (m/s) and the normal force (N)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from taimill.model.contact.damping import smoothstep


def friction_coefficient(v, mu_s, mu_d, v_s, v_d):
    """Regularised Coulomb μ(v), thesis eq 3.7: μ_s·step(v/v_s), then easing to μ_d at v_d."""
    v = np.asarray(v, dtype=float)
    rise = mu_s * smoothstep(v / v_s)
    fall = mu_s - (mu_s - mu_d) * smoothstep((v - v_s) / (v_d - v_s))
    return np.where(v < v_s, rise, fall)


def friction_force(slip, f_n, mu_s, mu_d, v_s, v_d, inv_mass_t, dt):
    """Friction force (N, 3-vector) opposing the slip velocity `slip` (m/s). Its impulse
    in one step is capped at the one that brings the slip to rest (never reverses it):
    |F| dt · inv_mass_t ≤ |slip|, with inv_mass_t = Σ 1/m + a²/I over both bodies."""
    slip = np.asarray(slip, dtype=float)
    vs = np.linalg.norm(slip)
    if vs == 0.0:
        return np.zeros(3)
    mag = min(friction_coefficient(vs, mu_s, mu_d, v_s, v_d) * f_n, vs / (dt * inv_mass_t))
    return -mag * slip / vs


@dataclass(frozen=True)
class Tangential:
    """A tangential sub-model: its NumPy force and its coefficients (the Friction
    fields it reads). `name` is also the name of its Taichi twin."""

    name: str
    force: object  #: NumPy twin of the Taichi force
    coefficients: tuple  #: Friction fields it reads
    history: bool = False  #: keeps a per-contact state between steps


# thesis eq 3.7, with the impulse cap that keeps a stiff stick from reversing the slip
REGULARISED_COULOMB = Tangential("regularised-coulomb", friction_force, ("mu_s", "mu_d", "v_s", "v_d"))
