"""What a run emits, declared once: the columns of the three tables of the stream
(frames, collision events, energy ledger) and the rows of the run summary, each with
its dtype, unit and meaning. The kernel's event record, the sinks, the zarr store,
the readers and the printed tables are all built from these declarations, so a new
column is one line here (plus, for a kernel column, the value the kernel writes).

NumPy-free and Taichi-free: every layer may import it.
"""

from __future__ import annotations

# ---------------------------------------------------------------- stream tables
# name -> (dtype, unit, meaning); per-ball columns have rows of shape (n_balls, 3).
FRAME_COLUMNS: dict[str, tuple[str, str, str]] = {
    "time": ("f8", "s", "simulated time"),
    "position": ("f8", "m", "ball centres, jar frame"),
    "velocity": ("f8", "m/s", "ball velocities, jar frame"),
    "spin": ("f8", "rad/s", "absolute spin, jar-frame components"),
    "plate_angle": ("f8", "rad", "angle φ_p of the plate (of the jar's centre about the plate axis)"),
    "plate_speed": ("f8", "rad/s", "plate speed Ω"),
    "jar_angle": ("f8", "rad", "absolute angle φ_j of the jar frame (ψ = φ_p − φ_j points away from the plate axis)"),
    "jar_spin": ("f8", "rad/s", "absolute spin w of the jar frame"),
}
FRAME_FIELDS = tuple(FRAME_COLUMNS)
PER_BALL = frozenset(("position", "velocity", "spin"))
DRIVE_FIELDS = ("plate_angle", "plate_speed", "jar_angle", "jar_spin")  #: per-frame drive columns
VELOCITY_CONVENTION = ("velocity: of the ball centre relative to the rotating jar frame (v = u − w ẑ×x with u "
                       "the velocity in the non-rotating jar-centred frame), jar-frame components; spin: absolute "
                       "angular velocity, jar-frame components; position: jar frame, origin on the jar axis at "
                       "the floor; the jar frame's angle and spin are stored per frame")

# name -> (dtype, unit, meaning)
EVENT_COLUMNS: dict[str, tuple[str, str, str]] = {
    "t_start": ("f8", "s", "time of first touch"),
    "duration": ("f8", "s", "first touch to separation"),
    "body_i": ("i4", "-", "ball index (the lower index for ball-ball)"),
    "body_j": ("i4", "-", "partner ball index, or -1 side wall, -2 floor, -3 lid"),
    "kind": ("i1", "-", "0 ball-ball, 1 ball-wall"),
    "x": ("f8", "m", "contact point at onset, jar frame"),
    "y": ("f8", "m", "contact point at onset, jar frame"),
    "z": ("f8", "m", "contact point at onset, jar frame"),
    "un": ("f8", "m/s", "onset normal approach speed (>= 0, or a rounding error below 0 for a grazing contact)"),
    "ut": ("f8", "m/s", "onset slip speed at the contact point, spin included"),
    "m_eff": ("f8", "kg", "effective mass m_i m_j/(m_i+m_j); m_ball for walls"),
    "se_n": ("f8", "J", "normal stress energy 1/2 m_eff un^2"),
    "se_t": ("f8", "J", "tangential stress energy 1/2 m_eff ut^2"),
    "peak_force": ("f8", "N", "largest normal force during the event"),
    "peak_penetration": ("f8", "m", "largest overlap during the event"),
    "dissipated_normal": ("f8", "J", "work of the normal damper (and of the F>=0 clamp)"),
    "dissipated_friction": ("f8", "J", "friction work"),
}

ENERGY_COLUMNS: dict[str, tuple[str, str, str]] = {
    "time": ("f8", "s", "simulated time"),
    "kinetic": ("f8", "J", "ground-frame kinetic energy, translation + rotation"),
    "potential": ("f8", "J", "gravitational energy m g z"),
    "elastic": ("f8", "J", "energy stored in the contact springs"),
    "drive_work": ("f8", "J", "work done by the jar walls on the balls since t = 0"),
    "dissipated": ("f8", "J", "energy dissipated by all contacts since t = 0"),
}

# Where the dissipation happens: by contact kind, by class of contact and by part of the
# contact law. A contact is an *impact* while its onset normal speed is at least the
# stress-event threshold and it is younger than the impact age (model/mechanisms.py);
# otherwise it is *persistent* (rolling, sliding, resting). The parts sum to `dissipated`.
MECHANISM_KINDS = ("ball_ball", "side", "floor", "lid")
MECHANISM_CLASSES = ("impact", "persistent")
MECHANISM_PARTS = ("normal", "friction")
MECHANISM_COLUMNS = tuple(f"dissipated_{k}_{c}_{p}" for k in MECHANISM_KINDS for c in MECHANISM_CLASSES
                          for p in MECHANISM_PARTS)
ENERGY_COLUMNS.update({
    name: ("f8", "J", f"part of `dissipated`: {p} work in {c} contacts with the {k.replace('_', '-')}"
           if k != "ball_ball" else f"part of `dissipated`: {p} work in {c} ball-ball contacts")
    for name, (k, c, p) in zip(MECHANISM_COLUMNS, ((k, c, p) for k in MECHANISM_KINDS for c in MECHANISM_CLASSES
                                                   for p in MECHANISM_PARTS))})

