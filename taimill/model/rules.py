"""The rule book: every rule that ties values of a run together, stated once, for the
preset loader (and so the command line, whose options are preset overrides) and the
live mill of the TUI. Each rule is a pure function that returns what it decided or
raises the ConfigError naming who gave the value (a file, the command line, the TUI),
the key, the value and what is allowed. The range of a single value is in `ranges`."""

from __future__ import annotations

import functools
import math

from taimill.errors import ConfigError
from taimill.model import laws as laws_np
from taimill.model.ranges import RANGES

MAX_STEPS = 1e10  #: time steps of one run; more would take years of wall time
MAX_FRAMES = 1e7  #: trajectory frames of one run (the thesis' 24 s at 100 Hz: 2400)
MAX_RATE = 1e5  #: Hz, trajectory frames per simulated second


# ------------------------------------------------------------------ drive
def one_jar_speed(source, ratio, jar_rpm, *, options: bool = False):
    """The jar's speed is given as K (`ratio`) or as ω (`jar_rpm`, rpm), not both: each
    alone fixes its spin w. None: not given; options: both came as the command-line
    options --ratio / --jar-rpm (the message names them so)."""
    if ratio is None or jar_rpm is None:
        return
    if options:
        raise ConfigError(source, "--jar-rpm", jar_rpm, f"give either --ratio ({ratio!r}) or --jar-rpm, not both")
    raise ConfigError(source, "jar_rpm", jar_rpm, "give either ratio or jar_rpm, not both")


def one_of_two(source, key: str, value, other: str, other_value):
    """Two keys that fix one quantity (balls.count and balls.filling; the options --balls
    and --filling): give one, not both. None: not given."""
    if value is None or other_value is None:
        return
    raise ConfigError(source, key, value, f"give either {other} ({other_value!r}) or {key}, not both")


def one_jar(source, jar, volume_ml):
    """The jar is given as a jar (`jar`: a name or file) or as the mill's bowl of a volume
    (`jar_volume_ml`), not both. None: not given."""
    if jar is not None and volume_ml is not None:
        raise ConfigError(source, "jar_volume_ml", volume_ml, "give either jar or jar_volume_ml, not both")


def one_ball_size(source, radius_mm, diameter_mm):
    """The balls' size is given by `radius_mm` or by `diameter_mm` (mm), not both (None:
    not given)."""
    if radius_mm is not None and diameter_mm is not None:
        raise ConfigError(source, "balls.diameter_mm", diameter_mm, f"give either radius_mm ({radius_mm!r}) or diameter_mm, not both")


def jar_speed_fits(source, key: str, value, drive):
    """One limit on the jar's speed however it is given: ω = w − Ω (relative to the
    plate) within RANGES["jar_rpm"], also when the jar's speed came as K = `ratio`
    (ω = (K − 1)·Ω), so `--plate-rpm 1000 --ratio 10` (ω = 9000 rpm) is refused like
    `--jar-rpm 9000`. key, value: how the speed was given; drive: the resulting `Drive`."""
    r = RANGES["jar_rpm"]
    if r.lo <= drive.jar_rpm <= r.hi:
        return
    if key != "ratio" or drive.plate_rpm == 0:
        raise ConfigError(source, key, value, f"allowed range [{r.lo:g}, {r.hi:g}] {r.unit}")
    k, p = RANGES["ratio"], drive.plate_rpm
    a, b = sorted((1 + r.lo / p, 1 + r.hi / p))
    raise ConfigError(source, key, value, f"allowed range [{max(a, k.lo):.4g}, {min(b, k.hi):.4g}] at plate_rpm = {p:g}: "
                      f"the jar would turn at {drive.jar_rpm:.6g} rpm relative to the plate, "
                      f"at most [{r.lo:g}, {r.hi:g}] {r.unit} however its speed is given")


