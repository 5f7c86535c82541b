"""Fixed parameters of a run: frozen dataclasses in SI units, loaded from TOML and
validated before any kernel runs (docs/model.md, faults). Files use mm and rpm where the thesis
does, with the unit in the key name; everything here is SI (m, kg, s, rad/s).
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import io
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from taimill.model import files, geometry
from taimill.model.overlap import first_overlap
from taimill.model.drive import Drive
from taimill.errors import ConfigError
from taimill.model.ranges import RANGES
from taimill.model import laws as laws_np
from taimill.model.contact.model import NormalModel
from taimill.model.contact.registry import NAMES as LAW_NAMES, law_by_name
from taimill.model.contact.springs import hertz_stiffness, with_exponent

PACKAGE = Path(__file__).resolve().parent.parent
ROOT = PACKAGE.parent
MATERIALS_FILE = PACKAGE / "data" / "materials.toml"
JARS_DIR = ROOT / "jars"
GRAVITY = 9.81
MAX_STEPS = 1e10  #: time steps of one run; more would take years of wall time

# The keys of each kind of table (unknown keys are errors, reported with the nearest known one)
FRICTION_KEYS = ("mu_s", "mu_d", "v_s_mm_s", "v_d_mm_s", "mu_r")
# Contact kinds a preset may give its own friction pair and tuning (a coated jar: ball-wall only).
KINDS = ("ball_ball", "ball_wall")
PRESET_KEYS = ("jar", "pair", "plate_rpm", "ratio", "jar_rpm", "duration", "analysis_start", "dt", "seed", "law",
               "initial_positions", "ramp_time", "plate_radius_mm", "gravity", "balls", "outputs", "friction",
               *(f"pair_{k}" for k in KINDS), *(f"friction_{k}" for k in KINDS))
BALLS_KEYS = ("count", "material", "radius_mm")
OUTPUTS_KEYS = ("trajectory_rate",)
JAR_KEYS = ("height_mm", "wall_material", "description", "fillet_mm", "profile")
MATERIAL_KEYS = ("density_kg_m3", "youngs_modulus_gpa", "poisson")
CONTACT_KEYS = ("ball", "wall", "law", "ball_radius_mm", "ball_ball", "ball_wall")
NORMAL_LAW_KEYS = ("c_max_Ns_per_mm", "d_mm", "e", "u_ref_mm_s")


@dataclass(frozen=True)
class Material:
    name: str
    density: float  #: kg/m³
    youngs_modulus: float  #: Pa
    poisson: float  #: -


@dataclass(frozen=True)
class Friction:
    """Regularised Coulomb friction of thesis eq 3.7, and rolling resistance (a
    constant torque μ_r R_eff F_n against the relative rolling, taimill.model.laws)."""

    name: str
    mu_s: float  #: static coefficient
    mu_d: float  #: dynamic coefficient
    v_s: float  #: m/s, μ reaches μ_s
    v_d: float  #: m/s, μ has eased to μ_d
    mu_r: float = 0.0  #: rolling-resistance coefficient; 0: off (the thesis model)


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

    @property
    def model(self) -> NormalModel:
        """The law's composition of a spring and a damping (taimill.model.contact); a
        power spring if n differs from the law's own exponent (sensitivity studies)."""
        law = law_by_name(self.law)
        spring = with_exponent(law.spring, self.n)
        return law if spring is law.spring else dataclasses.replace(law, name=f"{law.name}, n = {self.n:g}", spring=spring)


@dataclass(frozen=True)
class Jar:
    """A 2-D profile extruded between floor (z = 0) and lid (z = height)."""

    name: str
    source: str
    height: float  #: m
    wall_material: str
    primitives: tuple  #: ((type, {param: SI value}), ...); interior = intersection
    fillet: float = 0.0  #: m, radius rounding every corner of the profile
    description: str = ""

    @functools.cached_property
    def profile(self) -> geometry.Profile:
        key = tuple((kind, tuple(sorted(values.items()))) for kind, values in self.primitives)
        return _profile(key, self.fillet)

    @property
    def radius(self) -> float:
        """Bounding radius of the profile (m)."""
        return self.profile.bounding_radius

    @property
    def area(self) -> float:
        """Cross-section area (m²)."""
        return self.profile.area

    @property
    def volume(self) -> float:
        return self.area * self.height


