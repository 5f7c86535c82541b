"""Contact sets: the normal laws of a friction pair's ball-ball and ball-wall contacts,
read from its [contact.*] table, their stiffness derived from the materials and their
damping calibrated to the restitution (taimill.model.laws).

A pair's measured set holds for its own ball and wall materials only. For any other
balls or wall the set is derived the way the thesis derived zirconia's (§2.1, §5): Hertz
stiffness from E, ν and the radii (eqs 3.3/3.4), c_max from the damped-vibration
solution with the materials' restitution (eqs 3.5/3.6, in the thesis' units), and d
fitted so that a simulated impact at the restitution's speed rebounds with it (the
thesis' drop-test fit of d). Its default law is hertz-mindlin, whose damping follows
from e at every speed (docs/media.md: why)."""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.model import laws as laws_np
from taimill.model import rules
from taimill.model.contact.model import NormalModel
from taimill.model.contact.registry import NAMES as LAW_NAMES, law_by_name
from taimill.model.contact.springs import hertz_stiffness, mindlin_stiffness, with_exponent
from taimill.model.jars import Jar
from taimill.model.materials import (MATERIALS_FILE, Balls, MaterialData, contact_table, load_friction, load_material,
                                     material_data)
from taimill.model.tables import Table

CONTACT_KEYS = ("ball", "wall", "law", "ball_radius_mm", "ball_ball", "ball_wall")
NORMAL_LAW_KEYS = ("c_max_Ns_per_mm", "d_mm", "e", "u_ref_mm_s")
DERIVED_LAW = "hertz-mindlin"  #: default law of derived sets: the restitution holds at every speed


@dataclass(frozen=True)
class NormalLaw:
    """F = max(0, k uⁿ + c g(u) u̇) for one contact type (see taimill.model.laws)."""

    law: str
    k: float  #: N/m^n
    n: float  #: -
    c: float  #: damping, unit depends on the law (N·s/m for adams-impact)
    d: float  #: m, full-damping penetration (adams-impact)
    m_eff: float  #: kg, effective mass of the contact type
    e: float  #: nominal restitution (at u_ref for speed-dependent laws)
    u_ref: float  #: m/s
    kt: float = 0.0  #: N/m^1.5, Mindlin's tangential stiffness 8 G* √R_eff per √u (the `history` friction model)

    @property
    def model(self) -> NormalModel:
        """The law's composition of a spring and a damping (taimill.model.contact); a
        power spring if n differs from the law's own exponent (sensitivity studies)."""
        law = law_by_name(self.law)
        spring = with_exponent(law.spring, self.n)
        return law if spring is law.spring else dataclasses.replace(law, name=f"{law.name}, n = {self.n:g}", spring=spring)


def _normal_law(t: Table, law: str, k, m_eff, e_eff, r_eff) -> tuple:
    """One contact type, read: (its NormalModel, (c_max, e, k, m_eff, u_ref, d)); k is
    derived as the law's spring says; e_eff (Pa) and
    r_eff (m) of eq 2.17 give a linear spring's k*."""
    c_max = t.get("c_max_Ns_per_mm", lo=0, hi=1e6) * 1e3  # N·s/mm → N·s/m (docs/model.md, unit trap)
    d = t.get("d_mm", lo=0, lo_open=True, hi=100) * 1e-3
    e = t.get("e", lo=0, lo_open=True, hi=1)
    u_ref = t.get("u_ref_mm_s", lo=0, lo_open=True, hi=1e6) * 1e-3
    t.done()
    cl = law_by_name(law)
    if cl.calibrated and not e < 1.0:
        raise ConfigError(t.source, t.key("e"), e, f"law {law} needs a restitution in (0, 1)")
    k = cl.stiffness(k, m_eff, u_ref, e_eff, r_eff)
    return cl, (c_max, e, k, m_eff, u_ref, d)


