"""A preset: the fixed parameters of a run as one frozen dataclass in SI units, read
from its TOML file with the command line's overrides and validated before any kernel
runs (docs/model.md, faults). Files use mm and rpm where the thesis does, with the unit
in the key name; everything here is SI (m, kg, s, rad/s).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.model import charge, files
from taimill.model import rules
from taimill.model.contact.registry import NAMES as LAW_NAMES
from taimill.model.contact_sets import NormalLaw, contact_laws, soften
from taimill.model.drive import Drive
from taimill.model.jars import Jar, load_jar
from taimill.model import mills
from taimill.model.mills import Mill, load_mill
from taimill.model.materials import (FRICTION_KEYS, Balls, Friction, contact_table, load_friction, material_data,
                                     pair_estimates,
                                     read_friction)
from taimill.model.positions import load_positions
from taimill.model.ranges import RANGES
from taimill.model.tables import Table, read_toml

GRAVITY = 9.81  #: m/s²

# Contact kinds a preset may give its own friction pair and tuning (a coated jar: ball-wall only).
KINDS = ("ball_ball", "ball_wall")
# The keys of each kind of table (unknown keys are errors, reported with the nearest known one)
PRESET_KEYS = ("mill", "jar", "jar_volume_ml", "jar_material", "pair", "plate_rpm", "ratio", "jar_rpm", "duration",
               "analysis_start", "dt", "seed", "law", "softening", "initial_positions", "ramp_time", "plate_radius_mm", "gravity", "balls",
               "powder", "outputs", "friction",
               *(f"pair_{k}" for k in KINDS), *(f"friction_{k}" for k in KINDS))
BALLS_KEYS = ("count", "filling", "material", "radius_mm", "diameter_mm")
POWDER_KEYS = ("mass_g", "ball_to_powder")
#: an override of one key drops the other from the file (the command line wins)
EXCLUSIVE = {"ratio": "jar_rpm", "jar_rpm": "ratio", "balls.count": "balls.filling", "balls.filling": "balls.count",
             "powder.mass_g": "powder.ball_to_powder", "jar": "jar_volume_ml", "jar_volume_ml": "jar",
             "balls.radius_mm": "balls.diameter_mm", "balls.diameter_mm": "balls.radius_mm"}
OUTPUTS_KEYS = ("trajectory_rate", "events")

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
    powder: charge.Powder | None = None  #: the powder charged (recorded, not simulated)
    #: one line each, for the user before the run starts: numbers that are estimates or
    #: assumptions, implausible but allowed values (the loader appends; cli prints them)
    warnings: tuple[str, ...] = field(default=(), compare=False)
    mill: Mill | None = None  #: the planetary mill (its gear, plate speeds, R_p unless the preset gives plate_radius_mm)
    #: what is stored of the collision events: "rows" (one per event) or "spectra" (the
    #: energy spectra only: large mills; rules.events_output)
    events_output: str = "rows"
    softening: float = 1.0  #: contact stiffness divided by this (contact_sets.soften); 1: as measured

    @property
    def frictions(self) -> tuple[Friction, Friction]:
        """(ball-ball, ball-wall) friction, in contact-type order."""
        return self.friction, self.wall_friction or self.friction

    def as_dict(self) -> dict:
        """Resolved configuration as plain JSON-able data (for stores and summaries);
        the drive's speeds are top-level keys in every form (see Drive.as_dict). `mill`
        is the mill's own data (Mill.as_dict: name, maker, model, stations, its R_p as
        plate_radius_mm, gear, plate speeds, bowls); the `plate_radius` in use is the
        mill's unless the preset's plate_radius_mm overrides it (`plate_radius_from`:
        "mill" or "preset")."""
        d = dataclasses.asdict(dataclasses.replace(self, initial_positions=None, mill=None))
        del d["drive"], d["warnings"]
        if self.powder is None:
            del d["powder"]
        if self.mill is not None:
            d["mill"] = self.mill.as_dict()
            d["plate_radius_from"] = "mill" if self.plate_radius == self.mill.plate_radius else "preset"
        x = self.initial_positions
        if x is not None:  # inline for a few balls; the trajectory's first frame holds them all anyway
            d["initial_positions"] = x.tolist() if len(x) <= INLINE_POSITIONS else f"{len(x)} ball centres: the trajectory's first frame"
        return d | self.drive.as_dict()


def load_preset(path, overrides: dict | None = None) -> Preset:
    """Read and validate a preset: a bundled preset's name ("p4-cy-steel") or a file
    (relative to the current folder). `overrides` maps preset keys to values given on the
    command line (e.g. {"ratio": -3.0, "balls.count": 24}); they win over the file."""
    overrides = overrides or {}
    rules.one_jar_speed("command line", overrides.get("ratio"), overrides.get("jar_rpm"), options=True)
    rules.one_of_two("command line", "--filling", overrides.get("balls.filling"), "--balls", overrides.get("balls.count"))
    text = files.check_path_text(str(path) if isinstance(path, Path) else path, "command line", "preset", "a preset file")
    path = files.resolve(text, "preset", True, source="command line", key="preset")
    if files.missing(path) and path.stem in files.bundled_names("preset"):  # presets/NAME.toml from another folder
        raise ConfigError("command line", "preset", text, f"no such preset file here; the bundled preset of this name "
                          f"runs from any folder as `taimill run {path.stem}`")
    data = read_toml(path, "preset", "command line")
    files.check_kind(data, "preset", text, "command line", "preset")
    file_duration = data.get("duration")  # the preset's own, for its analysis window (rules.analysis_window)
    source = str(path)
    Table(data, source, known=PRESET_KEYS)
    for key, value in overrides.items():
        if value is None:
            continue
        table, _, leaf = key.rpartition(".")
        target = data.setdefault(table, {}) if table else data
        if not isinstance(target, dict):
            raise ConfigError(source, table, target, "must be a table")
        target[leaf] = value
        if key in EXCLUSIVE and overrides.get(EXCLUSIVE[key]) is None:
            target.pop(EXCLUSIVE[key].rpartition(".")[2], None)
    overridden = frozenset(k for k, v in overrides.items() if v is not None)
    t = Table(data, source, "", overridden, known=PRESET_KEYS)

    mill_src = t.where("mill")
    mill = load_mill(t.get("mill", mills.DEFAULT, kind=str), mill_src, Path.cwd() if mill_src == "command line" else path.parent)
    warnings: list[str] = []
    # a jar file named on the command line is relative to the current folder, in a preset to the preset's
    jar_src = t.where("jar_volume_ml" if t.has("jar_volume_ml") else "jar")
    jar = load_jar(_jar_name(t, mill, warnings), jar_src, None if jar_src == "command line" else path.parent)
    if t.has("jar_material"):  # the jar's shape in another material
        wall = material_data(t.get("jar_material", kind=str), t.where("jar_material"), "jar_material")
        jar = dataclasses.replace(jar, wall_material=wall.name)
    else:
        wall = material_data(jar.wall_material, jar.source, "wall_material")
    bt = t.table("balls", known=BALLS_KEYS)
    ball = material_data(bt.get("material", kind=str), bt.where("material"), "balls.material")
    size_key = _size_key(bt)
    size = bt.get(size_key, lo=0, lo_open=True)
    radius = (size if size_key == "radius_mm" else size / 2.0) * 1e-3
    rules.ball_fits_jar(bt.where(size_key), f"balls.{size_key}", size, radius, jar)
    count, count_key, notes = charge.ball_count(bt, jar, radius)
    balls = Balls(count, ball.material, radius)
    bt.done()
    _check_fill(balls, jar, bt.where(count_key), placed=t.has("initial_positions"))
    warnings += ball.estimate_notes(("density_kg_m3", "youngs_modulus_gpa", "poisson"), "ball material")
    warnings += wall.estimate_notes(("youngs_modulus_gpa", "poisson"), "wall material")
    pt = t.table("powder", required=False, known=POWDER_KEYS)
    powder = None
    if pt is not None:
        powder = charge.read_powder(pt, balls.count * balls.mass)
        pt.done()

    pair = t.get("pair", kind=str)
    pair_base = Path.cwd() if t.where("pair") == "command line" else path.parent
    friction, contact = load_friction(pair, t.where("pair"), base=pair_base)
    warnings += pair_estimates(pair)
    if pair.endswith(".toml"):  # a pair file: its resolved path, valid from any directory
        pair = str((pair_base / pair).resolve())
    ft = t.table("friction", required=False, known=FRICTION_KEYS)
    if ft is not None:  # the pair's friction, tuned by the user
        friction = read_friction(ft, f"{pair} (tuned)", friction)
        ft.done()
    frictions = [_kind_friction(t, kind, friction, contact, path, pair_base, warnings) for kind in KINDS]
    friction, wall_friction = frictions[0], (frictions[1] if frictions[1] != frictions[0] else None)
    law = t.get("law", None, allowed=LAW_NAMES)
    ball_ball, ball_wall = contact_laws(contact, law, balls, jar, source, notes=warnings)
    if ft is None:
        warnings += _borrowed_friction(pair, contact, friction, balls, jar)
    softening = t.get("softening", 1.0, lo=1.0, hi=rules.SOFTENING_MAX)
    if softening != 1.0:
        ball_ball, ball_wall = soften(ball_ball, softening), soften(ball_wall, softening)
        warnings.append(rules.softening_note(softening))

    r = mill.plate_range
    plate_rpm = t.get("plate_rpm", **(r.bounds if mill.plate_rpm_max is None else {}))
    if plate_rpm == 0:
        raise ConfigError(t.where("plate_rpm"), "plate_rpm", plate_rpm, f"allowed range [{r.lo:g}, 0) or (0, {r.hi:g}] {r.unit}: "
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
        jar_key, jar_speed = "ratio", rules.gear_ratio(t.where(given) if given else source, given, data.get(given), mill)
    else:
        if given is None and mill.gear.kind == "set":
            rules.gear_ratio(source, None, None, mill)
        jar_speed = t.get(jar_key, **RANGES[jar_key].bounds)
    plate_radius_mm = t.get("plate_radius_mm", None, **RANGES["plate_radius_mm"].bounds)
    plate_radius = mill.plate_radius if plate_radius_mm is None else plate_radius_mm * 1e-3
    rules.plate_fits_jar(t.where("plate_radius_mm"), plate_radius, jar)

    duration = t.get("duration", lo=0, lo_open=True, hi=36000)
    ramp_time = t.get("ramp_time", 1.0, **(RANGES["ramp_time"].bounds | {"hi": duration}))
    window_note = None
    given_start = data.get("analysis_start", 0.0)
    if isinstance(given_start, (int, float)) and not isinstance(given_start, bool):  # else t.get refuses it
        start, window_note = rules.analysis_window(
            given_start, file_duration if isinstance(file_duration, (int, float)) else None, duration, ramp_time,
            start_given="analysis_start" in overridden, duration_given="duration" in overridden)
        if start != given_start:
            data["analysis_start"] = start
    analysis_start = t.get("analysis_start", 0.0, lo=0, hi=duration)
    if analysis_start >= duration:
        raise ConfigError(source, "analysis_start", analysis_start, f"must be below duration = {duration:g} s")
    drive = Drive.from_rpm(plate_rpm, **{jar_key: jar_speed}, ramp_time=ramp_time)
    rules.jar_speed_fits(t.where(jar_key), jar_key, jar_speed, drive)
    if mill.gear.kind != "fixed":
        rules.gear_ratio(t.where(jar_key), jar_key, jar_speed, mill, drive)
    warnings += mill.estimates_in_use(radius_from_mill=plate_radius_mm is None)
    gravity = t.get("gravity", GRAVITY, lo=0, hi=1000)
    seed = t.get("seed", 0, kind=int, lo=0, hi=2**63 - 1)

    v_max = rules.max_impact_speed(drive.plate_omega, drive.jar_spin, plate_radius, jar, gravity)
    dt_auto = rules.auto_dt(ball_ball, ball_wall, (friction, wall_friction or friction), balls, v_max)
    t.used.add("dt")
    dt, is_auto = rules.time_step(t.where("dt"), t.data.get("dt", "auto"), dt_auto, v_max, duration)
    if is_auto:
        rules.auto_steps(t.where("dt"), t.where("duration"), dt, duration)

    out = t.table("outputs", required=False, known=OUTPUTS_KEYS)
    rate, rate_source = 100.0, source
    events = rules.events_output(balls.count)
    if out is not None:
        rate = out.get("trajectory_rate", 100.0, lo=0, lo_open=True)
        rate_source = out.where("trajectory_rate")
        events = out.get("events", events, allowed=rules.EVENT_OUTPUTS)
        out.done()
    rules.frames_fit(rate_source, t.where("duration"), rate, dt, duration,
                     blame_duration="duration" in overridden and "outputs.trajectory_rate" not in overridden)
    init = None
    if t.has("initial_positions"):
        init = load_positions(t.get("initial_positions", kind=str), path.parent, balls, jar, source)
    t.done()
    measured = None  # the ball size the contact set in use was measured for (a derived set: the balls' own)
    if contact is not None:
        table = contact_table(contact)[0]
        if rules.measured_set_applies(table.get("ball"), table.get("wall"), balls, jar):
            measured = table.get("ball_radius_mm")
    checks = (rules.ball_size_note(balls.radius, measured * 1e-3 if isinstance(measured, (int, float)) else None, contact),
              window_note)
    warnings += [*notes, *(n for n in checks if n)]
    return Preset(
        source, jar, balls, pair, friction, ball_ball, ball_wall, drive, plate_radius,
        duration, analysis_start, dt, is_auto, seed, rate, gravity, init, wall_friction, powder=powder,
        warnings=tuple(warnings), mill=mill, events_output=events, softening=softening,
    )


def _jar_name(t: Table, mill: Mill, warnings: list) -> str:
    """The jar: `jar` (a name or jar file), or the mill's bowl of `jar_volume_ml` (its
    maker's bowl file; its estimated sizes are added to warnings)."""
    if not t.has("jar_volume_ml"):
        return t.get("jar", kind=str)
    rules.one_jar(t.where("jar_volume_ml"), t.data.get("jar"), t.data["jar_volume_ml"])
    volume = t.get("jar_volume_ml", kind=int, lo=1, hi=100_000)
    path = mills.bowl_path(mill, volume, t.where("jar_volume_ml"))
    warnings += mills.bowl_estimates(mill, path, t.where("jar_volume_ml"))
    return str(path)