@dataclass(frozen=True)
class Balls:
    count: int
    material: Material
    radius: float  #: m

    @property
    def mass(self) -> float:
        return self.material.density * 4.0 / 3.0 * math.pi * self.radius**3

    @property
    def inertia(self) -> float:
        """Moment of inertia of a solid sphere, 2/5 m r², kg·m²."""
        return 0.4 * self.mass * self.radius**2


INLINE_POSITIONS = 1000  # balls; a resolved config lists at most this many start positions


@dataclass(frozen=True)
class Preset:
    source: str
    jar: Jar
    balls: Balls
    pair: str
    friction: Friction  #: of ball-ball contacts
    ball_ball: NormalLaw
    ball_wall: NormalLaw
    drive: Drive  #: Ω, the jar's spin and the start-up ramp
    plate_radius: float  #: m, R_p
    duration: float  #: s
    analysis_start: float  #: s
    dt: float  #: s (resolved: auto or given)
    dt_auto: bool
    seed: int
    trajectory_rate: float  #: Hz
    gravity: float = GRAVITY  #: m/s²
    initial_positions: np.ndarray | None = field(default=None, compare=False, repr=False)
    wall_friction: Friction | None = None  #: of ball-wall contacts; None: `friction`

    @property
    def frictions(self) -> tuple[Friction, Friction]:
        """(ball-ball, ball-wall) friction, in contact-type order."""
        return self.friction, self.wall_friction or self.friction

    def as_dict(self) -> dict:
        """Resolved configuration as plain JSON-able data (for stores and summaries);
        the drive's speeds are top-level keys in every form (see Drive.as_dict)."""
        d = dataclasses.asdict(dataclasses.replace(self, initial_positions=None))
        del d["drive"]
        x = self.initial_positions
        if x is not None:  # inline for a few balls; the trajectory's first frame holds them all anyway
            d["initial_positions"] = x.tolist() if len(x) <= INLINE_POSITIONS else f"{len(x)} ball centres: the trajectory's first frame"
        return d | self.drive.as_dict()


@functools.lru_cache(maxsize=64)
def _profile(primitives: tuple, fillet: float) -> geometry.Profile:
    """The profile of hashable primitives ((kind, ((param, value), ...)), ...): built
    once per process (0.1 s each; a sweep loads its preset once per point)."""
    return geometry.build_profile(tuple((kind, dict(values)) for kind, values in primitives), fillet)


@functools.lru_cache(maxsize=256)
def _auto_dt(ball_ball: NormalLaw, ball_wall: NormalLaw, v_max: float) -> float:
    """laws.auto_dt, once per process for a pair of laws and a speed (it simulates impacts)."""
    return laws_np.auto_dt((ball_ball, ball_wall), v_max)


# ------------------------------------------------------------------ checking
class _Table:
    """A TOML table being read: remembers the file and key path for error messages,
    and reports keys it does not know (typos must not pass silently, nor be reported
    as a missing key: `known` is checked first, with the nearest known key suggested)."""

    def __init__(self, data: dict, source: str, prefix: str = "", overridden=frozenset(), known=None):
        if not isinstance(data, dict):
            raise ConfigError(source, prefix.rstrip(".") or "file", data, "must be a table")
        self.data, self.source, self.prefix, self.used = data, source, prefix, set()
        self.overridden = overridden
        if known is not None:
            self.expect(known)

    def expect(self, known):
        """Refuse any key not in `known`."""
        extra = [k for k in self.data if k not in known]
        if extra:
            raise self.unknown(extra[0], known)

    def unknown(self, k, known) -> ConfigError:
        close = difflib.get_close_matches(str(k), sorted(known), n=1, cutoff=0.6)
        hint = f" (did you mean '{close[0]}'?)" if close else f"; allowed: {', '.join(sorted(known))}"
        return ConfigError(self.where(k), self.key(k), self.data[k], f"unknown key '{k}'{hint}")

    def key(self, k):
        return f"{self.prefix}{k}"

    def where(self, k):
        """The file, or the command line if the value was given there."""
        return "command line" if self.key(k) in self.overridden else self.source

    def has(self, k):
        return k in self.data

    def get(self, k, default=..., *, kind=float, lo=None, hi=None, lo_open=False, allowed=None):
        self.used.add(k)
        if k not in self.data:
            if default is ...:
                raise ConfigError(self.source, self.key(k), None, "missing (required key)")
            return default
        v = self.data[k]
        src = self.where(k)
        if allowed is not None:
            if v not in allowed:
                raise ConfigError(src, self.key(k), v, f"must be one of {', '.join(map(str, allowed))}")
            return v
        if kind is str:
            if not isinstance(v, str):
                raise ConfigError(src, self.key(k), v, "must be a string")
            return v
        if kind is int and (isinstance(v, bool) or not isinstance(v, int)):
            raise ConfigError(src, self.key(k), v, "must be an integer")
        if kind is float and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ConfigError(src, self.key(k), v, "must be a number")
        if kind is float and isinstance(v, int) and abs(v) > 1e300:
            raise ConfigError(src, self.key(k), v, "must be finite")
        if isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(src, self.key(k), v, "must be finite")
        bad_lo = lo is not None and (v <= lo if lo_open else v < lo)
        if bad_lo or (hi is not None and v > hi):
            lo_s = "-inf" if lo is None else f"{lo:g}"
            hi_s = "inf" if hi is None else f"{hi:g}"
            raise ConfigError(src, self.key(k), v, f"allowed range {'(' if lo_open else '['}{lo_s}, {hi_s}]")
        return kind(v)

    def table(self, k, required=True, known=None):
        self.used.add(k)
        v = self.data.get(k)
        if v is None and not required:
            return None
        if v is None:
            raise ConfigError(self.source, self.key(k), v, "missing (required table)")
        if not isinstance(v, dict):
            raise ConfigError(self.where(k), self.key(k), v, "must be a table")
        return _Table(v, self.source, f"{self.prefix}{k}.", self.overridden, known)

    def done(self):
        extra = sorted(set(self.data) - self.used, key=str)
        if extra:
            raise self.unknown(extra[0], self.used)


