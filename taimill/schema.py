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
    "un": ("f8", "m/s", "onset normal approach speed (>= 0)"),
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
# (key in the summary, label, unit, scale)
SUMMARY_ROWS = (
    ("sim_seconds", "simulated time", "s", 1),
    ("wall_seconds", "wall time", "s", 1),
    ("realtime_factor", "simulated s per wall s", "", 1),
    ("dt", "time step", "µs", 1e6),
    ("events", "stress events in window", "", 1),
    ("events_ball_ball", "  ball-ball", "", 1),
    ("events_ball_wall", "  ball-wall", "", 1),
    ("collision_rate", "stress-event rate", "1/s", 1),
    ("impact_power", "impact power E_I/τ (eq 3.8)", "W", 1),
    ("impact_power_normal", "  normal", "W", 1),
    ("impact_power_tangential", "  tangential", "W", 1),
    ("mean_se", "mean stress energy", "mJ", 1e3),
    ("mean_se_normal", "  normal", "mJ", 1e3),
    ("mean_se_tangential", "  tangential", "mJ", 1e3),
    ("normal_fraction", "normal / total SE", "", 1),
    ("dissipated_power", "dissipated power", "W", 1),
    ("dissipated_power_impact", "  in impacts", "W", 1),
    ("dissipated_power_persistent", "  in persistent contacts", "W", 1),
    ("dissipated_power_friction", "  by friction", "W", 1),
    ("energy_balance_error", "energy balance error", "%", 100),
    ("randomness_index", "randomness index 1/σ", "", 1),
    ("regime", "motion regime", "", None),
    ("regime_confidence", "  confidence (share of 1 s pieces)", "", 1),
    ("critical_ratio", "critical ratio K_c (one ball)", "", 1),
    ("single_ball_se", "one-ball hit energy (Burgio-type)", "mJ", 1e3),
)