def _normal_laws(law: str, *contacts) -> tuple:
    """NormalLaws of contact types read by _normal_law, their dampings calibrated in one
    batch (laws.calibrate_dampings: half the set-up time of one at a time)."""
    laws_np.calibrate_dampings([(cl, e, k, m_eff, u_ref, d)
                                for cl, (_, e, k, m_eff, u_ref, d) in contacts if cl.calibrated])
    return tuple(NormalLaw(law, k, cl.n, laws_np.calibrate_damping(cl, e, k, m_eff, u_ref, d) if cl.calibrated else c_max,
                           d, m_eff, e, u_ref)
                 for cl, (c_max, e, k, m_eff, u_ref, d) in contacts)


def eq_3_5_c_max(e, m_eff, u_ref, e_eff, r_eff) -> float:
    """c_m of eq 3.5 with k* of eq 3.6 as the thesis evaluated it, in MSC.Adams' units
    (m_eff kg, u̇ mm/s, E_e N/mm², R_e mm): the number its tables print as "kg/s" and Adams
    reads as N·s/mm (docs/model.md, unit trap). Arguments in SI (kg, m/s, Pa, m).
    Gives Table 3.2's 10.1 / 17.5 for the steel set and 0.34 / 0.60 for zirconia (0.33 / 0.57)."""
    k_star = (320.0 / 81.0 * m_eff * (u_ref * 1e3) ** 2 * (e_eff * 1e-6) ** 4 * (r_eff * 1e3) ** 2) ** 0.2
    ln_e = math.log(e)
    return -2.0 * ln_e / math.sqrt(ln_e**2 + math.pi**2) * math.sqrt(m_eff * k_star)


def pair_restitution(ball: MaterialData, wall: MaterialData) -> tuple[float, float, bool]:
    """(e, speed m/s, assumed) of a ball on a wall: the ball material's own for one
    material; of two, the lower restitution with the speed it is stated at, an
    assumption (the more dissipative partner governs; docs/media.md)."""
    if ball.name == wall.name:
        return ball.restitution, ball.restitution_speed, False
    low = min((ball, wall), key=lambda m: m.restitution)
    return low.restitution, low.restitution_speed, True


@functools.lru_cache(maxsize=64)
def derived_table(ball_name: str, wall_name: str, radius: float) -> dict:
    """The [contact.*] table derived for balls of `ball_name` of `radius` (m) on walls of
    `wall_name` (module docstring), in the file's keys and units."""
    ball, wall = material_data(ball_name), material_data(wall_name)
    bm, wm = ball.material, wall.material
    m = bm.density * 4.0 / 3.0 * math.pi * radius**3
    adams = law_by_name("adams-impact")
    contacts = {}
    for kind, e_u, k, m_eff, e_eff, r_eff in (
            ("ball_ball", (ball.restitution, ball.restitution_speed),
             hertz_stiffness(bm.youngs_modulus, bm.poisson, bm.youngs_modulus, bm.poisson, radius, radius),
             m / 2.0, bm.youngs_modulus / 2.0, radius / 2.0),
            ("ball_wall", pair_restitution(ball, wall)[:2],
             hertz_stiffness(bm.youngs_modulus, bm.poisson, wm.youngs_modulus, wm.poisson, radius),
             m, 1.0 / (1.0 / bm.youngs_modulus + 1.0 / wm.youngs_modulus), radius)):
        e, u_ref = e_u
        c_max = eq_3_5_c_max(e, m_eff, u_ref, e_eff, r_eff)  # N·s/mm
        d = laws_np.calibrate_depth(adams, e, k, c_max * 1e3, m_eff, u_ref)
        contacts[kind] = {"c_max_Ns_per_mm": c_max, "d_mm": d * 1e3, "e": e, "u_ref_mm_s": u_ref * 1e3}
    return {"ball": ball_name, "wall": wall_name, "law": DERIVED_LAW, "ball_radius_mm": radius * 1e3, **contacts}