def _read_toml(path: Path, what: str, source=None) -> dict:
    """A TOML file; `source` (default: the file) is who named it, for read errors."""
    return files.read_toml(path, path if source is None else source, what)


# ------------------------------------------------------------------ materials
def _materials_db():
    return _read_toml(MATERIALS_FILE, "materials")


def load_material(name: str, source="material") -> Material:
    db = _materials_db()["material"]
    if name not in db:
        raise ConfigError(source, "material", name, f"must be one of {', '.join(db)}")
    t = _Table(db[name], MATERIALS_FILE, f"material.{name}.", known=MATERIAL_KEYS)
    m = Material(
        name,
        t.get("density_kg_m3", lo=0, lo_open=True, hi=30000),
        t.get("youngs_modulus_gpa", lo=0, lo_open=True, hi=2000) * 1e9,
        t.get("poisson", lo=-1, lo_open=True, hi=0.5),
    )
    t.done()
    return m


def load_friction(name: str, source, key="pair", base: Path | None = None) -> tuple[Friction, str]:
    """A built-in pair, or a pair file (NAME ending in .toml, relative to `base`):
    (friction, contact-set id for `_contact_laws`)."""
    files.check_path_text(name, source, key, "a pair name or pair file")
    if name.endswith(".toml"):
        return _pair_file(name, source, key, base)
    db = _materials_db()
    if name not in db["pair"]:
        raise ConfigError(source, key, name, f"must be one of {', '.join(db['pair'])}, or a pair file NAME.toml")
    t = _Table(db["pair"][name], MATERIALS_FILE, f"pair.{name}.", known=("contact", *FRICTION_KEYS))
    contact = t.get("contact", kind=str)
    friction = _friction(t, name)
    t.done()
    return friction, contact


def _pair_file(name: str, source, key, base: Path | None) -> tuple[Friction, str]:
    """A pair file holds one [pair.NAME] table and the [contact.*] table it uses (same
    keys and units as materials.toml; materials are the built-in ones). Its contact
    set's id is "FILE#CONTACT"; a contact name the file lacks is a built-in one."""
    path = Path(name) if Path(name).is_absolute() or base is None else base / name
    if files.missing(path):  # a broken link or a name the OS refuses: read_toml says why
        raise ConfigError(source, key, name, f"no pair file {path}; built-in pairs: {', '.join(_materials_db()['pair'])}")
    data = _read_toml(path, key, source)
    top = _Table(data, path)
    extra = sorted(set(data) - {"pair", "contact"})
    if extra:
        raise top.unknown(extra[0], ("pair", "contact"))
    pairs = data.get("pair")
    if not isinstance(pairs, dict) or len(pairs) != 1:
        raise ConfigError(path, "pair", list(pairs) if isinstance(pairs, dict) else pairs, "a pair file needs exactly one [pair.NAME] table")
    (pair_name, table), = pairs.items()
    t = _Table(table, path, f"pair.{pair_name}.", known=("contact", *FRICTION_KEYS))
    contact = t.get("contact", kind=str)
    friction = _friction(t, pair_name)
    t.done()
    own = data.get("contact", {})
    if not isinstance(own, dict) or not all(isinstance(v, dict) for v in own.values()):
        raise ConfigError(path, "contact", own, "[contact.NAME] tables of a normal law (see taimill/data/materials.toml)")
    if contact not in own and contact not in _materials_db()["contact"]:
        raise ConfigError(path, f"pair.{pair_name}.contact", contact, f"no [contact.{contact}] table in the file or built in")
    return friction, f"{path.resolve()}#{contact}" if contact in own else contact