def plate_speed_fits(source, key: str, plate_rpm, mill):
    """Ω (rpm) within the mill's plate speeds (`Mill.plate_range`, and at least its
    plate_rpm_min in size where known); a mill with unknown limits keeps the global
    RANGES["plate_rpm"]. Ω = 0 is allowed here (a live mill at rest); the preset
    refuses it where K would be undefined."""
    r = mill.plate_range
    lo = mill.plate_rpm_min
    if r.lo <= plate_rpm <= r.hi and (lo is None or plate_rpm == 0 or abs(plate_rpm) >= lo):
        return plate_rpm
    if mill.plate_rpm_max is None and lo is None:
        raise ConfigError(source, key, plate_rpm, f"allowed range [{r.lo:g}, {r.hi:g}] {r.unit}")
    raise ConfigError(source, key, plate_rpm, f"allowed range [{lo or 0:g}, {r.hi:g}] {r.unit} on the mill {mill.name} "
                      "(a negative speed is its mirror image)")


def gear_ratio(source, key: str | None, value, mill, drive=None) -> float | None:
    """The speed ratio K the mill's gear allows. key, value: how the jar's speed was given
    (`ratio` K or `jar_rpm` ω, None: not given), drive: the `Drive` it gives. A fixed gear
    refuses any given speed and returns its K; a set of gears takes only its K; a free gear
    within a range only K in it. Returns the fixed gear's K, else None (the given speed stands)."""
    g = mill.gear
    if g.kind == "fixed":
        if key is not None:
            raise ConfigError(source, key, value, f"{mill.name} has a fixed gear {g.text} ({g.k_text}); {key} cannot be set")
        return g.ks[0]
    if key is None:
        allowed = f" ({g.k_text}, gear {g.text})" if g.kind == "set" else ""
        raise ConfigError(source, "ratio", None, f"missing (required key): give ratio or jar_rpm{allowed}")
    k = drive.ratio
    if g.kind == "set" and not any(abs(k - x) <= 1e-9 * max(1.0, abs(x)) for x in g.ks):
        raise ConfigError(source, key, value, f"{mill.name} has the gears {g.text}: allowed {g.k_text}" +
                          (f" (here K = {k:.6g})" if key != "ratio" else ""))
    if g.kind == "free" and ((g.k_min is not None and k < g.k_min) or (g.k_max is not None and k > g.k_max)):
        raise ConfigError(source, key, value, f"{mill.name} drives the jar at {g.k_text}" + (f" (here K = {k:.6g})" if key != "ratio" else ""))
    return None


# ------------------------------------------------------------------ friction
def friction_order(source, key: str, mu_s: float, mu_d: float):
    """μ_d ≤ μ_s (both -): friction eases from its static to its dynamic value as the
    slip grows (thesis eq 3.7), never up."""
    if mu_d > mu_s:
        raise ConfigError(source, key, mu_d, f"dynamic friction must not exceed static mu_s = {mu_s:g}; allowed range [0, {mu_s:g}]")


# ------------------------------------------------------------------ contact sets
def measured_set_applies(ball_material: str, wall_material: str, balls, jar) -> bool:
    """A contact set is measured for one ball material on one wall material: it holds
    for these balls (`Balls`) and the jar's wall (`Jar`) when they are those; otherwise
    the contact set is derived from the materials (taimill.model.contact_sets)."""
    return ball_material == balls.material.name and wall_material == jar.wall_material


def same_contact_set(source, key: str, pair: str, contact: str, in_use: str, uses: str, why: str = ""):
    """A further pair (a preset's pair_KIND, a pair chosen while the mill runs) changes
    friction only: the normal laws stay those of the contact set in use, so the pair's
    contact set `contact` must be it. uses, why: how the message names the set in use
    and why it must be kept. A pair without a measured set (contact None) changes friction
    only wherever it is used."""
    if contact is not None and contact != in_use:
        raise ConfigError(source, key, pair, f"is for the '{contact}' contact set; {uses} '{in_use}'{why}")


# ------------------------------------------------------------------ time step
def max_impact_speed(plate_omega: float, jar_spin: float, plate_radius: float, jar, gravity: float) -> float:
    """Upper estimate of contact speeds (m/s), for the automatic time step: the jar's
    ground speed plus its wall speed plus a free fall across the jar. Ω, w in rad/s,
    R_p in m, gravity in m/s²."""
    return abs(plate_omega) * plate_radius + abs(jar_spin) * jar.radius + math.sqrt(2 * gravity * 2 * jar.radius) + 0.5


@functools.lru_cache(maxsize=256)
def _auto_dt(ball_ball, ball_wall, v_max: float) -> float:
    """laws.auto_dt, once per process for a pair of laws and a speed (it simulates impacts)."""
    return laws_np.auto_dt((ball_ball, ball_wall), v_max)


