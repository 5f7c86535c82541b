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
from taimill.model import charge, files, mills, preset_contacts, preset_drive, rules
from taimill.model.contact_sets import NormalLaw
from taimill.model.drive import Drive
from taimill.model.jars import Jar, load_jar
from taimill.model.materials import Balls, Friction, material_data
from taimill.model.mills import Mill, load_mill
from taimill.model.positions import load_positions
from taimill.model.preset_contacts import KINDS
from taimill.model.ranges import RANGES
from taimill.model.tables import Table, read_toml

GRAVITY = 9.81  #: m/s²

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
    command line (e.g. {"ratio": -3.0, "balls.count": 24}); they win over the file. The
    steps run in the order in which their refusals and warnings are to be given."""
    r = _read(path, overrides or {})
    t, w = r.t, r.warnings
    mill, jar, wall = _mill_and_jar(r)
    balls, count_notes = _balls(r, jar, wall)
    powder = _powder(t, balls)
    pair, friction, wall_friction, contact, tuned = preset_contacts.frictions(t, r.path.parent, w)
    ball_ball, ball_wall, softening = preset_contacts.normal_laws(t, pair, contact, friction, tuned, balls, jar, w)
    plate_rpm, jar_key, jar_speed = preset_drive.speeds(t, mill, w)
    plate_radius, radius_from_mill = preset_drive.plate_radius(t, mill, jar)
    duration, ramp_time, analysis_start, window_note = _timing(r)
    drive = preset_drive.drive(t, mill, plate_rpm, jar_key, jar_speed, ramp_time)
    w += mill.estimates_in_use(radius_from_mill=radius_from_mill)
    gravity = t.get("gravity", GRAVITY, lo=0, hi=1000)
    seed = t.get("seed", 0, kind=int, lo=0, hi=2**63 - 1)
    v_max = rules.max_impact_speed(drive.plate_omega, drive.jar_spin, plate_radius, jar, gravity)
    dt, is_auto = _time_step(t, ball_ball, ball_wall, (friction, wall_friction or friction), balls, v_max, duration)
    rate, events = _outputs(t, balls, dt, duration)
    init = None
    if t.has("initial_positions"):
        init = load_positions(t.get("initial_positions", kind=str), r.path.parent, balls, jar, t.source)
    t.done()
    w += [*count_notes, *(n for n in (preset_contacts.size_note(contact, balls, jar), window_note) if n)]
    return Preset(
        t.source, jar, balls, pair, friction, ball_ball, ball_wall, drive, plate_radius,
        duration, analysis_start, dt, is_auto, seed, rate, gravity, init, wall_friction, powder=powder,
        warnings=tuple(w), mill=mill, events_output=events, softening=softening,
    )


@dataclass
class _Reading:
    """A preset file being read, the command line's overrides applied: what the steps
    of load_preset share."""

    path: Path
    t: Table  #: its top-level table (t.data: the file's data, overrides applied)
    file_duration: object  #: the file's own duration, before any override (rules.analysis_window)
    warnings: list = field(default_factory=list)  #: the preset's warnings, in order


def _read(path, overrides: dict) -> _Reading:
    """The preset file `path` (a name or file) read, with `overrides` applied."""
    rules.one_jar_speed("command line", overrides.get("ratio"), overrides.get("jar_rpm"), options=True)
    rules.one_of_two("command line", "--filling", overrides.get("balls.filling"), "--balls", overrides.get("balls.count"))
    text = files.check_path_text(str(path) if isinstance(path, Path) else path, "command line", "preset", "a preset file")
    path = files.resolve(text, "preset", True, source="command line", key="preset")
    if files.missing(path) and path.stem in files.bundled_names("preset"):  # presets/NAME.toml from another folder
        raise ConfigError("command line", "preset", text, f"no such preset file here; the bundled preset of this name "
                          f"runs from any folder as `taimill run {path.stem}`")
    data = read_toml(path, "preset", "command line")
    files.check_kind(data, "preset", text, "command line", "preset")
    file_duration = data.get("duration")
    Table(data, str(path), known=PRESET_KEYS)
    overridden = _override(data, overrides, str(path))
    return _Reading(path, Table(data, str(path), "", overridden, known=PRESET_KEYS), file_duration)


def _override(data: dict, overrides: dict, source: str) -> frozenset:
    """Apply the command line's `overrides` to the file's `data` (one of two exclusive
    keys drops the other); the keys given."""
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
    return frozenset(k for k, v in overrides.items() if v is not None)


def _mill_and_jar(r: _Reading) -> tuple[Mill, Jar, object]:
    """(the mill, the jar, the jar wall's material data)."""
    t = r.t
    mill_src = t.where("mill")
    mill = load_mill(t.get("mill", mills.DEFAULT, kind=str), mill_src, Path.cwd() if mill_src == "command line" else r.path.parent)
    # a jar file named on the command line is relative to the current folder, in a preset to the preset's
    jar_src = t.where("jar_volume_ml" if t.has("jar_volume_ml") else "jar")
    jar = load_jar(_jar_name(t, mill, r.warnings), jar_src, None if jar_src == "command line" else r.path.parent)
    if t.has("jar_material"):  # the jar's shape in another material
        wall = material_data(t.get("jar_material", kind=str), t.where("jar_material"), "jar_material")
        jar = dataclasses.replace(jar, wall_material=wall.name)
    else:
        wall = material_data(jar.wall_material, jar.source, "wall_material")
    return mill, jar, wall


def _balls(r: _Reading, jar: Jar, wall) -> tuple[Balls, list]:
    """(the balls of the [balls] table, the notes on how their count was found); the
    ball and wall materials' estimates are added to the warnings."""
    bt = r.t.table("balls", known=BALLS_KEYS)
    ball = material_data(bt.get("material", kind=str), bt.where("material"), "balls.material")
    size_key = _size_key(bt)
    size = bt.get(size_key, lo=0, lo_open=True)
    radius = (size if size_key == "radius_mm" else size / 2.0) * 1e-3
    rules.ball_fits_jar(bt.where(size_key), f"balls.{size_key}", size, radius, jar)
    count, count_key, notes = charge.ball_count(bt, jar, radius)
    balls = Balls(count, ball.material, radius)
    bt.done()
    _check_fill(balls, jar, bt.where(count_key), placed=r.t.has("initial_positions"))
    r.warnings += ball.estimate_notes(("density_kg_m3", "youngs_modulus_gpa", "poisson"), "ball material")
    r.warnings += wall.estimate_notes(("youngs_modulus_gpa", "poisson"), "wall material")
    return balls, notes


def _powder(t: Table, balls: Balls) -> charge.Powder | None:
    """The powder charged ([powder]), or None."""
    pt = t.table("powder", required=False, known=POWDER_KEYS)
    if pt is None:
        return None
    powder = charge.read_powder(pt, balls.count * balls.mass)
    pt.done()
    return powder


def _timing(r: _Reading) -> tuple[float, float, float, str | None]:
    """(duration, ramp_time, analysis_start (s), the analysis window's warning or None);
    a shortened run's window as rules.analysis_window places it."""
    t, data = r.t, r.t.data
    duration = t.get("duration", lo=0, lo_open=True, hi=36000)
    ramp_time = t.get("ramp_time", 1.0, **(RANGES["ramp_time"].bounds | {"hi": duration}))
    window_note = None
    given_start = data.get("analysis_start", 0.0)
    if isinstance(given_start, (int, float)) and not isinstance(given_start, bool):  # else t.get refuses it
        start, window_note = rules.analysis_window(
            given_start, r.file_duration if isinstance(r.file_duration, (int, float)) else None, duration, ramp_time,
            start_given="analysis_start" in t.overridden, duration_given="duration" in t.overridden)
        if start != given_start:
            data["analysis_start"] = start
    analysis_start = t.get("analysis_start", 0.0, lo=0, hi=duration)
    if analysis_start >= duration:
        raise ConfigError(t.source, "analysis_start", analysis_start, f"must be below duration = {duration:g} s")
    return duration, ramp_time, analysis_start, window_note


def _time_step(t: Table, ball_ball: NormalLaw, ball_wall: NormalLaw, frictions, balls: Balls, v_max: float,
               duration: float) -> tuple[float, bool]:
    """(dt in s, whether automatic): `dt` of the preset, or the automatic step for
    impacts up to v_max (m/s)."""
    dt_auto = rules.auto_dt(ball_ball, ball_wall, frictions, balls, v_max)
    t.used.add("dt")
    dt, is_auto = rules.time_step(t.where("dt"), t.data.get("dt", "auto"), dt_auto, v_max, duration)
    if is_auto:
        rules.auto_steps(t.where("dt"), t.where("duration"), dt, duration)
    return dt, is_auto


def _outputs(t: Table, balls: Balls, dt: float, duration: float) -> tuple[float, str]:
    """(trajectory rate in Hz, what is stored of the events) of [outputs], the rate
    fitting the run (rules.frames_fit)."""
    out = t.table("outputs", required=False, known=OUTPUTS_KEYS)
    rate, rate_source = 100.0, t.source
    events = rules.events_output(balls.count)
    if out is not None:
        rate = out.get("trajectory_rate", 100.0, lo=0, lo_open=True)
        rate_source = out.where("trajectory_rate")
        events = out.get("events", events, allowed=rules.EVENT_OUTPUTS)
        out.done()
    rules.frames_fit(rate_source, t.where("duration"), rate, dt, duration,
                     blame_duration="duration" in t.overridden and "outputs.trajectory_rate" not in t.overridden)
    return rate, events


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


def _check_fill(balls: Balls, jar: Jar, source, placed=False):
    """Random loose packing reaches ~0.55; refuse fills that cannot be placed at random
    (given positions are checked ball by ball instead: a settled bed is denser)."""
    fill = balls.count * 4.0 / 3.0 * math.pi * balls.radius**3 / jar.volume
    if fill > charge.MAX_RANDOM_FILL and not placed:
        raise ConfigError(source, "balls.count", balls.count,
                          f"balls fill {fill:.0%} of the jar; at most {charge.MAX_RANDOM_FILL:.0%} can be placed at random")