def contact_table(contact: str) -> tuple[dict, Path, str]:
    """(table, file, name) of a contact-set id from `load_friction`."""
    if "#" in contact:
        file, name = contact.rsplit("#", 1)
        return _read_toml(Path(file), "pair")["contact"][name], Path(file), name
    db = _materials_db()["contact"]
    if contact not in db:
        raise ConfigError(MATERIALS_FILE, "contact", contact, f"must be one of {', '.join(db)}")
    return db[contact], MATERIALS_FILE, contact


def _friction(t: "_Table", name: str, base: Friction | None = None) -> Friction:
    """μ_s, μ_d, v_s, v_d from table t, defaulting to `base` (preset overrides)."""
    required = (...,) * 4  # the sentinel `get` takes for "no default"
    d_mu_s, d_mu_d, d_vs, d_vd = required if base is None else (base.mu_s, base.mu_d, base.v_s * 1e3, base.v_d * 1e3)
    mu_s = t.get("mu_s", d_mu_s, **RANGES["mu_s"].bounds)
    mu_d = t.get("mu_d", d_mu_d, **RANGES["mu_d"].bounds)
    if mu_d > mu_s:
        raise ConfigError(t.where("mu_d"), t.key("mu_d"), mu_d, f"dynamic friction must not exceed static mu_s = {mu_s:g}; allowed range [0, {mu_s:g}]")
    v_s = t.get("v_s_mm_s", d_vs, lo=0, lo_open=True, hi=1e4) * 1e-3
    v_d = t.get("v_d_mm_s", d_vd, lo=0, lo_open=True, hi=1e5) * 1e-3
    if v_d <= v_s:
        raise ConfigError(t.where("v_d_mm_s"), t.key("v_d_mm_s"), v_d * 1e3, f"must exceed v_s_mm_s = {v_s * 1e3:g}")
    mu_r = t.get("mu_r", 0.0 if base is None else base.mu_r, **RANGES["mu_r"].bounds)
    return Friction(name, mu_s, mu_d, v_s, v_d, mu_r)


# ------------------------------------------------------------------ jars
# primitive → its keys (unit in the name) and allowed ranges; see taimill.model.geometry
PRIMITIVES = {
    "circle": {"radius_mm": (0, 1000)},
    "cut": {"distance_mm": (0, 1000), "angle_deg": (-360, 360)},
    "lifter": {"radius_mm": (0, 1000), "distance_mm": (0, 1000), "angle_deg": (-360, 360)},
}


def resolve_jar_path(name: str, base: Path | None = None) -> Path:
    p = Path(name)
    if p.suffix == ".toml":
        return p if p.is_absolute() or base is None else (base / p)
    return JARS_DIR / f"{name}.toml"


def jar_names() -> list[str]:
    return sorted(p.stem for p in JARS_DIR.glob("*.toml"))


