"""Wear of the balls and jar as mass, and the contamination it puts into the powder
(docs/wear.md). Pure functions of a run's powers by surface; the powder is not
simulated.

Each surface in a contact wears by Archard's law written on the work the contact
dissipates (Archard, J. Appl. Phys. 24, 981 (1953); the energy form e.g. Fouvry et
al., Wear 255, 287 (2003)):

    V = k_f W_f / H  +  k_i W_i / H

W_f: friction work of the contacts on that surface (J), W_i: normal stress energy of
its impacts at or above a threshold E_th (J), H: the surface's Vickers hardness (Pa),
k_f and k_i dimensionless wear coefficients. Archard's classical K (V = K F_n s / H)
is k_f μ: for a sliding contact W_f = μ F_n s. A ball–ball contact wears two ball
surfaces, a ball–wall contact one ball surface and the wall. The worn mass ρ V of
balls and walls all goes into the powder: the contamination as a mass fraction of the
powder is c(t) = M(t) / (M(t) + m_powder), M(t) the worn mass after t seconds.

k varies by orders of magnitude between material pairs, lubricating powders and wear
regimes, so it is fitted to a measured contamination (`fit`) and carries over only
between similar conditions (the same balls, jar and powder); the run gives the powers
that scale it from one condition to another.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from taimill.errors import ConfigError
from taimill.outcome.models import Param

HV_PA = 9.80665e6  #: Pa per Vickers unit (kgf/mm²)
KINDS = ("ball_ball", "side", "floor", "lid")  #: the run's contact kinds (its ledger)
WALLS = ("side", "floor", "lid")
SURFACES = ("balls", *WALLS)  #: what wears
HOUR = 3600.0


@dataclass(frozen=True)
class Body:
    """What wears: a material's name, density (kg/m³) and Vickers hardness (HV)."""

    material: str
    density: float
    hardness_hv: float

    @property
    def hardness(self) -> float:
        """Pa."""
        return self.hardness_hv * HV_PA


@dataclass(frozen=True)
class WearCondition:
    """A run as the wear model sees it: the friction power and the impact power at or
    above `threshold_j` on each contact kind (W), the balls and the jar wall, and the
    powder (g). `wall_map`: the run's WallMap (None: no event rows), for the depth map."""

    name: str
    friction_w: dict  #: kind -> W, friction work rate (impacts and persistent contacts)
    impact_w: dict  #: kind -> W, normal stress energy rate of impacts with se_n ≥ threshold_j; None: no rows
    threshold_j: float
    balls: Body
    wall: Body
    powder_g: float
    wall_map: object = field(default=None, compare=False, repr=False)


def archard_volume(work_j, k: float, hardness_pa: float):
    """m³: Archard's worn volume of one surface, V = k W / H."""
    return k * np.asarray(work_j, dtype=float) / hardness_pa


def volume_rates(cond: WearCondition, k_friction: float, k_impact: float = 0.0) -> dict:
    """m³/s worn from each surface (SURFACES) at the wear coefficients given."""
    impact = cond.impact_w or {}
    if k_impact > 0 and cond.impact_w is None:
        raise ConfigError(cond.name, "k_impact", k_impact, "0: this run kept no event rows, so its impact energies "
                          "above a threshold are not known (outputs.events = \"rows\")")

    def work(kind):
        return k_friction * cond.friction_w.get(kind, 0.0) + k_impact * impact.get(kind, 0.0)

    ball_work = 2.0 * work("ball_ball") + sum(work(w) for w in WALLS)
    out = {"balls": float(archard_volume(ball_work, 1.0, cond.balls.hardness))}
    out |= {w: float(archard_volume(work(w), 1.0, cond.wall.hardness)) for w in WALLS}
    return out


def mass_rates(cond: WearCondition, k_friction: float, k_impact: float = 0.0) -> dict:
    """g/h worn from each surface."""
    v = volume_rates(cond, k_friction, k_impact)
    return {s: v[s] * (cond.balls.density if s == "balls" else cond.wall.density) * 1e3 * HOUR for s in SURFACES}


def contamination(cond: WearCondition, k_friction: float, k_impact: float, time_s):
    """Mass fraction of worn ball and jar material in the powder after time_s (s)."""
    rate = sum(mass_rates(cond, k_friction, k_impact).values()) / HOUR  # g/s
    worn = rate * np.asarray(time_s, dtype=float)
    return worn / (worn + cond.powder_g)


def depth_map(cond: WearCondition, surface: str, k_friction: float, k_impact: float = 0.0):
    """(µm/h per cell, relative standard error per cell) of one wall surface: the
    surface's worn volume spread over its cells as the events' friction work and
    impact energy are spread (WallMap layers), divided by cell area. The error is the
    counting error of a sum of random events, √(Σe²)/Σe (NaN where no event landed;
    the map's cells outside the jar are NaN too). Persistent contacts are in no event
    row: their wear is spread like the events'."""
    m = cond.wall_map
    rate = volume_rates(cond, k_friction, k_impact)[surface]  # m³/s
    weights = k_friction * m.layers["friction"][surface] + k_impact * m.layers["impact"][surface]
    total = weights.sum()
    area = m.area(surface)
    with np.errstate(invalid="ignore", divide="ignore"):
        depth = np.where(area > 0, rate * HOUR * 1e6 * (weights / total if total > 0 else 0.0) / area, np.nan)
        sq = k_friction ** 2 * m.squares["friction"][surface] + k_impact ** 2 * m.squares["impact"][surface]
        rel = np.where((area > 0) & (weights > 0), np.sqrt(sq) / weights, np.nan)
    return depth, rel