def auto_dt(ball_ball, ball_wall, frictions, balls, v_max: float) -> float:
    """The automatic time step (s): STEPS_PER_CONTACT steps in the shortest contact of
    either `NormalLaw` at impact speeds up to v_max (m/s), and short enough for the rolling
    resistance of the (ball-ball, ball-wall) `frictions` on these `balls`."""
    return min(_auto_dt(ball_ball, ball_wall, v_max),
               laws_np.rolling_dt(frictions, balls.inertia, balls.radius, math.inf))


def time_step(source, given, dt_auto: float, v_max: float, duration: float) -> tuple[float, bool]:
    """(dt in s, whether automatic) for a preset's `dt` = given: "auto" is dt_auto; a
    number is taken if it leaves ≥ 10 steps per contact at v_max (m/s) and, below the
    automatic step, at most MAX_STEPS steps in `duration` (s)."""
    if given == "auto":
        return dt_auto, True
    dt_limit = dt_auto * laws_np.STEPS_PER_CONTACT / 10.0  # ≥ 10 steps per contact
    if isinstance(given, bool) or not isinstance(given, (int, float)) or not 0 < given <= dt_limit:
        raise ConfigError(source, "dt", given, f"'auto' or a time step in (0, {dt_limit:.3g}] s (10 steps per contact at {v_max:.1f} m/s)")
    dt = float(given)
    dt_min = min(dt_auto, duration / MAX_STEPS)
    if dt < dt_min:
        raise ConfigError(source, "dt", given, f"'auto' or a time step in [{dt_min:.3g}, {dt_limit:.3g}] s: "
                          f"{duration / dt:.3g} steps for duration = {duration:g} s, at most {MAX_STEPS:.0e} "
                          "(smaller than the automatic step only while it runs in reasonable time)")
    return dt, False


def auto_steps(source, duration_source, dt: float, duration: float):
    """The automatic step `dt` (s) must be a finite positive number (a law whose impacts
    never end gives none) and leave at most MAX_STEPS steps in `duration` (s), like an
    explicit one."""
    if not (math.isfinite(dt) and dt > 0):
        raise ConfigError(source, "dt", "auto", f"the contact laws give no finite automatic time step ({dt!r} s); "
                          "give an explicit dt in s or another law or pair")
    if duration / dt > MAX_STEPS:
        raise ConfigError(duration_source, "duration", duration, f"allowed range (0, {MAX_STEPS * dt:.3g}] s: "
                          f"{duration / dt:.3g} steps of the automatic dt = {dt:.3g} s, at most {MAX_STEPS:.0e}")


def frame_every(rate: float, dt: float) -> int:
    """Time steps between trajectory frames at `rate` (Hz) and time step dt (s)."""
    return max(1, int(round(1.0 / (rate * dt))))


def frame_intervals(rate: float, dt: float, duration: float) -> int:
    """Frame intervals of a run of `duration` (s) at `rate` (Hz) and time step dt (s):
    a run lasts whole frame intervals, the nearest whole number and at least one, with
    a frame at both ends (frames_fit keeps the stretch within a step of the duration)."""
    return max(1, int(round(duration / (frame_every(rate, dt) * dt))))


def frames_fit(rate_source, duration_source, rate: float, dt: float, duration: float, blame_duration: bool):
    """The trajectory rate (Hz) and the duration (s) together: at least one frame in the
    run (a run lasts whole frame intervals: a shorter one would be stretched to one) and at
    most MAX_FRAMES; the rate at most MAX_RATE and two steps of dt (s) per frame.
    blame_duration: the duration was given last (the command line), so it is the value named."""
    hi = min(MAX_RATE, 0.5 / dt, MAX_FRAMES / duration)
    interval = frame_every(rate, dt) * dt
    # a run lasts whole frame intervals (frame_intervals): one more than a time step
    # longer than the run would stretch it (a 0.3 s run at 1 Hz would run 1 s); the
    # rounding of the interval to whole steps stretches it by half a step at most
    short = interval > duration + dt * (1 + 1e-9)
    if blame_duration and short:
        raise ConfigError(duration_source, "duration", duration, f"allowed range [{interval - dt:.3g}, 36000] s: "
                          f"at least one frame interval at trajectory_rate = {rate:g} Hz")
    lo = 1.0 / (duration + 0.5 * dt)  # from this rate on the interval, whole steps, keeps within a step of the run
    if short or rate > hi:
        raise ConfigError(rate_source, "outputs.trajectory_rate", rate, f"allowed range [{lo:.4g}, {hi:.4g}] Hz: at least one "
                          f"frame in duration = {duration:g} s, at most {MAX_FRAMES:.0e} frames and {min(MAX_RATE, 0.5 / dt):.4g} Hz")


