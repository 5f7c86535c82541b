"""A preset's drive (steps of taimill.model.preset.load_preset): the plate's speed, the
jar's (K or ω, or the K of a fixed gear) and the plate radius, within the limits of the
preset's mill and the rule book."""

from __future__ import annotations

from taimill.errors import ConfigError
from taimill.model import rules
from taimill.model.drive import Drive
from taimill.model.jars import Jar
from taimill.model.mills import Mill
from taimill.model.ranges import RANGES
from taimill.model.tables import Table


def speeds(t: Table, mill: Mill, warnings: list) -> tuple[float, str, float]:
    """(Ω in rpm, how the jar's speed is given: "ratio" or "jar_rpm", its value) within
    the mill's plate speeds and gear; a fixed gear gives K (said in `warnings` where it
    replaces the file's jar speed)."""
    data, source = t.data, t.source
    p = mill.plate_range
    plate_rpm = t.get("plate_rpm", **(p.bounds if mill.plate_rpm_max is None else {}))
    if plate_rpm == 0:
        raise ConfigError(t.where("plate_rpm"), "plate_rpm", plate_rpm, f"allowed range [{p.lo:g}, 0) or (0, {p.hi:g}] {p.unit}: "
                          "the speed ratio K = ω/Ω + 1 is undefined for a plate at rest")
    rules.plate_speed_fits(t.where("plate_rpm"), "plate_rpm", plate_rpm, mill)
    rules.one_jar_speed(t.where("jar_rpm"), data.get("ratio"), data.get("jar_rpm"))
    jar_key = "jar_rpm" if t.has("jar_rpm") else "ratio"
    given = jar_key if t.has(jar_key) else None
    if given and mill.gear.kind == "fixed" and t.where("mill") == "command line" != t.where(given):
        # the file's jar speed was set for the file's mill: the fixed gear of the mill chosen on
        # the command line replaces it (said); one given on the command line is refused below
        warnings.append(f"{given} = {data[given]:g} of {source} is replaced by the gear of {mill.name}: "
                        f"{mill.gear.text} ({mill.gear.k_text})")
        t.used.add(given)
        given = None
    if mill.gear.kind == "fixed":  # K from the gear; a given jar speed is refused
        return plate_rpm, "ratio", rules.gear_ratio(t.where(given) if given else source, given, data.get(given), mill)
    if given is None and mill.gear.kind == "set":
        rules.gear_ratio(source, None, None, mill)
    return plate_rpm, jar_key, t.get(jar_key, **RANGES[jar_key].bounds)


def plate_radius(t: Table, mill: Mill, jar: Jar) -> tuple[float, bool]:
    """(R_p in m: the preset's plate_radius_mm, else the mill's; whether it is the mill's).
    A radius too small for the jar is blamed on the file that gave it."""
    given = t.get("plate_radius_mm", None, **RANGES["plate_radius_mm"].bounds)
    if given is None:
        rules.plate_fits_jar(mill.source, mill.plate_radius, jar)
        return mill.plate_radius, True
    rules.plate_fits_jar(t.where("plate_radius_mm"), given * 1e-3, jar)
    return given * 1e-3, False


def drive(t: Table, mill: Mill, plate_rpm: float, jar_key: str, jar_speed: float, ramp_time: float) -> Drive:
    """The drive of these speeds (`speeds`), its jar speed within the limits however it
    is given and within the mill's gear."""
    d = Drive.from_rpm(plate_rpm, **{jar_key: jar_speed}, ramp_time=ramp_time)
    rules.jar_speed_fits(t.where(jar_key), jar_key, jar_speed, d)
    if mill.gear.kind != "fixed":
        rules.gear_ratio(t.where(jar_key), jar_key, jar_speed, mill, d)
    return d
