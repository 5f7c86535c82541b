"""The charge and its dose (docs/outcome.md): the dissipated power of one jar per gram
of its powder, the specific energy after a milling time, the rate of collisions above
an energy per gram, and the "gentle / shear" view of persistent friction.

Pure functions of a run's summary (W, taimill.analysis.summary) and resolved config
(`config["powder"] = {"mass": kg, "ball_to_powder": BPR}`, taimill.model.charge). A run
simulates one jar and the powder mass is per jar, so the ratios need no station count.
Without powder the dose functions return {} (or NaN): there is nothing to divide by.
"""

from __future__ import annotations

import math

from taimill.analysis.spectra import rate_above
from taimill.model.spectra import Spectra

WALL_KINDS = ("side", "floor", "lid")  #: the wall parts of summary["dissipation_by_mechanism"]
#: summary key -> the suffix of its dose key: the whole jar, by class and by part of the law
SPLITS = {"dissipated_power": "", "dissipated_power_impact": "_impact",
          "dissipated_power_persistent": "_persistent", "dissipated_power_normal": "_normal",
          "dissipated_power_friction": "_shear"}


def powder_grams(config: dict) -> float:
    """g of powder in the jar (NaN: the preset has no [powder] table)."""
    powder = (config or {}).get("powder") or {}
    mass = powder.get("mass")
    return float(mass) * 1e3 if isinstance(mass, (int, float)) and mass > 0 else math.nan


def dose_keys(summary: dict, config: dict) -> dict:
    """Summary keys of the dose: the dissipated power per gram of powder (W/g), in all
    and split into impacts / persistent contacts and normal / shear (friction) work, and
    the powder itself (g, BPR). {} without powder."""
    grams = powder_grams(config)
    if not math.isfinite(grams):
        return {}
    out = {"powder_mass_g": grams, "ball_to_powder": float(config["powder"].get("ball_to_powder", math.nan))}
    for key, suffix in SPLITS.items():
        if isinstance(summary.get(key), (int, float)):
            out[f"specific_power{suffix}_W_per_g"] = summary[key] / grams
    spectra = summary.get("spectra") or {}
    per_g = {m: {e: r / grams for e, r in d["rate_above"].items()} for m, d in spectra.items()
             if isinstance(d, dict) and isinstance(d.get("rate_above"), dict)}
    if per_g:  # stress events per second and gram at or above each energy (J) of the summary's spectra
        out["rate_above_per_g"] = per_g
    return out


def specific_energy(summary: dict, config: dict, seconds: float) -> float:
    """kJ/g: the energy the jar dissipates in `seconds` of milling per gram of powder,
    E_m = P_diss t / m_powder (the dose comminution results are plotted against;
    Burmeister & Kwade, Chem. Soc. Rev. 42, 7660 (2013)). NaN without powder."""
    return summary.get("dissipated_power", math.nan) * seconds / powder_grams(config) * 1e-3


def rate_per_gram(sp: Spectra, energy: float, measure: str, powder_g: float, kind: str | None = None) -> float:
    """Stress events per second and gram of powder whose `measure` is at least
    `energy` J (taimill.analysis.spectra.rate_above / powder mass)."""
    return rate_above(sp, energy, measure, kind) / powder_g if powder_g > 0 else math.nan


def shear_keys(summary: dict, wall_area_m2: float) -> dict:
    """The "gentle / shear" view: friction (shear) power in persistent contacts, the
    tangential action a bed sliding and rolling on the wall delivers without impacts.
    `shear_power_persistent_W` (all contact kinds), `shear_share` of the dissipated
    power, and the wall's part per unit wall area (W/m², side + floor + lid over
    `wall_area_m2`, the jar's inner area). {} without the dissipation by mechanism."""
    by = summary.get("dissipation_by_mechanism") or {}
    if not by:
        return {}
    friction = {k: (parts.get("persistent") or {}).get("friction", 0.0) for k, parts in by.items()}
    total = sum(friction.values())
    wall = sum(friction.get(k, 0.0) for k in WALL_KINDS)
    dissipated = summary.get("dissipated_power", math.nan)
    return {"shear_power_persistent_W": total,
            "shear_share": min(total / dissipated, 1.0) if dissipated else math.nan,  # a part ≤ the whole: rounding
            "shear_power_persistent_wall_W_per_m2": wall / wall_area_m2 if wall_area_m2 > 0 else math.nan}