def running_dt(preset, plate_omega: float, jar_spin: float, fixed: float | None = None) -> float:
    """The time step (s) of a running mill of `preset` at speeds up to Ω, w (rad/s): the
    automatic one, or a preset's explicit dt `fixed` where that is still below it (a
    speed change must not leave too few steps per contact)."""
    v = max_impact_speed(plate_omega, jar_spin, preset.plate_radius, preset.jar, preset.gravity)
    dt = auto_dt(preset.ball_ball, preset.ball_wall, preset.frictions, preset.balls, v)
    return dt if fixed is None else min(fixed, dt)


# ------------------------------------------------------------------ plausibility
BALL_SIZE_FACTOR = 10.0  #: a ball this many times larger or smaller than its contact set's is far outside it


def plate_fits_jar(source, plate_radius: float, jar):
    """The jar's axis is carried at R_p (m) from the plate's: a plate radius below the
    jar's own (a slip of units, 0.07 for 70 mm) puts the plate's axis inside the jar."""
    if plate_radius <= jar.radius:
        r = RANGES["plate_radius_mm"]
        raise ConfigError(source, "plate_radius_mm", plate_radius * 1e3,
                          f"allowed range ({jar.radius * 1e3:.4g}, {r.hi:g}] {r.unit}: the jar's axis must lie outside "
                          f"the jar {jar.name} (radius {jar.radius * 1e3:.4g} mm)")


def ball_fits_jar(source, key: str, size: float, radius: float, jar):
    """Balls of `radius` (m) fit in `jar`: their diameter at most the jar's (bounding)
    radius and below its height (a ball as tall as the jar would touch floor and lid at
    once), and their radius at most the fillet of its corners (ball_fits_corners).
    key, size: the balls' size as given (balls.radius_mm or balls.diameter_mm, mm)."""
    per_m = 1e3 if key.endswith("diameter_mm") else 0.5e3  # the largest size in mm, per m of min(R, H)
    largest = per_m * min(jar.radius, jar.height)
    if not (size <= largest and 2 * radius < jar.height):
        raise ConfigError(source, key, size, f"allowed range (0, {largest:g}{')' if jar.height <= jar.radius else ']'} mm: "
                          f"balls must fit in the jar {jar.name} (radius {jar.radius * 1e3:.4g} mm, height "
                          f"{jar.height * 1e3:.4g} mm)")
    if not ball_fits_corners(radius, jar):
        raise ConfigError(source, key, size, f"allowed range (0, {per_m * 2 * jar.fillet:g}] mm: jar {jar.name}'s "
                          f"corners are rounded to {jar.fillet * 1e3:g} mm")


def ball_fits_corners(radius: float, jar) -> bool:
    """A ball of `radius` (m) touches each corner of the jar's profile at one point: the
    corners' fillet is at least its radius (a plain circle has no corner). A larger ball
    would touch both walls of a corner while the side wall's distance names only the
    nearer one."""
    return len(jar.profile.pieces) == 1 or radius <= jar.fillet


def ball_size_note(radius: float, measured: float | None, contact: str) -> str | None:
    """A line if the balls' radius (m) is more than BALL_SIZE_FACTOR times off the radius
    `measured` (m) its contact set was measured or fitted for: its stiffness follows the
    radius, but its damping and full-damping depth were fitted at the measured size (a
    unit slip, 0.006 for 6 mm, also lands here). None: plausible, or no measured size."""
    if not measured or 1.0 / BALL_SIZE_FACTOR <= radius / measured <= BALL_SIZE_FACTOR:
        return None
    return (f"balls of radius {radius * 1e3:.4g} mm are {max(radius / measured, measured / radius):.3g} times "
            f"{'smaller' if radius < measured else 'larger'} than the {measured * 1e3:.4g} mm balls contact set "
            f"'{contact}' was measured for; its damping may not hold at this size (radius_mm is in mm)")