def depth_summary(cond: WearCondition, k_friction: float, k_impact: float = 0.0) -> dict:
    """Per wall surface: its mean and deepest wear (µm/h), the deepest among cells with
    at least MIN_EVENTS events (fewer: too uncertain to name), with its counting error."""
    from taimill.analysis.spatial import MIN_EVENTS

    out = {}
    for s in WALLS:
        depth, rel = depth_map(cond, s, k_friction, k_impact)
        area = cond.wall_map.area(s)
        inside = area > 0
        rate = volume_rates(cond, k_friction, k_impact)[s]
        mean = float(rate * HOUR * 1e6 / area[inside].sum()) if inside.any() else math.nan
        ok = inside & (cond.wall_map.count[s] >= MIN_EVENTS)
        row = {"mean_um_per_h": mean, "max_um_per_h": math.nan, "max_rel_error": math.nan,
               "cells_sampled": int(ok.sum()), "cells": int(inside.sum())}
        if ok.any():
            i = np.unravel_index(int(np.argmax(np.where(ok, depth, -np.inf))), depth.shape)
            row |= {"max_um_per_h": float(depth[i]), "max_rel_error": float(rel[i])}
        out[s] = row
    return out


def mass_per_joule(kind: str, balls: Body, wall: Body) -> float:
    """kg worn per J of work (at k = 1) in a contact of `kind`: two ball surfaces for
    ball–ball, a ball surface and the wall for any wall kind."""
    per = {"balls": balls.density / balls.hardness, "wall": wall.density / wall.hardness}
    return 2.0 * per["balls"] if kind == "ball_ball" else per["balls"] + per["wall"]


def wear_keys(summary: dict, balls: Body | None, wall: Body | None, powder_g: float = math.nan) -> dict:
    """Summary keys of wear per unit wear coefficient, for sweep tables and the designer
    (`--objective wear_friction_g_per_h_per_k:min`): the mass the balls and walls lose
    per hour at k = 1, `wear_friction_g_per_h_per_k` from the friction work of every
    contact (the ledger) and `wear_impact_g_per_h_per_k` from the normal stress energy
    of stress events (the event estimator's ball–ball and ball–wall impact powers);
    with powder, `contamination_friction_per_h_per_k`: the first over the powder mass
    (the contamination's growth per hour while it is small). Multiply by a k
    (docs/wear.md) for grams. {} without the mechanisms or a material's hardness."""
    by = summary.get("dissipation_by_mechanism") or {}
    if not by or balls is None or wall is None or not (balls.hardness_hv > 0 and wall.hardness_hv > 0):
        return {}
    friction = sum(sum(parts.get(c, {}).get("friction", 0.0) for c in ("impact", "persistent"))
                   * mass_per_joule(kind, balls, wall) for kind, parts in by.items())
    impact = sum(summary.get(f"impact_power_normal_{kind}", math.nan) * mass_per_joule(kind, balls, wall)
                 for kind in ("ball_ball", "ball_wall"))
    out = {"wear_friction_g_per_h_per_k": friction * 1e3 * HOUR, "wear_impact_g_per_h_per_k": impact * 1e3 * HOUR}
    if powder_g > 0:
        out["contamination_friction_per_h_per_k"] = out["wear_friction_g_per_h_per_k"] / powder_g
    return out


@dataclass(frozen=True)
class Wear:
    """The wear model as the least-squares fit (taimill.outcome.fit) sees it: the
    contamination fraction at a condition and milling time."""

    measure: str = "friction work"
    stress_only: bool = False
    name = "archard-wear"
    quantity = "contamination (mass fraction)"
    drive = "rate"
    values = (0.0, 1.0)
    values_text = "[0, 1) (a fraction; contamination_pct for percent)"
    params = (Param("k_friction", True, "wear coefficient on friction work, V = k W_f / H"),
              Param("k_impact", True, "wear coefficient on impact energy above the threshold"))

    def value(self, params: dict, cond: WearCondition, time_s):
        return contamination(cond, params["k_friction"], params.get("k_impact", 0.0), time_s)

    def guess(self, _threshold, time_s, value, conds) -> dict:
        """k from each point alone with the other k at zero, the median of them."""
        t, c = np.asarray(time_s, float), np.asarray(value, float)
        worn = c / np.maximum(1.0 - c, 1e-12) * np.array([x.powder_g for x in conds])  # g
        guesses = {}
        for name, kw in (("k_friction", {"k_friction": 1.0, "k_impact": 0.0}),
                         ("k_impact", {"k_friction": 0.0, "k_impact": 1.0})):
            per = []
            for w, ti, x in zip(worn, t, conds):
                if name == "k_impact" and x.impact_w is None:
                    continue
                unit = sum(mass_rates(x, **kw).values()) / HOUR * ti
                if unit > 0 and w > 0:
                    per.append(w / unit)
            guesses[name] = float(np.median(per)) if per else 1e-6
        return guesses