# Event columns the host derives from the kernel's columns after each launch (the
# kernel does not write them): name -> function of the other columns (arrays).
DERIVED_EVENT_COLUMNS = {
    "se_n": lambda c: 0.5 * c["m_eff"] * c["un"] ** 2,
    "se_t": lambda c: 0.5 * c["m_eff"] * c["ut"] ** 2,
}

# ---------------------------------------------------------------- run summary
# Summary entries that describe the machine, not the run: equal runs on other machines,
# thread counts or backends differ in these alone (`compute`: physics.ti.compute).
MACHINE_KEYS = ("wall_seconds", "realtime_factor", "compute")
# The regime split as the regime map splits it (taimill.analysis.regime.MAP_REGIMES,
# the summary's `regime_class`), repeated here so that this module imports nothing.
REGIME_CLASSES = ("cascading", "cataracting", "hopping bed", "pinned ring", "sliding bed", "rolling bed")
# A label with "{stations}" is filled with the summary's `stations` (the whole mill's rows).
# (key in the summary, label, unit, scale)
SUMMARY_ROWS = (
    ("sim_seconds", "simulated time", "s", 1),
    ("wall_seconds", "wall time, set-up and compiling left out", "s", 1),
    ("realtime_factor", "simulated s per wall s, compiling left out", "", 1),
    ("dt", "time step", "µs", 1e6),
    ("events", "stress events in window", "", 1),
    ("events_ball_ball", "  ball-ball", "", 1),
    ("events_ball_wall", "  ball-wall", "", 1),
    ("collision_rate", "stress-event rate", "1/s", 1),
    ("impact_power", "impact power E_I/τ (eq 3.8), one jar", "W", 1),
    ("impact_power_normal", "  normal", "W", 1),
    ("impact_power_tangential", "  tangential", "W", 1),
    ("impact_power_mill", "impact power, whole mill ({stations})", "W", 1),
    ("mean_se", "mean stress energy", "mJ", 1e3),
    ("mean_se_normal", "  normal", "mJ", 1e3),
    ("mean_se_tangential", "  tangential", "mJ", 1e3),
    ("normal_fraction", "normal / total SE", "", 1),
    ("dissipated_power", "dissipated power, one jar", "W", 1),
    ("friction_share", "  friction's share of it", "", 1),
    ("dissipated_power_impact", "  in impacts", "W", 1),
    ("dissipated_power_persistent", "  in persistent contacts", "W", 1),
    ("dissipated_power_friction", "  by friction", "W", 1),
    ("dissipated_power_mill", "dissipated power, whole mill ({stations})", "W", 1),
    ("specific_power_W_per_g", "dissipated power per g of powder", "W/g", 1),
    ("specific_power_impact_W_per_g", "  of it in impacts", "W/g", 1),
    ("shear_power_persistent_wall_W_per_m2", "persistent friction on the wall (shear view)", "W/m²", 1),
    ("energy_balance_error", "energy balance error", "%", 100),
    ("randomness_index", "randomness index 1/σ", "", 1),
    ("regime", "motion regime (the thesis' three, jar frame)", "", None),
    ("regime_confidence", "  confidence (share of 1 s pieces)", "", 1),
    ("regime_class", "  class (6, the plate frame too)", "", None),
    ("wall_lag", "  wall lag (0: turns with jar, 1: rests on plate)", "", 1),
    ("slip_ratio", "  wall slip ratio", "", 1),
    ("critical_ratio", "critical ratio K_c (one ball)", "", 1),
    ("single_ball_se", "one-ball hit energy (Burgio-type)", "mJ", 1e3),
)

# ---------------------------------------------------------------- units of the JSON outputs
# The unit of every number in a summary object (`taimill run --json`, the rows of
# `taimill sweep --json`, `taimill analyse --json`, a store's `summary` attribute):
# key -> unit, "1" for counts, ratios and fractions (0 … 1, not %). A key has the same
# unit wherever it appears, also inside nested objects (`all_contacts`, the estimators of
# `analyse`, `main_sink`, `wear_hot_spot`, …); an object whose entries all share one unit
# is listed under its own name (`dissipation_by_mechanism`: W). JSON values are SI except
# rpm (speeds as the presets give them) and deg (angles named `…_deg`).
_EVENT_UNITS = {"impact_power": "W", "impact_power_normal": "W", "impact_power_tangential": "W",
                "mean_se": "J", "mean_se_normal": "J", "mean_se_tangential": "J", "normal_fraction": "1",
                "events": "1", "points": "1"}