#: where the analysis window of a run shortened on the command line starts when the
#: preset's start no longer fits: this fraction of the run, the thesis' 4 of 24 s
SHORT_RUN_START = 1.0 / 6.0


def analysis_window(file_start: float, file_duration: float | None, duration: float, ramp_time: float, *,
                    start_given: bool, duration_given: bool) -> tuple[float, str | None]:
    """The analysis window's start (s) and a warning line or None: the one rule, applied
    by load_preset for every command that simulates (run, sweep, record, export).

    - analysis_start as the preset file or --analysis-start gives it, when either was
      given on the command line with --duration, or the run is not shortened;
    - a --duration shorter than the preset's keeps the preset's analysis_start when it
      lies below it (--duration 6 of a preset analysing 4 … 24 s: 4 … 6 s);
    - else the window starts at SHORT_RUN_START of the run (--duration 0.9: 0.15 … 0.9 s).
    The line says so whenever --duration shortened the preset's window, and when the
    window begins inside the start-up ramp (start_up_note), in one line.
    file_start, file_duration: the preset's (file_start the command line's when
    start_given); duration, ramp_time: the run's (s)."""
    if start_given or not duration_given or file_duration is None or duration >= file_duration:
        return file_start, start_up_note(file_start, duration, ramp_time)
    if file_start < duration:
        start, how = file_start, f"keeps the preset's analysis_start = {file_start:g} s"
    else:
        start = duration * SHORT_RUN_START
        how = f"ends before the preset's analysis_start = {file_start:g} s, so the window starts at duration/6"
    line = (f"--duration {duration:g} s is shorter than the preset's {file_duration:g} s and {how}: the analysis "
            f"window is {start:.4g} … {duration:g} s (the preset's {file_start:g} … {file_duration:g} s); "
            f"--analysis-start sets its start")
    ramp = start_up_note(start, duration, ramp_time)
    return start, line + (f"; {ramp}" if ramp else "")


def start_up_note(analysis_start: float, duration: float, ramp_time: float) -> str | None:
    """A line if the analysis window (analysis_start … duration, s) begins inside the
    start-up ramp (0 … ramp_time, s), where the speeds still rise: its figures would mix
    start-up and milling. None: the window starts at or after the ramp's end."""
    if analysis_start >= ramp_time:
        return None
    if duration <= ramp_time:
        return (f"the whole run ({duration:g} s) lies inside the {ramp_time:g} s start-up ramp: the mill never "
                f"reaches its speeds; give a duration above {ramp_time:g} s and analysis_start ≥ {ramp_time:g} s "
                f"(--duration, --analysis-start) or a shorter ramp_time")
    return (f"the analysis window starts at {analysis_start:g} s, inside the {ramp_time:g} s start-up ramp: "
            f"its figures mix start-up and milling; give analysis_start ≥ {ramp_time:g} s (--analysis-start) "
            f"or a shorter ramp_time")


# ---------------------------------------------------------------- what a run stores of its events
EVENT_OUTPUTS = ("rows", "spectra")
# balls: above this many a run stores the events' energy spectra, not one row per event
# (outputs.events in a preset chooses either way). A settled bed's ball opens and closes
# contacts all the time: one row is 136 bytes (17 columns of 8), and a bed of 10⁴ balls
# closes some 10⁶ contacts per simulated second (scripts/bench.py dense bed): 136 MB/s of
# rows nobody reads one by one, where the spectra are 36 kB whatever the mill.
EVENT_ROWS_UP_TO = 10_000


def events_output(balls: int) -> str:
    """The default of outputs.events for a mill of `balls` balls."""
    return "rows" if balls <= EVENT_ROWS_UP_TO else "spectra"


# ---------------------------------------------------------------- softened contacts
SOFTENING_MAX = 1e4  #: a Hertz contact 40× longer: beyond, overlaps reach a good part of a ball


def softening_note(factor: float) -> str:
    """The line a run with softened contacts prints (docs/softening.md)."""
    return (f"contacts softened: stiffness ÷ {factor:g}, damping recalibrated to keep each contact's restitution; "
            f"a Hertz contact lasts {factor ** 0.4:.3g}× longer and the time step grows with it; "
            "docs/softening.md shows which outputs move with the factor")