def derived_notes(contact: str | None, ball_name: str, wall_name: str, radius: float, measured: tuple | None) -> list[str]:
    """Warning lines of a derived set: which set, from what, and the numbers it takes
    that are estimates or assumptions."""
    ball, wall = material_data(ball_name), material_data(wall_name)
    instead = (f"the pair's measured contact set '{contact}' is for {measured[0]} balls on {measured[1]} walls"
               if measured else "the pair has no measured contact set")
    e, _, assumed = pair_restitution(ball, wall)
    notes = [f"contact set derived for {ball_name} balls of {radius * 1e3:g} mm radius on {wall_name} walls ({instead}): "
             f"Hertz stiffness from E, nu and the radius, law {DERIVED_LAW} by default, ball-ball e = {ball.restitution:g} "
             f"({ball_name}), ball-wall e = {e:g}"
             + (f" (the lower of {ball_name} {ball.restitution:g} and {wall_name} {wall.restitution:g}: an assumption)"
                if assumed else f" ({ball_name})")]
    used = [ball] if not assumed else [ball, wall]
    return notes + [line for mat in used for line in mat.estimate_notes(
        ("restitution", "restitution_speed_mm_s"), "contact set from material")]


def contact_source(contact: str | None, balls: Balls, jar: Jar, notes: list | None = None):
    """(table, file, name) of the contact set for these balls and jar: the pair's measured
    set where its ball and wall materials are these, else the derived one (its warning
    lines appended to `notes`)."""
    measured = None
    if contact is not None:
        table, file, name = contact_table(contact)
        t = Table(table, file, f"contact.{name}.", known=CONTACT_KEYS)
        measured = (t.get("ball", kind=str), t.get("wall", kind=str))
        for key, mat in zip(("ball", "wall"), measured):
            load_material(mat, file, f"contact.{name}.{key}")
        if rules.measured_set_applies(*measured, balls, jar):
            return table, file, name
    name = f"derived-{balls.material.name}-on-{jar.wall_material}"
    table = derived_table(balls.material.name, jar.wall_material, balls.radius)
    if notes is not None:
        notes += derived_notes(contact, balls.material.name, jar.wall_material, balls.radius, measured)
    return table, f"{MATERIALS_FILE} (derived)", name


def contact_laws(contact: str | None, law: str | None, balls: Balls, jar: Jar, source, override=None,
                 notes: list | None = None):
    """(ball-ball, ball-wall) laws of a contact set (`contact_source`: measured or
    derived; a derived set's warnings go to `notes`). `override` replaces entries of its
    tables, same keys and units, e.g. {"ball_wall": {"d_mm": 0.1}} (calibration fits);
    range errors then name the command line."""
    table, file, name = contact_source(contact, balls, jar, notes)
    Table(table, file, f"contact.{name}.", known=CONTACT_KEYS)
    override = override or {}
    for k in override:
        if not isinstance(table.get(k, {}), dict):
            raise ConfigError(file, f"contact.{name}.{k}", table[k], "must be a table")
    table = {**table, **{k: {**table.get(k, {}), **v} for k, v in override.items()}}
    changed = frozenset(f"contact.{name}.{k}.{leaf}" for k, v in override.items() for leaf in v)
    t = Table(table, file, f"contact.{name}.", changed, known=CONTACT_KEYS)
    t.get("ball", kind=str)
    wall_mat = t.get("wall", kind=str)
    t.get("ball_radius_mm", lo=0, lo_open=True, hi=1000)
    law = law or t.get("law", kind=str, allowed=LAW_NAMES)
    t.used.add("law")
    bm, wm = balls.material, load_material(wall_mat, file)
    r, m = balls.radius, balls.mass
    k_bb = hertz_stiffness(bm.youngs_modulus, bm.poisson, bm.youngs_modulus, bm.poisson, r, r)
    k_bw = hertz_stiffness(bm.youngs_modulus, bm.poisson, wm.youngs_modulus, wm.poisson, r)
    e_bb = 1.0 / (2.0 / bm.youngs_modulus)  # eq 2.17: 1/E_e = 1/E_i + 1/E_j
    e_bw = 1.0 / (1.0 / bm.youngs_modulus + 1.0 / wm.youngs_modulus)
    bb, bw = _normal_laws(law, _normal_law(t.table("ball_ball", known=NORMAL_LAW_KEYS), law, k_bb, m / 2.0, e_bb, r / 2.0),
                          _normal_law(t.table("ball_wall", known=NORMAL_LAW_KEYS), law, k_bw, m, e_bw, r))
    t.done()
    kt_bb = mindlin_stiffness(bm.youngs_modulus, bm.poisson, bm.youngs_modulus, bm.poisson, r / 2.0)
    kt_bw = mindlin_stiffness(bm.youngs_modulus, bm.poisson, wm.youngs_modulus, wm.poisson, r)
    return dataclasses.replace(bb, kt=kt_bb), dataclasses.replace(bw, kt=kt_bw)


