"""Parametric jar families for `taimill design`: each maps a parameter dict to a jar
file (TOML text) on the jar primitives of taimill.model.jars (circle, cut, lifter, one
fillet radius), so that a designed jar is an ordinary jar file any command runs.

The curved wall is the reference jar's circle (radius R: the bowl must fit the mill's
station), the height and wall material are the reference jar's. Parameters:

    n_lifters, lifter_radius_mm, lifter_protrusion_mm, lifter_spread, lifter_offset_deg
        n rounded lifters, each a disc of radius r reaching p into the jar (its innermost
        point at R - p, so its centre at R - p + r); lifter i sits at
        offset + i · spread · 360°/n (spread 1: evenly spaced, smaller: clustered).
    n_flats, flat_depth_mm, flat_spread
        n flat walls (cuts) at depth d from the curved wall (distance R - d from the
        axis); flat i at i · spread · 360°/n.
    fillet_mm
        the radius rounding every corner.

The search ranges are given as fractions of R (and the ball radius for the fillet):
they bound the search, they are not claims about good jars. The thesis' jars sit inside
them: 1L/3L lifters r = p = 4.85 mm = 0.15 R, HM's flat 14.4 mm = 0.44 R deep, T's 9.9 mm
= 0.30 R, fillets 8 mm.
"""

from __future__ import annotations

from dataclasses import dataclass

from taimill.errors import ConfigError


@dataclass(frozen=True)
class Param:
    """One searched parameter: [lo, hi], an integer or a float, in the unit its name ends with."""

    name: str
    lo: float
    hi: float
    integer: bool = False


@dataclass(frozen=True)
class Family:
    name: str
    description: str
    ranges: tuple  #: ((name, lo, hi, integer, scale), ...); scale "R" (× jar radius, mm), "ball" (× ball radius, mm), "" (as is)

    def params(self, radius_mm: float, ball_radius_mm: float) -> list[Param]:
        """The family's parameters with bounds for a jar of radius R and balls of radius r (mm)."""
        scale = {"R": radius_mm, "ball": ball_radius_mm, "": 1.0}
        out = []
        for name, lo, hi, integer, (s_lo, s_hi) in self.ranges:
            out.append(Param(name, round(lo * scale[s_lo], 6), round(hi * scale[s_hi], 6), integer))
        return out


FIXED = (("", ""), ("R", "R"), ("ball", "R"))  # scales of (lo, hi)
_LIFTERS = (("n_lifters", 1, 4, True, FIXED[0]), ("lifter_radius_mm", 0.1, 0.4, False, FIXED[1]),
            ("lifter_protrusion_mm", 0.1, 0.5, False, FIXED[1]), ("lifter_spread", 0.25, 1.0, False, FIXED[0]))
_FLATS = (("n_flats", 1, 3, True, FIXED[0]), ("flat_depth_mm", 0.1, 0.6, False, FIXED[1]),
          ("flat_spread", 0.25, 1.0, False, FIXED[0]))
_FILLET = (("fillet_mm", 1.0, 0.4, False, FIXED[2]),)

FAMILIES = {
    "lifters": Family("lifters", "n rounded lifters on the curved wall", _LIFTERS + _FILLET),
    "flats": Family("flats", "n flat walls (the half-moon and triangle idea)", _FLATS + _FILLET),
    "mixed": Family("mixed", "0-2 flat walls and 0-3 lifters, the lifters turned by an offset",
                    (("n_flats", 0, 2, True, FIXED[0]),) + _FLATS[1:]
                    + (("n_lifters", 0, 3, True, FIXED[0]),) + _LIFTERS[1:]
                    + (("lifter_offset_deg", 0.0, 360.0, False, FIXED[0]),) + _FILLET),
}


def family(name: str, source="command line") -> Family:
    if name not in FAMILIES:
        raise ConfigError(source, "--family", name, f"one of {', '.join(FAMILIES)}")
    return FAMILIES[name]


def primitives(params: dict, radius_mm: float) -> list[dict]:
    """The [[profile]] tables (mm, degrees) of a parameter dict on a circle of radius R."""
    R = radius_mm
    out = [{"type": "circle", "radius_mm": R}]
    n = int(params.get("n_flats", 0))
    for i in range(n):
        out.append({"type": "cut", "distance_mm": R - params["flat_depth_mm"],
                    "angle_deg": i * params["flat_spread"] * 360.0 / n})
    n = int(params.get("n_lifters", 0))
    for i in range(n):
        r, p = params["lifter_radius_mm"], params["lifter_protrusion_mm"]
        angle = params.get("lifter_offset_deg", 0.0) + i * params["lifter_spread"] * 360.0 / n
        out.append({"type": "lifter", "radius_mm": r, "distance_mm": R - p + r, "angle_deg": angle % 360.0})
    return out


def _num(v: float) -> str:
    return f"{v:.6g}"


def jar_text(params: dict, radius_mm: float, height_mm: float, wall_material: str, description: str,
             comment: list[str] = ()) -> str:
    """A jar file: the comment lines, then the jar of `params` (taimill.model.jars format)."""
    lines = [f"# {c}" if c else "#" for c in comment]
    lines += [f'description = "{description}"', f"height_mm = {_num(height_mm)}", f'wall_material = "{wall_material}"']
    prims = primitives(params, radius_mm)
    if len(prims) > 1:
        lines.append(f"fillet_mm = {_num(params['fillet_mm'])}")
    for prim in prims:
        lines += ["", "[[profile]]", f'type = "{prim["type"]}"']
        lines += [f"{k} = {_num(v)}" for k, v in prim.items() if k != "type"]
    return "\n".join(lines) + "\n"


def describe(params: dict) -> str:
    """A short name of a design: '3 lifters r 4.9 p 6.1 mm, fillet 8 mm'."""
    parts = []
    if int(params.get("n_flats", 0)):
        parts.append(f"{int(params['n_flats'])} flat(s) {params['flat_depth_mm']:.3g} mm deep")
    if int(params.get("n_lifters", 0)):
        parts.append(f"{int(params['n_lifters'])} lifter(s) r {params['lifter_radius_mm']:.3g} "
                     f"p {params['lifter_protrusion_mm']:.3g} mm")
    if not parts:
        return "cylinder"
    return ", ".join(parts) + f", fillet {params['fillet_mm']:.3g} mm"