def load_jar(name: str, source="preset", base: Path | None = None) -> Jar:
    files.check_path_text(name, source, "jar", "a jar name or jar file")
    path = resolve_jar_path(name, base)
    if files.missing(path):
        raise ConfigError(source, "jar", name, f"no jar file {path}; known jars: {', '.join(jar_names())}")
    t = _Table(_read_toml(path, "jar", source), path, known=JAR_KEYS)
    height = t.get("height_mm", lo=0, lo_open=True, hi=1000) * 1e-3
    wall = t.get("wall_material", kind=str)
    desc = t.get("description", "", kind=str)
    fillet = t.get("fillet_mm", 0.0, lo=0, hi=1000) * 1e-3
    t.used.add("profile")
    raw = t.data.get("profile")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(path, "profile", raw, "must be a non-empty array of [[profile]] tables")
    prims = []
    for i, item in enumerate(raw):
        p = _Table(item, path, f"profile[{i}].", known={"type", *(k for keys in PRIMITIVES.values() for k in keys)})
        kind = p.get("type", kind=str, allowed=tuple(PRIMITIVES))
        p.expect(("type", *PRIMITIVES[kind]))
        values = {}
        for key, (lo, hi) in PRIMITIVES[kind].items():
            v = p.get(key, lo=lo, lo_open=key.endswith("_mm"), hi=hi)
            values[key.removesuffix("_mm").removesuffix("_deg") + ("_deg" if key.endswith("_deg") else "")] = (
                v * 1e-3 if key.endswith("_mm") else v)
        p.done()
        prims.append((kind, values))
    if sum(k == "circle" for k, _ in prims) != 1:
        raise ConfigError(path, "profile", [k for k, _ in prims], "needs exactly one circle primitive (the curved wall)")
    t.done()
    _check_primitives(path, prims)
    load_material(wall, path)
    jar = Jar(path.stem, str(path), height, wall, tuple(prims), fillet, desc)
    try:
        jar.profile
    except (ValueError, ArithmeticError, IndexError) as err:
        raise ConfigError(path, "profile", [k for k, _ in prims], f"cannot build the cross-section: {err}") from None
    if len(jar.profile.pieces) > 1 and fillet <= 0:
        raise ConfigError(path, "fillet_mm", fillet * 1e3, "a profile with corners needs a fillet radius > 0")
    return jar


def _check_primitives(path, prims):
    """Every cut and lifter must shape the wall: a flat wall inside the circle, a lifter
    reaching into it without covering the axis (the profile is star-shaped about it)."""
    R = next(v["radius"] for k, v in prims if k == "circle")
    for i, (kind, v) in enumerate(prims):
        if kind == "cut" and v["distance"] >= R:
            raise ConfigError(path, f"profile[{i}].distance_mm", v["distance"] * 1e3,
                              f"allowed range (0, {R * 1e3:g}): a cut at or beyond the circle's radius "
                              f"({R * 1e3:g} mm) lies outside the jar")
        if kind == "lifter" and v["distance"] - v["radius"] >= R:
            raise ConfigError(path, f"profile[{i}].distance_mm", v["distance"] * 1e3,
                              f"allowed range (0, {(R + v['radius']) * 1e3:g}): the lifter's disc "
                              f"(radius {v['radius'] * 1e3:g} mm) lies outside the circle ({R * 1e3:g} mm)")
        if kind == "lifter" and v["distance"] <= v["radius"]:
            raise ConfigError(path, f"profile[{i}].distance_mm", v["distance"] * 1e3,
                              f"must exceed the lifter's radius_mm = {v['radius'] * 1e3:g}: its disc would cover the jar's axis")