def pair_contact(pair: str, radius: float | None = None, law: str | None = None, source="command line",
                 contact: dict | None = None, ball_material: str | None = None, wall_material: str | None = None,
                 notes: list | None = None):
    """Everything a single impact needs for a friction pair (a name or a pair file),
    without a preset: (Balls of one ball, Jar of the wall material, ball-ball law,
    ball-wall law, Friction). radius (m) defaults to the balls the contact set was
    fitted for; `contact` overrides entries of the contact set (see `contact_laws`);
    ball_material / wall_material other than the set's give its derived set (a pair
    without a measured set needs both, and a radius)."""
    friction, contact_id = load_friction(pair, source, base=Path.cwd())
    if contact_id is None:
        if ball_material is None or wall_material is None or radius is None:
            raise ConfigError(source, "pair", pair, "names no measured normal laws: give the ball and wall materials and the radius")
        ball_mat, wall_mat = ball_material, wall_material
    else:
        db, file, name = contact_table(contact_id)
        t = Table(db, file, f"contact.{name}.", known=CONTACT_KEYS)  # checked in full by contact_laws
        radius = radius or t.get("ball_radius_mm", lo=0, lo_open=True, hi=1000) * 1e-3
        ball_mat = ball_material or t.get("ball", kind=str)
        wall_mat = wall_material or t.get("wall", kind=str)
    ball = Balls(1, load_material(ball_mat, source, "ball material"), radius)
    load_material(wall_mat, source, "wall material")
    jar = Jar("plate", "drop test", 10.0, wall_mat, (("circle", {"radius": 1.0}),))  # a 2 m wide plate
    if law is not None and law not in LAW_NAMES:
        raise ConfigError(source, "law", law, f"must be one of {', '.join(LAW_NAMES)}")
    bb, bw = contact_laws(contact_id, law, ball, jar, source, contact, notes)
    return ball, jar, bb, bw, friction


def soften(law: NormalLaw, factor: float) -> NormalLaw:
    """The law with its stiffness divided by `factor` (≥ 1; DEM practice to lengthen the
    time step: a Hertz contact lasts factor^(2/5) longer), keeping its restitution: the
    full-damping overlap d grows as an impact's peak overlap does, factor^(1/(n+1)), and
    the damping c is chosen so that a simulated head-on impact at u_ref rebounds as the
    stiff law's does. A law whose damping depends on the overlap only through u/d
    (adams-impact) or as a power of the overlap times √(k m) (the Hertz dampers) is then
    the stiff law on a stretched length and time scale, and keeps its restitution at
    every impact speed (tests/test_spectra.py checks it from 5 cm/s to 4 m/s). Mindlin's
    tangential stiffness kt is divided by the same factor. factor 1: the law itself."""
    if factor == 1.0:
        return law
    model = law.model
    e = float(laws_np.simulate_impact(model, law.k, law.c, law.d, law.m_eff, law.u_ref)["e"][0])
    k = law.k / factor
    d = law.d * factor ** (1.0 / (law.n + 1.0))
    lo, hi = 0.0, law.c  # a softer contact needs less damping for the same rebound
    for _ in range(5):  # e falls as c grows: 17-point grids, each round 16× narrower
        grid = np.linspace(lo, hi, 17)
        got = laws_np.simulate_impact(model, k, grid, d, law.m_eff, law.u_ref)["e"]
        i = int(np.argmax(got <= e)) if (got <= e).any() else len(grid) - 1
        lo, hi = grid[max(i - 1, 0)], grid[i]
    return dataclasses.replace(law, k=k, c=0.5 * (lo + hi), d=d, kt=law.kt / factor)
