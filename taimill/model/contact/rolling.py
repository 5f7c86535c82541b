"""Rolling-resistance sub-models: a torque against the relative rolling of two bodies."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np


def rolling_velocity(spin_rel, normal):
    """ω_r (rad/s, 3-vector): the relative spin ω_i − ω_j (absolute spins; a wall turns
    with the jar) without its twist about the contact normal."""
    spin_rel, normal = np.asarray(spin_rel, dtype=float), np.asarray(normal, dtype=float)
    return spin_rel - spin_rel.dot(normal) * normal


def rolling_torque(spin_rel, normal, f_n, mu_r, r_eff, inv_inertia, dt):
    """Rolling-resistance torque (N m, 3-vector) on the first body: a constant torque
    μ_r R_eff F_n against the relative rolling ω_r (Ai et al. 2011 model A; LIGGGHTS
    `rolling_friction cdt`, EDEM's constant directional torque). Regularised like the
    friction force: its angular impulse in one step never exceeds the one that stops
    ω_r, |M| dt · inv_inertia ≤ |ω_r| with inv_inertia = 1/I_i + 1/I_j (a wall: 1/I_i),
    so near ω_r = 0 it settles the rolling instead of flipping sign every step."""
    w_r = rolling_velocity(spin_rel, normal)
    wn = np.linalg.norm(w_r)
    if wn == 0.0 or mu_r == 0.0:
        return np.zeros(3)
    mag = min(mu_r * r_eff * f_n, wn / (dt * inv_inertia))
    return -mag * w_r / wn


def rolling_dissipation(torque, spin_rel, normal, inv_inertia, dt):
    """Energy (J) the rolling torque dissipates over one step: −M·ω_r at mid-step, as
    its own angular impulse changes ω_r (as for friction)."""
    torque = np.asarray(torque, dtype=float)
    return (-torque.dot(rolling_velocity(spin_rel, normal)) - 0.5 * torque.dot(torque) * inv_inertia * dt) * dt


def _constant_torque_dt(inertia, mu_r, r_eff, f_n):
    """No bound: the capped torque acts like a rotational damper of at most c = I/dt
    (it stops ω_r in one step, never more), and an explicit damper is stable for
    c·dt/I < 2; acting together with the capped friction on the same spin the sum stays
    below 1 + (r²/I)/(1/m + r²/I) = 12/7 < 2 for a solid sphere."""
    return math.inf


@dataclass(frozen=True)
class Rolling:
    """A rolling-resistance sub-model: its NumPy torque and the time step its explicit
    integration needs. `name` is also the name of its Taichi twin. μ_r = 0 switches
    rolling resistance off (the thesis model): the torque is then never computed."""

    name: str
    torque: Callable  #: (spin_rel, normal, f_n, mu_r, r_eff, inv_inertia, dt) -> N m
    dt_limit: Callable  #: (inertia kg m², mu_r, r_eff m, f_n N) -> s
    history: bool = False  #: keeps a per-contact state between steps


CONSTANT_TORQUE = Rolling("constant-torque", rolling_torque, _constant_torque_dt)