# ------------------------------------------------------------------ contact laws
def _normal_law(t: _Table, law: str, k, m_eff, e_eff, r_eff) -> tuple:
    """One contact type, read: (its ContactLaw, the arguments of ContactLaw.damping, k,
    m_eff, e, u_ref, d); k is derived as the law's registry entry says; e_eff (Pa) and
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


def _contact_laws(contact: str, law: str | None, balls: Balls, jar: Jar, source, override=None):
    """(ball-ball, ball-wall) laws of a contact set. `override` replaces entries of its
    tables, same keys and units, e.g. {"ball_wall": {"d_mm": 0.1}} (calibration fits);
    range errors then name the command line."""
    table, file, name = contact_table(contact)
    _Table(table, file, f"contact.{name}.", known=CONTACT_KEYS)
    override = override or {}
    for k in override:
        if not isinstance(table.get(k, {}), dict):
            raise ConfigError(file, f"contact.{name}.{k}", table[k], "must be a table")
    table = {**table, **{k: {**table.get(k, {}), **v} for k, v in override.items()}}
    changed = frozenset(f"contact.{name}.{k}.{leaf}" for k, v in override.items() for leaf in v)
    t = _Table(table, file, f"contact.{name}.", changed, known=CONTACT_KEYS)
    ball_mat = t.get("ball", kind=str)
    wall_mat = t.get("wall", kind=str)
    t.get("ball_radius_mm", lo=0, lo_open=True, hi=1000)
    law = law or t.get("law", kind=str, allowed=LAW_NAMES)
    t.used.add("law")
    if ball_mat != balls.material.name:
        raise ConfigError(source, "balls.material", balls.material.name, f"the pair's contact set '{contact}' is for {ball_mat} balls")
    if wall_mat != jar.wall_material:
        raise ConfigError(source, "jar", jar.name, f"wall material {jar.wall_material}; the pair's contact set '{contact}' is for {wall_mat} walls")
    bm, wm = balls.material, load_material(wall_mat, file)
    r, m = balls.radius, balls.mass
    k_bb = hertz_stiffness(bm.youngs_modulus, bm.poisson, bm.youngs_modulus, bm.poisson, r, r)
    k_bw = hertz_stiffness(bm.youngs_modulus, bm.poisson, wm.youngs_modulus, wm.poisson, r)
    e_bb = 1.0 / (2.0 / bm.youngs_modulus)  # eq 2.17: 1/E_e = 1/E_i + 1/E_j
    e_bw = 1.0 / (1.0 / bm.youngs_modulus + 1.0 / wm.youngs_modulus)
    bb, bw = _normal_laws(law, _normal_law(t.table("ball_ball", known=NORMAL_LAW_KEYS), law, k_bb, m / 2.0, e_bb, r / 2.0),
                          _normal_law(t.table("ball_wall", known=NORMAL_LAW_KEYS), law, k_bw, m, e_bw, r))
    t.done()
    return bb, bw


def pair_contact(pair: str, radius: float | None = None, law: str | None = None, source="command line",
                 contact: dict | None = None):
    """Everything a single impact needs for a friction pair (a name or a pair file),
    without a preset: (Balls of one ball, Jar of the wall material, ball-ball law,
    ball-wall law, Friction). radius (m) defaults to the balls the contact set was
    fitted for; `contact` overrides entries of the contact set (see `_contact_laws`)."""
    friction, contact_id = load_friction(pair, source, base=Path.cwd())
    db, file, name = contact_table(contact_id)
    t = _Table(db, file, f"contact.{name}.", known=CONTACT_KEYS)  # checked in full by _contact_laws
    radius = radius or t.get("ball_radius_mm", lo=0, lo_open=True, hi=1000) * 1e-3
    ball = Balls(1, load_material(t.get("ball", kind=str), file), radius)
    jar = Jar("plate", "drop test", 10.0, t.get("wall", kind=str), (("circle", {"radius": 1.0}),))  # a 2 m wide plate
    if law is not None and law not in LAW_NAMES:
        raise ConfigError(source, "law", law, f"must be one of {', '.join(LAW_NAMES)}")
    bb, bw = _contact_laws(contact_id, law, ball, jar, source, contact)
    return ball, jar, bb, bw, friction


# ------------------------------------------------------------------ presets
def max_impact_speed(plate_omega, jar_spin, plate_radius, jar: Jar, gravity=GRAVITY) -> float:
    """Upper estimate of contact speeds (m/s), for the automatic time step: the jar's
    ground speed plus its wall speed plus a free fall across the jar."""
    return abs(plate_omega) * plate_radius + abs(jar_spin) * jar.radius + math.sqrt(2 * gravity * 2 * jar.radius) + 0.5


def load_preset(path, overrides: dict | None = None) -> Preset:
    """Read and validate a preset. `overrides` maps preset keys to values given on the
    command line (e.g. {"ratio": -3.0, "balls.count": 24}); they win over the file."""
    overrides = overrides or {}
    if overrides.get("ratio") is not None and overrides.get("jar_rpm") is not None:
        raise ConfigError("command line", "--jar-rpm", overrides["jar_rpm"],
                          f"give either --ratio ({overrides['ratio']!r}) or --jar-rpm, not both")
    files.check_path_text(str(path) if isinstance(path, Path) else path, "command line", "preset", "a preset file")
    path = Path(path)
    data = _read_toml(path, "preset", "command line")
    source = str(path)
    _Table(data, source, known=PRESET_KEYS)
    for key, value in overrides.items():
        if value is None:
            continue
        table, _, leaf = key.rpartition(".")
        target = data.setdefault(table, {}) if table else data
        if not isinstance(target, dict):
            raise ConfigError(source, table, target, "must be a table")
        target[leaf] = value
        if key in ("ratio", "jar_rpm"):
            data.pop("jar_rpm" if key == "ratio" else "ratio", None)
    overridden = frozenset(k for k, v in overrides.items() if v is not None)
    t = _Table(data, source, "", overridden, known=PRESET_KEYS)

    jar = load_jar(t.get("jar", kind=str), t.where("jar"), path.parent)
    bt = t.table("balls", known=BALLS_KEYS)
    material = load_material(bt.get("material", kind=str), source)
    balls = Balls(
        bt.get("count", kind=int, **RANGES["balls.count"].bounds),
        material,
        bt.get("radius_mm", lo=0, lo_open=True, hi=0.5e3 * min(jar.radius, jar.height)) * 1e-3,
    )
    bt.done()
    _check_fill(balls, jar, bt.where("count"), bt.where("radius_mm"), placed=t.has("initial_positions"))

    pair = t.get("pair", kind=str)
    pair_base = Path.cwd() if t.where("pair") == "command line" else path.parent
    friction, contact = load_friction(pair, t.where("pair"), base=pair_base)
    if pair.endswith(".toml"):  # a pair file: its resolved path, valid from any directory
        pair = str((pair_base / pair).resolve())
    ft = t.table("friction", required=False, known=FRICTION_KEYS)
    if ft is not None:  # the pair's friction, tuned by the user
        friction = _friction(ft, f"{pair} (tuned)", friction)
        ft.done()
    frictions = [_kind_friction(t, kind, friction, contact, path, pair_base) for kind in KINDS]
    friction, wall_friction = frictions[0], (frictions[1] if frictions[1] != frictions[0] else None)
    law = t.get("law", None, allowed=LAW_NAMES)
    ball_ball, ball_wall = _contact_laws(contact, law, balls, jar, source)

    plate_rpm = t.get("plate_rpm", **RANGES["plate_rpm"].bounds)
    if plate_rpm == 0:
        r = RANGES["plate_rpm"]
        raise ConfigError(t.where("plate_rpm"), "plate_rpm", plate_rpm, f"allowed range [{r.lo:g}, 0) or (0, {r.hi:g}] {r.unit}: "
                          "the speed ratio K = ω/Ω + 1 is undefined for a plate at rest")
    if t.has("ratio") and t.has("jar_rpm"):
        raise ConfigError(t.where("jar_rpm"), "jar_rpm", data["jar_rpm"], "give either ratio or jar_rpm, not both")
    jar_key = "jar_rpm" if t.has("jar_rpm") else "ratio"
    jar_speed = t.get(jar_key, **RANGES[jar_key].bounds)
    plate_radius = t.get("plate_radius_mm", 125.0, lo=0, lo_open=True, hi=2000) * 1e-3

    duration = t.get("duration", lo=0, lo_open=True, hi=36000)
    if "duration" in overridden and "analysis_start" not in overridden and data.get("analysis_start", 0) >= duration:
        # a short run asked for on the command line keeps the thesis' proportion (4 of 24 s)
        data["analysis_start"] = duration / 6.0
    analysis_start = t.get("analysis_start", 0.0, lo=0, hi=duration)
    if analysis_start >= duration:
        raise ConfigError(source, "analysis_start", analysis_start, f"must be below duration = {duration:g} s")
    ramp_time = t.get("ramp_time", 1.0, **(RANGES["ramp_time"].bounds | {"hi": duration}))
    drive = Drive.from_rpm(plate_rpm, **{jar_key: jar_speed}, ramp_time=ramp_time)
    gravity = t.get("gravity", GRAVITY, lo=0, hi=1000)
    seed = t.get("seed", 0, kind=int, lo=0, hi=2**63 - 1)

    v_max = max_impact_speed(drive.plate_omega, drive.jar_spin, plate_radius, jar, gravity)
    dt_auto = min(_auto_dt(ball_ball, ball_wall, v_max),
                  laws_np.rolling_dt((friction, wall_friction or friction), balls.inertia, balls.radius, math.inf))
    dt_raw = t.data.get("dt", "auto")
    t.used.add("dt")
    if dt_raw == "auto":
        dt, is_auto = dt_auto, True
    else:
        dt_limit = dt_auto * laws_np.STEPS_PER_CONTACT / 10.0  # ≥ 10 steps per contact
        if isinstance(dt_raw, bool) or not isinstance(dt_raw, (int, float)) or not 0 < dt_raw <= dt_limit:
            raise ConfigError(t.where("dt"), "dt", dt_raw, f"'auto' or a time step in (0, {dt_limit:.3g}] s (10 steps per contact at {v_max:.1f} m/s)")
        dt, is_auto = float(dt_raw), False
        dt_min = min(dt_auto, duration / MAX_STEPS)
        if dt < dt_min:
            raise ConfigError(t.where("dt"), "dt", dt_raw, f"'auto' or a time step in [{dt_min:.3g}, {dt_limit:.3g}] s: "
                              f"{duration / dt:.3g} steps for duration = {duration:g} s, at most {MAX_STEPS:.0e} "
                              "(smaller than the automatic step only while it runs in reasonable time)")

    out = t.table("outputs", required=False, known=OUTPUTS_KEYS)
    rate = 100.0
    if out is not None:
        rate = out.get("trajectory_rate", 100.0, lo=0, lo_open=True, hi=min(1e5, 0.5 / dt))
        out.done()
    init = None
    if t.has("initial_positions"):
        init = load_positions(t.get("initial_positions", kind=str), path.parent, balls, jar, source)
    t.done()
    return Preset(
        source, jar, balls, pair, friction, ball_ball, ball_wall, drive, plate_radius,
        duration, analysis_start, dt, is_auto, seed, rate, gravity, init, wall_friction,
    )


def _kind_friction(t: _Table, kind: str, friction: Friction, contact: str, path: Path, pair_base: Path) -> Friction:
    """Friction of one contact kind: `pair_KIND` (a pair of the same contact set)
    instead of `pair`, then tuned by `[friction_KIND]`; else the preset's friction."""
    key = f"pair_{kind}"
    if t.has(key):
        name = t.get(key, kind=str)
        base = Path.cwd() if t.where(key) == "command line" else pair_base
        friction, own = load_friction(name, t.where(key), key, base)
        if own != contact:
            raise ConfigError(t.where(key), key, name, f"is for the '{own}' contact set; `pair` uses '{contact}' "
                              "(the normal laws come from `pair`; pick a pair of the same contact set)")
    ft = t.table(f"friction_{kind}", required=False, known=FRICTION_KEYS)
    if ft is not None:
        friction = _friction(ft, f"{friction.name} ({kind.replace('_', '-')}, tuned)", friction)
        ft.done()
    return friction


