"""Normal springs: the elastic part k uⁿ of the normal force (u ≥ 0 overlap, m)."""

from __future__ import annotations

import math
from dataclasses import dataclass


def hertz_stiffness(e1, nu1, e2, nu2, r1, r2=None):
    """Hertz k (N/m^1.5), eqs 2.10-2.12: 4/(3π)·1/(η₁+η₂)·√R_eff, η = (1-ν²)/(πE).
    r2 = None is a plane (sphere-plane uses √R_ball, eq 2.11)."""
    eta = (1 - nu1**2) / (math.pi * e1) + (1 - nu2**2) / (math.pi * e2)
    r_eff = r1 if r2 is None else r1 * r2 / (r1 + r2)
    return 4.0 / (3.0 * math.pi) / eta * math.sqrt(r_eff)


def mindlin_stiffness(e1, nu1, e2, nu2, r_eff):
    """Mindlin's tangential stiffness per √overlap (N/m^1.5): k_t = 8 G* √(R_eff u) with
    1/G* = (2-ν₁)/G₁ + (2-ν₂)/G₂, G = E/(2(1+ν)) (Mindlin 1949; as LIGGGHTS' hertz model)."""
    g_star = 1.0 / (2.0 * (2.0 - nu1) * (1.0 + nu1) / e1 + 2.0 * (2.0 - nu2) * (1.0 + nu2) / e2)
    return 8.0 * g_star * math.sqrt(r_eff)


def di_maio_stiffness(m_eff, u_ref, e_eff, r_eff):
    """Linear stiffness k* (N/m) matching Hertz' peak force/overlap ratio, eq 2.17."""
    return (320.0 / 81.0 * m_eff * u_ref**2 * e_eff**4 * r_eff**2) ** 0.2


@dataclass(frozen=True)
class Spring:
    """F_el = k uⁿ. `name` is also the name of its Taichi twin."""

    name: str
    n: float  #: exponent

    def power(self, u):
        """uⁿ (u ≥ 0). (The Taichi twin takes u√u for n = 3/2: equal to 1 ulp.)"""
        return u**self.n

    def stiffness(self, k_hertz, m_eff, u_ref, e_eff, r_eff):
        """k: Hertz' k (N/m^1.5), or for a linear spring k* of eq 2.17 (N/m)."""
        return di_maio_stiffness(m_eff, u_ref, e_eff, r_eff) if self.n == 1.0 else k_hertz


HERTZ = Spring("hertz", 1.5)  # eqs 2.10-2.12
LINEAR = Spring("linear", 1.0)  # eq 2.13 with k* of eq 2.17
POWER = Spring("power", 1.5)  # any other exponent (the sensitivity study of thesis Fig 2.5 varies n)


def with_exponent(spring: Spring, n: float) -> Spring:
    """`spring` if its exponent is n, else the power spring with exponent n."""
    return spring if spring.n == n else Spring(POWER.name, n)
