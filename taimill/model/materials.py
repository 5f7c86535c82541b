"""Materials, friction pairs and the ball charge: the built-in table
(taimill/data/materials.toml), pair files (a pair and its contact set in one file) and
the frozen dataclasses they load into, in SI units (kg, Pa, m, m/s)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from taimill.errors import ConfigError
from taimill.model import files, rules
from taimill.model.contact.registry import DEFAULT_ROLLING, DEFAULT_TANGENTIAL, ROLLING, TANGENTIAL
from taimill.model.ranges import RANGES
from taimill.model.tables import Table, is_estimate, read_toml

MATERIALS_FILE = files.PACKAGE / "data" / "materials.toml"
# The keys of each kind of table (unknown keys are errors, reported with the nearest known one)
FRICTION_KEYS = ("mu_s", "mu_d", "v_s_mm_s", "v_d_mm_s", "mu_r", "tangential", "rolling")
MATERIAL_NUMBERS = ("density_kg_m3", "youngs_modulus_gpa", "poisson", "restitution", "restitution_speed_mm_s",
                    "friction", "hardness_hv")
# Thermal numbers (optional: the heat model, taimill.outcome.thermal, needs them)
THERMAL_NUMBERS = ("cp_J_per_kgK", "conductivity_W_per_mK")
MATERIAL_KEYS = (*MATERIAL_NUMBERS, *THERMAL_NUMBERS, "source")


@dataclass(frozen=True)
class Material:
    name: str
    density: float  #: kg/m³
    youngs_modulus: float  #: Pa
    poisson: float  #: -


@dataclass(frozen=True)
class MaterialData:
    """A material with what contact sets are derived from and where each number comes
    from (taimill/data/materials.toml). `Material` alone is what runs carry."""

    material: Material
    restitution: float  #: e of a ball on a plate of this material, at `restitution_speed`
    restitution_speed: float  #: m/s
    friction: float  #: dry sliding friction coefficient, self-mated (listings only)
    sources: dict  #: {file key: source text}; texts starting "estimate" mark estimates
    hardness_hv: float = math.nan  #: Vickers hardness (HV); nan: not known (taimill wear refuses it)

    @property
    def name(self) -> str:
        return self.material.name

    def estimates(self, keys=MATERIAL_NUMBERS) -> list[str]:
        """The file keys among `keys` whose numbers are estimates."""
        return [k for k in keys if is_estimate(self.sources.get(k, ""))]

    def estimate_notes(self, keys, role: str) -> list[str]:
        """One warning line per estimated number among `keys` (role: how the run uses
        the material, e.g. "ball material")."""
        return [f"{role} {self.name}: {k} is an estimate, not a measured value ({self.sources[k]})"
                for k in self.estimates(keys)]


@dataclass(frozen=True)
class Friction:
    """Friction and rolling resistance of a contact kind: the coefficients and the
    tangential and rolling sub-models that use them (taimill.model.contact; by default
    the regularised Coulomb friction of thesis eq 3.7 and a constant rolling torque)."""

    name: str
    mu_s: float  #: static coefficient
    mu_d: float  #: dynamic coefficient (the Coulomb cap of the `history` model)
    v_s: float  #: m/s, μ reaches μ_s
    v_d: float  #: m/s, μ has eased to μ_d
    mu_r: float = 0.0  #: rolling-resistance coefficient; 0: off (the thesis model)
    tangential: str = DEFAULT_TANGENTIAL  #: tangential sub-model (registry.TANGENTIAL)
    rolling: str = DEFAULT_ROLLING  #: rolling sub-model (registry.ROLLING)


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


def _materials_db():
    return read_toml(MATERIALS_FILE, "materials")


def material_names() -> list[str]:
    return list(_materials_db()["material"])


def load_material(name: str, source="material", key="material") -> Material:
    return material_data(name, source, key).material


def material_data(name: str, source="material", key="material") -> MaterialData:
    """A built-in material, every number checked and with its source."""
    db = _materials_db()["material"]
    if name not in db:
        raise ConfigError(source, key, name, f"must be one of {', '.join(db)}")
    t = Table(db[name], MATERIALS_FILE, f"material.{name}.", known=MATERIAL_KEYS)
    m = Material(
        name,
        t.get("density_kg_m3", lo=0, lo_open=True, hi=30000),
        t.get("youngs_modulus_gpa", lo=0, lo_open=True, hi=2000) * 1e9,
        t.get("poisson", lo=-1, lo_open=True, hi=0.5),
    )
    data = MaterialData(
        m,
        t.get("restitution", lo=0, lo_open=True, hi=0.999),  # < 1: damping is calibrated to it
        t.get("restitution_speed_mm_s", lo=0, lo_open=True, hi=1e5) * 1e-3,
        t.get("friction", **RANGES["mu_s"].bounds),
        {k: v for k, v in t.sources(MATERIAL_NUMBERS + THERMAL_NUMBERS).items() if k in MATERIAL_NUMBERS},
        t.get("hardness_hv", math.nan, lo=0, lo_open=True, hi=1e4),
    )
    for k in THERMAL_NUMBERS:
        t.get(k, None, lo=0, lo_open=True, hi=1e4)
    t.done()
    return data


@dataclass(frozen=True)
class Thermal:
    """A material's specific heat capacity and thermal conductivity near room
    temperature, each with its source (a text starting "estimate" marks an estimate)."""

    name: str
    cp: float  #: J/(kg K)
    conductivity: float  #: W/(m K)
    sources: dict

    def estimate_notes(self, role: str) -> list[str]:
        return [f"{role} {self.name}: {k} is an estimate, not a measured value ({v})"
                for k, v in self.sources.items() if is_estimate(v)]


def thermal_data(name: str, source="material", key="material") -> Thermal:
    """The thermal numbers of a built-in material (a one-line error where it has none)."""
    material_data(name, source, key)  # every number and source checked
    t = _materials_db()["material"][name]
    for k in THERMAL_NUMBERS:
        if k not in t:
            raise ConfigError(MATERIALS_FILE, f"material.{name}.{k}", None,
                              "missing: the heat model needs it (give the number with its source)")
    return Thermal(name, float(t["cp_J_per_kgK"]), float(t["conductivity_W_per_mK"]),
                   {k: t["source"][k].strip() for k in THERMAL_NUMBERS})


def load_friction(name: str, source, key="pair", base: Path | None = None) -> tuple[Friction, str]:
    """A built-in pair, or a pair file (NAME ending in .toml, relative to `base`):
    (friction, contact-set id for `contact_laws`; None: a pair without a measured set,
    whose normal laws are always derived from the materials)."""
    files.check_path_text(name, source, key, "a pair name or pair file")
    if name.endswith(".toml"):
        return _pair_file(name, source, key, base)
    db = _materials_db()
    if name not in db["pair"]:
        folder = Path(base or ".") / name
        if os.path.isdir(folder):  # a store given as the pair: named as such (os.path: never raises)
            files.name_kind("pair", files.kind_of_path(folder), name, source, key)
        raise ConfigError(source, key, name, f"must be one of {', '.join(db['pair'])}, or a pair file NAME.toml")
    t = Table(db["pair"][name], MATERIALS_FILE, f"pair.{name}.", known=("contact", "source", *FRICTION_KEYS))
    contact = t.get("contact", None, kind=str)
    friction = read_friction(t, name)
    t.sources(FRICTION_KEYS, required=False)
    t.done()
    return friction, contact


def pair_names() -> list[str]:
    return list(_materials_db()["pair"])


def pairs_sharing(pair: str) -> list[str]:
    """The pairs a mill running with `pair` (a built-in name or a pair file's path) may
    switch to: `pair` itself, the built-in pairs of its contact set and those without a
    measured set, which change friction only (rules.same_contact_set)."""
    _, contact = load_friction(pair, "pair", base=None)
    names = [name for name, p in _materials_db()["pair"].items() if p.get("contact") in (contact, None)]
    return names if pair in names else [pair, *names]


def _pair_sources(name: str) -> tuple[dict, dict]:
    """(table, {key: source text}) of a built-in pair; ({}, {}) for a pair file."""
    table = {} if name.endswith(".toml") else _materials_db()["pair"].get(name, {})
    sources = table.get("source", {}) if isinstance(table, dict) else {}
    return table, sources


def pair_source_texts(name: str) -> dict:
    """{key: where the number comes from} of a built-in pair ({} for a pair file)."""
    return dict(_pair_sources(name)[1])


def pair_estimate_keys(name: str) -> list[str]:
    """The keys of a built-in pair whose numbers are estimates (assumptions)."""
    table, sources = _pair_sources(name)
    return [k for k, text in sources.items() if is_estimate(text) and k in table]


def pair_friction_measured(name: str) -> bool:
    """Whether a pair's Coulomb friction (μ_s and μ_d) is a measurement: a built-in pair
    neither of whose coefficients is marked an estimate (the thesis' pairs come from its
    Table 3.3, the file's header says; an estimate's source text says "estimate"). A pair
    file names no sources, so its friction is not known to be measured."""
    if name.endswith(".toml") or name not in _materials_db()["pair"]:
        return False
    return not {"mu_s", "mu_d"} & set(pair_estimate_keys(name))


def pair_estimates(name: str) -> list[str]:
    """Warning lines for a built-in pair's numbers that are estimates (assumptions)."""
    table, sources = _pair_sources(name)
    return [f"pair {name}: {k} = {table[k]:g} is an estimate (an assumption, not a measurement): {sources[k]}"
            for k in pair_estimate_keys(name)]


def _pair_file(name: str, source, key, base: Path | None) -> tuple[Friction, str]:
    """A pair file holds one [pair.NAME] table and the [contact.*] table it uses (same
    keys and units as materials.toml; materials are the built-in ones). Its contact
    set's id is "FILE#CONTACT"; a contact name the file lacks is a built-in one."""
    path = files.resolve(name, "pair", base is None, base, source=source, key=key)
    if files.missing(path):  # a broken link or a name the OS refuses: read_toml says why
        raise ConfigError(source, key, name, f"no pair file {path}; built-in pairs: {', '.join(_materials_db()['pair'])}")
    data = read_toml(path, key, source)
    files.check_kind(data, "pair", name, source, key)
    top = Table(data, path)
    extra = sorted(set(data) - {"pair", "contact"})
    if extra:
        raise top.unknown(extra[0], ("pair", "contact"))
    pairs = data.get("pair")
    if not isinstance(pairs, dict) or len(pairs) != 1:
        raise ConfigError(path, "pair", list(pairs) if isinstance(pairs, dict) else pairs, "a pair file needs exactly one [pair.NAME] table")
    (pair_name, table), = pairs.items()
    t = Table(table, path, f"pair.{pair_name}.", known=("contact", *FRICTION_KEYS))
    contact = t.get("contact", kind=str)
    friction = read_friction(t, pair_name)
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
        return read_toml(Path(file), "pair")["contact"][name], Path(file), name
    db = _materials_db()["contact"]
    if contact not in db:
        raise ConfigError(MATERIALS_FILE, "contact", contact, f"must be one of {', '.join(db)}")
    return db[contact], MATERIALS_FILE, contact


def read_friction(t: "Table", name: str, base: Friction | None = None) -> Friction:
    """μ_s, μ_d, v_s, v_d from table t, defaulting to `base` (preset overrides)."""
    required = (...,) * 4  # the sentinel `get` takes for "no default"
    d_mu_s, d_mu_d, d_vs, d_vd = required if base is None else (base.mu_s, base.mu_d, base.v_s * 1e3, base.v_d * 1e3)
    mu_s = t.get("mu_s", d_mu_s, **RANGES["mu_s"].bounds)
    mu_d = t.get("mu_d", d_mu_d, **RANGES["mu_d"].bounds)
    rules.friction_order(t.where("mu_d"), t.key("mu_d"), mu_s, mu_d)
    v_s = t.get("v_s_mm_s", d_vs, lo=0, lo_open=True, hi=1e4) * 1e-3
    v_d = t.get("v_d_mm_s", d_vd, lo=0, lo_open=True, hi=1e5) * 1e-3
    if v_d <= v_s:
        raise ConfigError(t.where("v_d_mm_s"), t.key("v_d_mm_s"), v_d * 1e3, f"must exceed v_s_mm_s = {v_s * 1e3:g}")
    mu_r = t.get("mu_r", 0.0 if base is None else base.mu_r, **RANGES["mu_r"].bounds)
    tangential = t.get("tangential", DEFAULT_TANGENTIAL if base is None else base.tangential, kind=str,
                       allowed=tuple(TANGENTIAL))
    rolling = t.get("rolling", DEFAULT_ROLLING if base is None else base.rolling, kind=str, allowed=tuple(ROLLING))
    return Friction(name, mu_s, mu_d, v_s, v_d, mu_r, tangential, rolling)
