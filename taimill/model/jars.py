"""Jars: a 2-D profile of primitives (circle, cuts, lifters) extruded between floor and
lid, read from jars/NAME.toml or a jar file and checked before its geometry is built."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

from taimill.errors import ConfigError
from taimill.model import files, geometry
from taimill.model.materials import load_material
from taimill.model.provenance import read_origins
from taimill.model.tables import Table, read_toml

JARS_DIR = files.ROOT / "jars"
JAR_KEYS = ("height_mm", "wall_material", "description", "fillet_mm", "profile", "sources", "estimates")
ORIGIN_KEYS = ("height_mm", "fillet_mm", "radius_mm")  #: numbers of a jar with [sources]/[estimates]; radius: the circle's


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


@functools.lru_cache(maxsize=64)
def _profile(primitives: tuple, fillet: float) -> geometry.Profile:
    """The profile of hashable primitives ((kind, ((param, value), ...)), ...): built
    once per process (0.1 s each; a sweep loads its preset once per point)."""
    return geometry.build_profile(tuple((kind, dict(values)) for kind, values in primitives), fillet)


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
    t = Table(read_toml(path, "jar", source), path, known=JAR_KEYS)
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
        p = Table(item, path, f"profile[{i}].", known={"type", *(k for keys in PRIMITIVES.values() for k in keys)})
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
    if t.has("sources") or t.has("estimates"):  # a bowl file: every number's origin (taimill.model.provenance)
        read_origins(t, tuple(k for k in ORIGIN_KEYS if t.has(k) or k == "radius_mm"))
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
    n = len(jar.profile.pieces)
    if n > geometry.MAX_PIECES:
        raise ConfigError(path, "profile", f"{len(prims)} primitives", f"make {n} boundary pieces (with the fillets); "
                          f"allowed range [1, {geometry.MAX_PIECES}] pieces, what the engine holds")
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