def _size_key(bt: Table) -> str:
    """"radius_mm" or "diameter_mm": the balls' size is given by exactly one."""
    rules.one_ball_size(bt.where("diameter_mm"), bt.data.get("radius_mm"), bt.data.get("diameter_mm"))
    bt.used.update(("radius_mm", "diameter_mm"))
    return "diameter_mm" if bt.has("diameter_mm") else "radius_mm"


def _borrowed_friction(pair: str, contact: str | None, friction: Friction, balls: Balls, jar: Jar) -> list[str]:
    """The warning line when a pair's friction, measured with its contact set's ball and
    wall materials, is used for other materials (its normal laws are then derived:
    contact_sets.contact_source): friction describes the surfaces with their powder, and
    no material's data gives it."""
    if contact is None:  # a pair without a measured set (dry-ceramic-powder) says what it assumes itself
        return []
    table, _, _ = contact_table(contact)
    measured = (table.get("ball"), table.get("wall"))
    if rules.measured_set_applies(*measured, balls, jar):
        return []
    return [f"friction of pair {Path(pair).stem} (mu_s = {friction.mu_s:g}, mu_d = {friction.mu_d:g}) was measured for "
            f"{measured[0]} balls on {measured[1]} walls and is used as it is for {balls.material.name} balls on "
            f"{jar.wall_material} walls; --pair names one for your powder (taimill materials lists them, e.g. "
            "dry-ceramic-powder)"]