def _check_fill(balls: Balls, jar: Jar, source, radius_source, placed=False):
    """Random loose packing reaches ~0.55; refuse fills that cannot be placed at random
    (given positions are checked ball by ball instead: a settled bed is denser). A ball
    larger than the fillets would touch both walls of a corner while the side-wall
    SDF reports only the nearer: refuse it."""
    fill = balls.count * 4.0 / 3.0 * math.pi * balls.radius**3 / jar.volume
    if fill > 0.45 and not placed:
        raise ConfigError(source, "balls.count", balls.count, f"balls fill {fill:.0%} of the jar; at most 45% can be placed at random")
    if 2 * balls.radius >= jar.height or balls.radius >= jar.radius:
        raise ConfigError(radius_source, "balls.radius_mm", balls.radius * 1e3, "balls must fit in the jar")
    if len(jar.profile.pieces) > 1 and balls.radius > jar.fillet:
        raise ConfigError(radius_source, "balls.radius_mm", balls.radius * 1e3,
                          f"allowed range (0, {jar.fillet * 1e3:g}]: jar {jar.name}'s corners are rounded to {jar.fillet * 1e3:g} mm")


def load_positions(name: str, base: Path, balls: Balls, jar: Jar, source) -> np.ndarray:
    """Ball centres (N, 3), m, jar frame, from CSV (x,y,z per line) or NPZ (array 'positions')."""
    files.check_path_text(name, source, "initial_positions")
    p = Path(name) if Path(name).is_absolute() else base / name
    npz = p.suffix == ".npz"
    data = files.read_bytes(p, source, "initial_positions") if npz else files.read_text(p, source, "initial_positions", "CSV file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty file: loadtxt warns, the shape check below reports it
            if npz:
                x = np.load(io.BytesIO(data), allow_pickle=False)["positions"]
            else:
                x = np.loadtxt(io.StringIO(data), delimiter=",", ndmin=2)
            x = np.asarray(x, dtype=float)
    except (OSError, KeyError, ValueError, TypeError, EOFError) as err:
        raise ConfigError(source, "initial_positions", name, f"cannot read ({err})") from None
    if x.shape != (balls.count, 3):
        raise ConfigError(source, "initial_positions", name, f"shape {x.shape}; need ({balls.count}, 3) ball centres in m")
    if not np.isfinite(x).all():
        raise ConfigError(source, "initial_positions", name, "every coordinate must be a finite number (m)")
    r = balls.radius
    phi, _ = geometry.profile_sdf(jar.profile, x[:, :2])
    if (phi < r).any() or (x[:, 2] < r).any() or (x[:, 2] > jar.height - r).any():
        raise ConfigError(source, "initial_positions", name, "a ball is not fully inside the jar")
    pair = first_overlap(x, r)
    if pair is not None:
        i, j = pair
        raise ConfigError(source, "initial_positions", name, f"balls {i} and {j} overlap (rows {i + 1} and {j + 1})")
    return x
