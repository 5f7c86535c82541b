"""A contact model as a composition of sub-models (package docstring)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from taimill.model.contact.damping import Damping
from taimill.model.contact.rolling import Rolling
from taimill.model.contact.springs import Spring
from taimill.model.contact.tangential import Tangential


@dataclass(frozen=True)
class NormalModel:
    """F = max(0, k uⁿ + c g(u) u̇): a spring and a damping, under a law's name."""

    name: str
    spring: Spring
    damping: Damping
    constant_e: bool = False  #: restitution independent of the impact speed

    @property
    def n(self) -> float:
        return self.spring.n

    @property
    def calibrated(self) -> bool:
        """c is calibrated to the restitution e at u_ref (else c = c_max as given)."""
        return self.damping.calibrated

    @property
    def parameters(self) -> tuple:
        """The NormalLaw fields its force depends on."""
        return ("k", "n", "c") + self.damping.parameters

    def shape(self, u, k, d, m_eff):
        """g(u) of the damping."""
        return self.damping.shape(u, self.spring.power(u), k, self.n, d, m_eff)

    def force(self, u, udot, k, c, d, m_eff):
        """(F, F_elastic): the clamped normal force and its spring part, N. u ≥ 0 assumed."""
        u = np.maximum(u, 0.0)
        un = self.spring.power(u)
        f_el = k * un
        return np.maximum(0.0, f_el + c * self.damping.shape(u, un, k, self.n, d, m_eff) * udot), f_el

    def first_guess(self, e, k, m_eff, u_ref):
        """Closed-form damping c for restitution e, ignoring the F ≥ 0 clamp."""
        return self.damping.first_guess(e, k, self.n, m_eff, u_ref)

    def stiffness(self, k_hertz, m_eff, u_ref, e_eff, r_eff):
        return self.spring.stiffness(k_hertz, m_eff, u_ref, e_eff, r_eff)


@dataclass(frozen=True)
class ContactModel:
    """normal spring + damping + tangential + rolling: what a kernel is compiled for."""

    normal: NormalModel
    tangential: Tangential
    rolling: Rolling

    @property
    def name(self) -> str:
        return f"{self.normal.name} + {self.tangential.name} + {self.rolling.name}"
