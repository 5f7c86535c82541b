"""Jars: a 2-D profile of primitives (circle, cuts, lifters) extruded between floor and
lid, read from a bundled jar or bowl (taimill/data/jars/NAME.toml, then
taimill/data/bowls/NAME.toml) or a jar file and checked before its geometry is built."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

from taimill.errors import ConfigError
from taimill.model import files, geometry
from taimill.model.materials import load_material
from taimill.model.provenance import read_origins
from taimill.model.tables import Table, read_toml

JARS_DIR = files.BUNDLED["jar"][0]  #: the bundled jars (bundled bowls are jars too: files.BUNDLED)
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


def resolve_jar_path(name: str, base: Path | None = None, source="preset") -> Path:
    """A jar's file: a name is a bundled jar or bowl; a path (ending in .toml) is
    relative to `base` (the folder of the preset naming it), or to the current folder
    if base is None (a jar given on the command line)."""
    return files.resolve(name, "jar", base is None, base, source=source, key="jar")


def jar_names() -> list[str]:
    """The bundled jars and bowls, by name."""
    return files.bundled_names("jar")


def load_jar(name: str, source="preset", base: Path | None = None) -> Jar:
    """A jar by name or file (see resolve_jar_path), checked."""
    files.check_path_text(name, source, "jar", "a jar name or jar file")
    path = resolve_jar_path(name, base, source)
    if files.missing(path):
        raise ConfigError(source, "jar", name, f"no jar file {path}; known jars: {', '.join(jar_names())}")
    data = read_toml(path, "jar", source)
    files.check_kind(data, "jar", name, source, "jar")
    t = Table(data, path, known=JAR_KEYS)
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


BUILT_MARK = "# Written by `taimill jars new`"  #: first line of a jar file the builder wrote


def cylinder_jar_text(name: str, volume_ml: float, diameter_mm: float, fillet_mm: float = 0.0,
                      material: str = "aisi-304", source="command line") -> str:
    """A jar file (TOML text) of a plain cylinder of inside volume V and diameter D,
    height = V / (π r²); impossible values are a ConfigError naming the option."""
    h_lo, h_hi = 0.0, 1000.0  # mm, what load_jar takes
    if not 0 < diameter_mm <= 2 * PRIMITIVES["circle"]["radius_mm"][1]:
        raise ConfigError(source, "--diameter", diameter_mm, f"allowed range (0, {2 * PRIMITIVES['circle']['radius_mm'][1]:g}] mm")
    if volume_ml <= 0:
        raise ConfigError(source, "--volume", volume_ml, "must be a volume > 0 ml")
    r = diameter_mm / 2
    height = volume_ml * 1e3 / (math.pi * r**2)  # mm (1 ml = 1000 mm³)
    if not h_lo < height <= h_hi:
        raise ConfigError(source, "--volume", volume_ml, f"in a {diameter_mm:g} mm cylinder makes a jar {height:.4g} mm high; "
                          f"allowed range ({h_lo:g}, {h_hi:g}] mm: give a volume of at most {math.pi * r**2 * h_hi * 1e-3:.4g} ml")
    if not 0 <= fillet_mm < min(r, height / 2):
        raise ConfigError(source, "--fillet", fillet_mm, f"allowed range [0, {min(r, height / 2):.4g}) mm: "
                          f"below the radius ({r:g} mm) and half the height ({height:.4g} mm)")
    try:
        load_material(material, source)
    except ConfigError as err:
        raise ConfigError(source, "--material", material, err.allowed) from None
    return "\n".join([
        f"{BUILT_MARK} {name} --volume {volume_ml:g} --diameter {diameter_mm:g}"
        + (f" --fillet {fillet_mm:g}" if fillet_mm else "") + f" --material {material}",
        "# The inside volume and diameter are the user's figures; height = V / (pi r^2).",
        f'description = "{volume_ml:g} ml cylinder, {diameter_mm:g} mm inside diameter, {material}"',
        f"height_mm = {height:.6g}",
        f'wall_material = "{material}"',
        *([f"fillet_mm = {fillet_mm:g}  # a plain cylinder's cross-section has no corner to round"] if fillet_mm else []),
        "",
        "[[profile]]",
        'type = "circle"',
        f"radius_mm = {r:.6g}",
        "",
    ])
