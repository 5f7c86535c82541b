"""Normal damping: the dissipative part c g(u) u̇ of F = max(0, k uⁿ + c g(u) u̇), as a
shape g and the way its coefficient c is found (given, or calibrated to a restitution)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np


def smoothstep(s):
    """step(s) = s²(3-2s) on [0, 1], clamped outside (MSC.Adams STEP)."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def damping_ratio(e):
    """ζ of a linear oscillator rebounding with restitution e, eq 2.15."""
    ln_e = math.log(e)
    return -ln_e / math.sqrt(ln_e**2 + math.pi**2)


def _eq_2_16_damping(e, k, n, m_eff, u_ref):
    """c = 2ζ√(m_e k), eq 2.16; a Hertz law uses its tangent stiffness n k u_max^(n-1)
    at the peak overlap u_max of an impact at u_ref (m/s)."""
    k_lin = k if n == 1.0 else (n * k * ((n + 1) * m_eff * u_ref**2 / (2 * k)) ** ((n - 1) / (n + 1)))
    return 2.0 * damping_ratio(e) * math.sqrt(m_eff * k_lin)


def _hunt_crossley_damping(e, k, n, m_eff, u_ref):
    """λ/k = 3(1-e)/(2 u_ref), Hunt & Crossley 1975 (s/m)."""
    return 1.5 * (1.0 - e) / u_ref


def _tsuji_damping(e, k, n, m_eff, u_ref):
    """2√(5/6)·β with β = ζ of eq 2.15 (Tsuji 1992 / EDEM), dimensionless."""
    return 2.0 * math.sqrt(5.0 / 6.0) * damping_ratio(e)


@dataclass(frozen=True)
class Damping:
    """A damping shape g(u, uⁿ, k, n, d, m_eff) and its coefficient's first guess
    c(e, k, n, m_eff, u_ref) (closed form, ignoring the F ≥ 0 clamp). `name` is also the
    name of its Taichi twin."""

    name: str
    shape: Callable  #: g(u, un, k, n, d, m_eff), NumPy; un = uⁿ of the spring
    first_guess: Callable
    calibrated: bool = True  #: c calibrated to e at u_ref; False: c = c_max of the contact set
    parameters: tuple = ()  #: the contact set's parameters its force depends on besides k, n, c


STEP = Damping("adams-step", lambda u, un, k, n, d, m: smoothstep(u / d), _eq_2_16_damping,
               calibrated=False, parameters=("d",))  # MSC.Adams IMPACT, eqs 2.20 / 3.2
VISCOUS = Damping("viscous", lambda u, un, k, n, d, m: np.ones_like(u), _eq_2_16_damping)  # eqs 2.13, 2.18
HUNT_CROSSLEY = Damping("hunt-crossley", lambda u, un, k, n, d, m: k * un, _hunt_crossley_damping)  # eq 2.19
TSUJI = Damping("tsuji", lambda u, un, k, n, d, m: np.sqrt(m * n * k) * u ** (0.5 * (n - 1.0)),
                _tsuji_damping)  # √(m_e S_n), S_n = n k u^(n-1) (Tsuji 1992)
