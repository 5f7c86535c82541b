"""Contact sets: the normal laws of a friction pair's ball-ball and ball-wall contacts,
read from its [contact.*] table, their stiffness derived from the materials and their
damping calibrated to the restitution (taimill.model.laws)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from taimill.errors import ConfigError
from taimill.model import laws as laws_np
from taimill.model import rules
from taimill.model.contact.model import NormalModel
from taimill.model.contact.registry import NAMES as LAW_NAMES, law_by_name
from taimill.model.contact.springs import hertz_stiffness, mindlin_stiffness, with_exponent
from taimill.model.jars import Jar
from taimill.model.materials import Balls, contact_table, load_friction, load_material
from taimill.model.tables import Table

CONTACT_KEYS = ("ball", "wall", "law", "ball_radius_mm", "ball_ball", "ball_wall")
NORMAL_LAW_KEYS = ("c_max_Ns_per_mm", "d_mm", "e", "u_ref_mm_s")


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


def contact_laws(contact: str, law: str | None, balls: Balls, jar: Jar, source, override=None):
    """(ball-ball, ball-wall) laws of a contact set. `override` replaces entries of its
    tables, same keys and units, e.g. {"ball_wall": {"d_mm": 0.1}} (calibration fits);
    range errors then name the command line."""
    table, file, name = contact_table(contact)
    Table(table, file, f"contact.{name}.", known=CONTACT_KEYS)
    override = override or {}
    for k in override:
        if not isinstance(table.get(k, {}), dict):
            raise ConfigError(file, f"contact.{name}.{k}", table[k], "must be a table")
    table = {**table, **{k: {**table.get(k, {}), **v} for k, v in override.items()}}
    changed = frozenset(f"contact.{name}.{k}.{leaf}" for k, v in override.items() for leaf in v)
    t = Table(table, file, f"contact.{name}.", changed, known=CONTACT_KEYS)
    ball_mat = t.get("ball", kind=str)
    wall_mat = t.get("wall", kind=str)
    t.get("ball_radius_mm", lo=0, lo_open=True, hi=1000)
    law = law or t.get("law", kind=str, allowed=LAW_NAMES)
    t.used.add("law")
    rules.contact_set_fits(source, contact, ball_mat, wall_mat, balls, jar)
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
                 contact: dict | None = None):
    """Everything a single impact needs for a friction pair (a name or a pair file),
    without a preset: (Balls of one ball, Jar of the wall material, ball-ball law,
    ball-wall law, Friction). radius (m) defaults to the balls the contact set was
    fitted for; `contact` overrides entries of the contact set (see `contact_laws`)."""
    friction, contact_id = load_friction(pair, source, base=Path.cwd())
    db, file, name = contact_table(contact_id)
    t = Table(db, file, f"contact.{name}.", known=CONTACT_KEYS)  # checked in full by contact_laws
    radius = radius or t.get("ball_radius_mm", lo=0, lo_open=True, hi=1000) * 1e-3
    ball = Balls(1, load_material(t.get("ball", kind=str), file), radius)
    jar = Jar("plate", "drop test", 10.0, t.get("wall", kind=str), (("circle", {"radius": 1.0}),))  # a 2 m wide plate
    if law is not None and law not in LAW_NAMES:
        raise ConfigError(source, "law", law, f"must be one of {', '.join(LAW_NAMES)}")
    bb, bw = contact_laws(contact_id, law, ball, jar, source, contact)
    return ball, jar, bb, bw, friction