SUMMARY_UNITS: dict[str, str] = {
    **_EVENT_UNITS,
    **{f"{k}_{kind}": u for k, u in _EVENT_UNITS.items() for kind in ("ball_ball", "ball_wall")},
    "min_un": "m/s", "events_below_threshold": "1", "events_total": "1", "samples": "1",
    "collision_rate": "1/s", "collision_rate_per_ball": "1/s",
    "impact_power_density": "W/m³", "mean_se_density": "J/m³",
    "dissipated_power": "W", "drive_work": "J",
    "energy_balance_error": "1", "energy_balance_worst": "1",
    "stations": "1", "impact_power_mill": "W", "dissipated_power_mill": "W",  # the whole mill: stations × one jar
    "dissipation_by_mechanism": "W",
    **{f"dissipated_power_{k}": "W" for k in (*MECHANISM_CLASSES, *MECHANISM_PARTS, *MECHANISM_KINDS)},
    "power": "W", "share": "1",  # main_sink
    "randomness_index": "1", "regime_confidence": "1", "side_wall_fraction": "1",
    "wall_fraction": "1", "flight_fraction": "1", "flight_chord": "1", "wall_lag": "1", "impact_chord": "1",  # regime_criteria
    "friction_share": "1",  # of the dissipated power (power_led)
    "regime_thresholds": "1",
    "power_per_area": "W/m²", "concentration": "1", "arc_length": "m", "angle_deg": "deg",
    "x": "m", "y": "m", "z": "m", "z_range": "m", "r_range": "m", "over_band": "1", "band_sigmas": "1",
    "sampled_share": "1",  # wear_hot_spot
    "critical_ratio": "1", "single_ball_se": "J",
    "analysis_window": "s", "sim_seconds": "s", "wall_seconds": "s", "realtime_factor": "1", "dt": "s",
    "compute": "1",  # backend and device names, a thread count (physics.ti.compute)
    "steps": "1", "ratio": "1", "plate_rpm": "rpm",
    # taimill analyse
    "r_edges": "m", "g": "1", "wall_energy": "J",
    "se": "J", "se_n": "J", "se_t": "J", "un": "m/s", "ut": "m/s", "detach_angle_deg": "deg",
    "flight_time": "s",  # single_ball_hit
    # a TUI recording: its span and the live changes made while it ran
    "recorded": "s", "time": "s", "jar_rpm": "rpm", "ramp_time": "s", "mu_s": "1", "mu_d": "1", "mu_r": "1",
    # taimill sweep rows: the point and its swept values
    "point": "1", "balls": "1", "seed": "1", "replica": "1", "batch": "1", "duration": "s",
    "plate_radius": "m", "jar_radius": "m", "ball_radius": "m", "regime_fractions": "1", "replicas": "1",
    "mu": "1", "mu_wall": "1", "mu_d_wall": "1", "mu_r_wall": "1", "ball_mass": "kg", "ball_diameter_mm": "mm", "plate_radius_mm": "mm",
    **{f"dissipated_power_{k}_{c}_{p}": "W" for k in MECHANISM_KINDS for c in MECHANISM_CLASSES for p in MECHANISM_PARTS},
    "slip_ratio": "1",  # taimill.analysis.regime.slip_ratio (regime maps)
    # the energy spectra's summary (taimill.analysis.spectra.summary; rate_above: events/s
    # at or above each energy, keyed by the energy in J) and their sweep columns
    "softening": "1",  # contact stiffness divided by it (a softened run)
    # the dose (taimill.outcome.dose): the jar's powder, the dissipated power per gram, the shear view
    "powder_mass_g": "g", "ball_to_powder": "1", "rate_above_per_g": "1/(s g)",
    **{f"specific_power{s}_W_per_g": "W/g" for s in ("", "_impact", "_persistent", "_normal", "_shear")},
    "shear_power_persistent_W": "W", "shear_share": "1", "shear_power_persistent_wall_W_per_m2": "W/m²",
    # wear per unit wear coefficient (taimill.outcome.wear.wear_keys; docs/wear.md)
    "wear_friction_g_per_h_per_k": "g/h", "wear_impact_g_per_h_per_k": "g/h",
    "contamination_friction_per_h_per_k": "1/h",
    "window": "s", "stress_un": "m/s", "energy": "J", "mean": "J", "median": "J", "p90": "J", "rate_above": "1/s",
    **{f"spectrum_{m}_{stat}": "J" for m in ("dissipated_normal", "dissipated_friction", "se_normal", "se_tangential")
       for stat in ("mean", "median", "p90")},
}


def units_of(obj) -> dict[str, str]:
    """SUMMARY_UNITS restricted to the keys found in `obj` (a summary: nested objects and
    lists of objects searched too; an object listed by name is not searched further)."""
    found: dict[str, str] = {}

    def walk(v):
        if isinstance(v, dict):
            for k, x in v.items():
                if k in SUMMARY_UNITS:
                    found[k] = SUMMARY_UNITS[k]
                if k not in SUMMARY_UNITS or not isinstance(x, dict):
                    walk(x)
        elif isinstance(v, (list, tuple)):
            for x in v:
                walk(x)

    walk(obj)
    return dict(sorted(found.items()))


def with_units(summary: dict) -> dict:
    """The summary with its `units` table (units_of) as its last key."""
    return {k: v for k, v in summary.items() if k != "units"} | {"units": units_of(summary)}