def _kind_friction(t: Table, kind: str, friction: Friction, contact: str | None, path: Path, pair_base: Path,
                   warnings: list) -> Friction:
    """Friction of one contact kind: `pair_KIND` (a pair of the same contact set)
    instead of `pair`, then tuned by `[friction_KIND]`; else the preset's friction."""
    key = f"pair_{kind}"
    if t.has(key):
        name = t.get(key, kind=str)
        base = Path.cwd() if t.where(key) == "command line" else pair_base
        friction, own = load_friction(name, t.where(key), key, base)
        warnings += pair_estimates(name)
        rules.same_contact_set(t.where(key), key, name, own, contact, "`pair` uses",
                               " (the normal laws come from `pair`; pick a pair of the same contact set)")
    ft = t.table(f"friction_{kind}", required=False, known=FRICTION_KEYS)
    if ft is not None:
        friction = read_friction(ft, f"{friction.name} ({kind.replace('_', '-')}, tuned)", friction)
        ft.done()
    return friction


def _check_fill(balls: Balls, jar: Jar, source, placed=False):
    """Random loose packing reaches ~0.55; refuse fills that cannot be placed at random
    (given positions are checked ball by ball instead: a settled bed is denser)."""
    fill = balls.count * 4.0 / 3.0 * math.pi * balls.radius**3 / jar.volume
    if fill > charge.MAX_RANDOM_FILL and not placed:
        raise ConfigError(source, "balls.count", balls.count,
                          f"balls fill {fill:.0%} of the jar; at most {charge.MAX_RANDOM_FILL:.0%} can be placed at random")
