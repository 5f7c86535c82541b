"""Outcome models: what a milling condition's collisions do to the powder
(docs/outcome.md). Each model is a function of its parameters, a condition
(taimill.outcome.condition: spectra and powder) and the milling time t (s), and
says how long a condition takes to reach a target.

The energy measure is the model's choice, recorded with every fit: one of the spectra's
measures (taimill.model.spectra.MEASURES): energy dissipated by the normal damper or
by friction during an event, or the thesis' kinematic stress energy at onset, normal
or tangential. A "total dissipated" measure (normal + friction of the same event) is
not offered: the spectra bin the two separately, and the distribution of their sum per
event cannot be rebuilt from the two distributions (only its mean can).
`stress_only` counts only stress events (onset u̇n ≥ the spectra's threshold); by
default every contact counts and the energy threshold alone selects.

Rates and powers are per gram of the jar's powder, so that a parameter fitted on one
charge carries over to another.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from taimill.outcome.condition import Condition


@dataclass(frozen=True)
class Param:
    name: str  #: with its unit, e.g. "e_star_J"
    log: bool  #: positive, fitted (and its interval found) in log10
    text: str
    threshold: bool = False  #: an energy threshold: bounded by the spectra, scanned on a grid


@dataclass(frozen=True)
class CriticalCollisions:
    """Critical-collision first-order kinetics (Delogu, Cocco and co-workers; e.g.
    Colacino et al., ACS Omega 3, 9196 (2018); Carta et al., PCCP (2024)):

        α(t) = 1 − exp(−κ_g ṅ_g(E ≥ E*) t)

    α: converted fraction; ṅ_g(E ≥ E*): events per second and gram of powder whose
    energy (the chosen measure) is at least E*; κ_g (g): the powder mass one such
    critical collision converts, so that κ = κ_g / m_powder is the fraction of the
    charge it affects (the literature's κ). Assumptions: every collision above E*
    converts the same mass and none below does; the powder is mixed so that each
    collision meets unconverted powder in proportion 1 − α (first order); the rate
    does not change as the powder changes (the balls do not feel it here)."""

    measure: str
    stress_only: bool = False
    name = "critical-collisions"
    quantity = "converted fraction α"
    drive = "rate"  #: the Condition curve the threshold acts through
    values = (0.0, 1.0)  #: what a measured α may be: a fraction, never a percent
    values_text = "[0, 1] (a fraction; percent? divide by 100)"
    params = (Param("kappa_g", True, "powder mass one critical collision converts (g)"),
              Param("e_star_J", True, "critical energy E* (J)", threshold=True))

    def rate(self, p: dict, cond: Condition) -> float:
        """1/s: κ_g ṅ_g(E ≥ E*), the first-order rate constant."""
        return p["kappa_g"] * cond.rate(p["e_star_J"], self.measure, self.stress_only)

    def value(self, p: dict, cond: Condition, t) -> np.ndarray:
        return 1.0 - np.exp(-self.rate(p, cond) * np.asarray(t, dtype=float))

    def time_to(self, p: dict, cond: Condition, target: float) -> float:
        """s to reach α = target (0 < target < 1)."""
        k = self.rate(p, cond)
        return -math.log1p(-target) / k if 0 < target < 1 and k > 0 else math.nan

    def guess(self, threshold: float, t, y, conds) -> dict:
        """κ_g from −ln(1 − α) = κ_g ṅ_g t at each point (α clipped into (0, 1))."""
        rates = np.array([c.rate(threshold, self.measure, self.stress_only) for c in conds])
        y = np.clip(np.asarray(y, dtype=float), 1e-6, 1 - 1e-6)
        k = -np.log1p(-y) / np.maximum(np.asarray(t) * rates, 1e-300)
        return {"kappa_g": float(np.exp(np.median(np.log(k))))}


def specific_energy(p: dict, model, cond: Condition, t) -> np.ndarray:
    """kJ/g: E_m = P_g(E ≥ E_thr) t, the energy per gram in events at or above the
    threshold (the chosen measure) after milling t s."""
    return cond.power(p["e_threshold_J"], model.measure, model.stress_only) * np.asarray(t, dtype=float) * 1e-3


def doses(model, threshold: float, t, conds) -> np.ndarray:
    """kJ/g: E_m of each point (time t[i] at condition conds[i])."""
    power = np.array([c.power(threshold, model.measure, model.stress_only) for c in conds])
    return power * np.asarray(t, dtype=float) * 1e-3


@dataclass(frozen=True)
class DoseExponential:
    """Dose–response of a size-like quantity y (crystallite or particle size) to the
    specific energy E_m (kJ/g) in events above a threshold energy:

        y = y_∞ + (y₀ − y_∞) exp(−E_m / E_c)

    The stress model (Kwade; Burmeister & Kwade, Chem. Soc. Rev. 42, 7660 (2013)) holds
    that the product is a function of the specific energy taken up by the powder once
    each stress exceeds what the particles need; the exponential approach to a
    grinding limit y_∞ is the usual empirical form for crystallite size against
    milling dose. Assumptions: a fixed share of the energy above the threshold reaches
    the powder at every condition; y depends on the dose only, not on how it is split
    between few strong and many weak events above the threshold."""

    measure: str
    stress_only: bool = False
    name = "dose-exponential"
    quantity = "y (a size)"
    drive = "power"
    values = None  #: any finite y (the unit is the user's)
    params = (Param("y0", False, "y before milling"), Param("y_inf", False, "y after a very large dose"),
              Param("e_c_kJ_per_g", True, "characteristic specific energy E_c (kJ/g)"),
              Param("e_threshold_J", True, "events below this energy do not count (J)", threshold=True))

    def value(self, p: dict, cond: Condition, t) -> np.ndarray:
        em = specific_energy(p, self, cond, t)
        return p["y_inf"] + (p["y0"] - p["y_inf"]) * np.exp(-em / p["e_c_kJ_per_g"])

    def time_to(self, p: dict, cond: Condition, target: float) -> float:
        share = (target - p["y_inf"]) / (p["y0"] - p["y_inf"]) if p["y0"] != p["y_inf"] else math.nan
        power = cond.power(p["e_threshold_J"], self.measure, self.stress_only)
        if not 0 < share <= 1 or not power > 0:
            return math.nan
        return -p["e_c_kJ_per_g"] * math.log(share) / (power * 1e-3)

    def guess(self, threshold: float, t, y, conds) -> dict:
        order = np.argsort(t)
        em = doses(self, threshold, t, conds)
        return {"y0": float(np.asarray(y)[order[0]]), "y_inf": float(np.min(y) if y[order[0]] > y[order[-1]] else np.max(y)),
                "e_c_kJ_per_g": float(max(np.median(em[em > 0]) if (em > 0).any() else 1.0, 1e-12))}


@dataclass(frozen=True)
class DosePower:
    """The power-law variant of the dose–response (same assumptions as DoseExponential):

        y = y₀ (1 + E_m / E_c)^(−n)

    For E_m ≫ E_c this is y ∝ E_m^(−n), the straight line of size against specific
    energy in log–log plots of the stress model literature (Burmeister & Kwade 2013);
    E_c keeps y finite at E_m = 0. It has no grinding limit."""

    measure: str
    stress_only: bool = False
    name = "dose-power"
    quantity = "y (a size)"
    drive = "power"
    values = None  #: any finite y (the unit is the user's)
    params = (Param("y0", False, "y before milling"),
              Param("e_c_kJ_per_g", True, "specific energy where y has fallen by 2^n (kJ/g)"),
              Param("n", True, "exponent"),
              Param("e_threshold_J", True, "events below this energy do not count (J)", threshold=True))

    def value(self, p: dict, cond: Condition, t) -> np.ndarray:
        em = specific_energy(p, self, cond, t)
        return p["y0"] * (1.0 + em / p["e_c_kJ_per_g"]) ** (-p["n"])

    def time_to(self, p: dict, cond: Condition, target: float) -> float:
        power = cond.power(p["e_threshold_J"], self.measure, self.stress_only)
        if not 0 < target <= p["y0"] or not power > 0:
            return math.nan
        return p["e_c_kJ_per_g"] * ((target / p["y0"]) ** (-1.0 / p["n"]) - 1.0) / (power * 1e-3)

    def guess(self, threshold: float, t, y, conds) -> dict:
        em = doses(self, threshold, t, conds)
        return {"y0": float(np.asarray(y)[np.argmin(t)]), "n": 0.5,
                "e_c_kJ_per_g": float(max(np.median(em[em > 0]) if (em > 0).any() else 1.0, 1e-12))}


MODELS = {m.name: m for m in (CriticalCollisions, DoseExponential, DosePower)}


def stress_model_points(conds: dict[str, Condition], points, measure: str, threshold: float,
                        stress_only: bool = False) -> list[dict]:
    """The stress-model plot (Kwade): for each measured point (condition, time_s,
    value), the mean stress energy SE (J: mean `measure` of the events at or above
    `threshold` J) and the stress number SN (such events per gram of powder after
    time_s; the literature's per-particle number needs the particle mass, which
    taimill does not know). The product quantity is then plotted against SE and SN."""
    out = []
    for c, t, v in points:
        cond = conds[c]
        rate = float(cond.rate(threshold, measure, stress_only))
        power = float(cond.power(threshold, measure, stress_only))
        out.append({"condition": c, "time_s": t, "value": v, "stress_energy_J": power / rate if rate > 0 else math.nan,
                    "stress_number_per_g": rate * t})
    return out
