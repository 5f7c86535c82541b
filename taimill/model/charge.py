"""The charge as users describe it: balls by count or by ball filling degree, and the
powder by mass or ball-to-powder ratio (docs/model.md, the charge). The powder is
recorded in the run's resolved configuration for outcome work; the simulated balls do
not feel it."""

from __future__ import annotations

import math
from dataclasses import dataclass

from taimill.errors import ConfigError
from taimill.model import rules
from taimill.model.ranges import RANGES

#: Packing fraction φ of a ball bed at rest (solid volume / bulk volume). An estimate:
#: equal spheres pack at random between random loose packing (≈ 0.55, no source
#: checked) and random close packing (0.64 ± 0.02, J. G. Berryman, Phys. Rev. A 27, 1053
#: (1983)); a bed poured into a small bowl, loosened by the wall, lies between the two.
PACKING_FRACTION = 0.60
MAX_RANDOM_FILL = 0.45  #: solid fraction of the jar balls placed at random can reach (preset._check_fill)
BPR_TOLERANCE = 0.01  #: relative disagreement allowed between powder.mass_g and powder.ball_to_powder


@dataclass(frozen=True)
class Powder:
    """The powder charged with the balls; not simulated (the balls do not feel it)."""

    mass: float  #: kg
    ball_to_powder: float  #: BPR: total ball mass / powder mass


def ball_volume(radius: float) -> float:
    """Volume of one ball (m³) of radius m."""
    return 4.0 / 3.0 * math.pi * radius**3


def count_from_filling(filling: float, jar_volume: float, radius: float, phi: float = PACKING_FRACTION) -> int:
    """Ball count of a ball filling degree: the ball bed's bulk volume as a fraction of
    the jar's, n = round(filling · V_jar · φ / V_ball)."""
    return round(filling * jar_volume * phi / ball_volume(radius))


def ball_count(bt, jar, radius: float) -> tuple[int, str, list[str]]:
    """(count, the key it came from, notes for Preset.warnings) of a [balls] table `bt`
    (taimill.model.tables.Table) giving exactly one of `count` and `filling`."""
    rules.one_of_two(bt.where("filling"), "balls.filling", bt.data.get("filling"), "balls.count", bt.data.get("count"))
    if not bt.has("filling"):
        if not bt.has("count"):
            raise ConfigError(bt.source, "balls.count", None, "missing (required key): give balls.count or balls.filling")
        return bt.get("count", kind=int, **RANGES["balls.count"].bounds), "count", []
    filling = bt.get("filling", lo=0, lo_open=True, hi=1)
    if filling * PACKING_FRACTION > MAX_RANDOM_FILL:
        raise ConfigError(bt.where("filling"), "balls.filling", filling,
                          f"allowed range (0, {MAX_RANDOM_FILL / PACKING_FRACTION:.2g}]: balls of a bed filling "
                          f"{filling:g} of the jar take {filling * PACKING_FRACTION:.0%} of its volume; "
                          f"at most {MAX_RANDOM_FILL:.0%} can be placed at random")
    count = count_from_filling(filling, jar.volume, radius)
    r = RANGES["balls.count"]
    if not r.lo <= count <= r.hi:
        raise ConfigError(bt.where("filling"), "balls.filling", filling,
                          f"gives {count} balls of {radius * 1e3:g} mm in jar {jar.name} ({jar.volume * 1e6:.4g} ml); "
                          f"allowed range [{r.lo:g}, {r.hi:g}] balls")
    note = (f"balls.filling = {filling:g}: {count} balls of {radius * 1e3:g} mm radius in jar {jar.name} "
            f"({jar.volume * 1e6:.4g} ml), count = round(filling · V_jar · φ / V_ball) with φ = {PACKING_FRACTION:g}, "
            "the packing fraction of a random ball bed (an estimate)")
    return count, "filling", [note]


def read_powder(pt, ball_mass: float) -> Powder:
    """The [powder] table `pt`: mass_g and/or ball_to_powder (mass ratio of all balls to
    the powder, `ball_mass` kg); one gives the other, both must agree within BPR_TOLERANCE."""
    if not (pt.has("mass_g") or pt.has("ball_to_powder")):
        raise ConfigError(pt.source, "powder", pt.data, "missing (required key): give powder.mass_g or powder.ball_to_powder")
    mass = pt.get("mass_g", None, lo=0, lo_open=True, hi=1e6)
    bpr = pt.get("ball_to_powder", None, lo=0, lo_open=True, hi=1e6)
    if mass is None:
        return Powder(ball_mass / bpr, bpr)
    derived = ball_mass / (mass * 1e-3)
    if bpr is not None and abs(bpr - derived) > BPR_TOLERANCE * derived:
        where = pt.where("mass_g") if pt.where("mass_g") == "command line" else pt.where("ball_to_powder")
        raise ConfigError(where, "powder.ball_to_powder", bpr,
                          f"disagrees with powder.mass_g = {mass:g}: the balls weigh {ball_mass * 1e3:.4g} g, so "
                          f"{mass:g} g of powder is a ball-to-powder ratio of {derived:.4g}; give one of the two")
    return Powder(mass * 1e-3, derived if bpr is None else bpr)
