"""A preset as a ready-to-run LIGGGHTS-PUBLIC 3.8 case (docs/liggghts.md).

`export_case(preset, DIR)` writes

    jar.stl          the jar (jar frame, m) as a closed surface, facets within 10 µm of the profile
    start.data       the balls at t = 0 in the ground frame (read_data, atom style granular)
    in.taimill       the input deck: materials, contact models, gravity, the planetary
                     motion as two superposed `fix move/mesh rotate/variable` with
                     taimill's start-up ramp, dumps at the preset's trajectory rate
    run.sh           `./run.sh P` runs it on P MPI processes (mpirun -np P liggghts -in in.taimill)
    taimill-case.json the resolved preset, the mapping and what the import needs

How each part of taimill's model is expressed (or refused) is decided here, in
`contact_mapping` and `motion`, and documented in docs/liggghts.md.

The planetary motion. In the ground frame the jar's centre is at R_p (cos φ_p, sin φ_p, 0)
and the jar frame has turned by φ_j. LIGGGHTS moves the mesh with two superposed movers:
the first turns it about the plate axis at Ω(t); the second turns it about the jar axis
at ω(t) = w(t) − Ω(t), and its origin (given at (R_p, 0, 0)) is carried along by the
first (LIGGGHTS: "the reference frame for the second move command moves along as the
mesh is moved by the first"). The mesh then sits at angle φ_p + (φ_j − φ_p) = φ_j with
its centre at φ_p, and each mover adds its own ω × r to the node velocities, which sum
to the jar centre's velocity plus w ẑ × (x − c): the wall speed taimill uses. Both ramps
are taimill's smoothstep, so ω(t) = (w − Ω)·step(t/T) exactly; a mover turns the mesh by
ω dt per step with ω evaluated at the middle of the step (a midpoint rule: the angle
is within O(dt²) of taimill's closed form, tests/test_liggghts.py measures it).
"""

from __future__ import annotations

import functools
import json
import math
import shlex
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from taimill.bridge.mesh import TOLERANCE, JarMesh, jar_mesh, write_stl
from taimill.errors import ConfigError
from taimill.model import laws as laws_np
from taimill.model.contact.damping import damping_ratio
from taimill.model.contact import rolling, rolling_epsd2, tangential, tangential_history
from taimill.model.contact.registry import ROLLING, TANGENTIAL, law_by_name
from taimill.model.materials import load_material
from taimill.model.preset import Preset
from taimill.model.rules import max_impact_speed
from taimill.model.spec import from_preset
from taimill.store.run import plain

FORMAT = "taimill-liggghts-case"
VERSION = 1
MANIFEST = "taimill-case.json"
DECK = "in.taimill"
DUMP = "dumps/balls.dump"
MESH_DUMP = "dumps/jar_*.stl"
BALL_TYPE, WALL_TYPE = 1, 2
DUMP_COLUMNS = ("id", "type", "x", "y", "z", "vx", "vy", "vz", "omegax", "omegay", "omegaz", "radius", "mass")
# LIGGGHTS' own advice for its check/timestep/gran: dt below these fractions of the
# Rayleigh and Hertz times.
RAYLEIGH_FRACTION, HERTZ_FRACTION = 0.2, 0.2


def is_case(path) -> bool:
    """True if `path` is a case `export_case` wrote: a folder with its manifest (what
    `export liggghts --overwrite` may replace; LIGGGHTS' dumps in it go with it)."""
    try:
        return json.loads((Path(path) / MANIFEST).read_text()).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        return False


@dataclass
class Mapping:
    """How taimill's contact model is expressed in LIGGGHTS, with what could not be."""

    normal: str  #: LIGGGHTS normal model (`hertz` or `hooke/stiffness`)
    tangential: str  #: LIGGGHTS tangential model of ball-ball contacts (tangential_models has both kinds)
    #: "ball_ball"/"ball_wall" -> LIGGGHTS tangential model
    tangential_models: dict = field(default_factory=dict)
    #: "ball_ball"/"ball_wall" -> the LIGGGHTS settings its tangential model needs (e.g. ["tangential_damping off"])
    tangential_settings: dict = field(default_factory=dict)
    #: "ball_ball"/"ball_wall" -> LIGGGHTS rolling_friction model (cdt, epsd2); absent: no rolling resistance
    rolling_models: dict = field(default_factory=dict)
    restitution: dict = field(default_factory=dict)  #: "ball_ball"/"ball_wall" -> LIGGGHTS input e
    stiffness: dict = field(default_factory=dict)  #: hooke/stiffness only: kn, gamman per contact type
    friction: dict = field(default_factory=dict)  #: "ball_ball"/"ball_wall" -> LIGGGHTS coefficientFriction
    rolling: dict = field(default_factory=dict)  #: "ball_ball"/"ball_wall" -> coefficientRollingFriction; {}: off
    notes: list = field(default_factory=list)  #: exact correspondences, one line each
    warnings: list = field(default_factory=list)  #: approximations, one line each


def _liggghts_restitution(c_tsuji: float) -> float:
    """LIGGGHTS' `hertz` damping is γ_n = 2√(5/6) β √(S_n m*), β = −ln e/√(ln² e + π²):
    taimill's hertz-mindlin with c = 2√(5/6) β. The e LIGGGHTS must be given for a
    damping c (it differs from the restitution the clamped law then gives)."""
    beta = c_tsuji / (2.0 * math.sqrt(5.0 / 6.0))
    if not 0.0 < beta < 1.0:
        raise ValueError(f"damping {c_tsuji} has no restitution form")
    return math.exp(-math.pi * beta / math.sqrt(1.0 - beta * beta))


@functools.lru_cache(maxsize=64)
def _hertz_input_e(e_target: float) -> float:
    """LIGGGHTS input e for which its clamped Hertz contact (limitForce on) rebounds
    with e_target. The clamped Tsuji law is scale-free, so this is one function of e:
    bisection on simulated unit impacts (k = m = u = 1) over the input e."""
    mindlin = law_by_name("hertz-mindlin")
    lo, hi = (0.05 if e_target > 0.22 else 1e-3), 0.999  # input 0.05 gives 0.21 (near e = 0 impacts end slowly)
    for _ in range(5):
        grid = np.linspace(lo, hi, 17)
        c = [2.0 * math.sqrt(5.0 / 6.0) * damping_ratio(e) for e in grid]
        got = laws_np.simulate_impact(mindlin, 1.0, c, 1.0, 1.0, 1.0, steps=600)["e"]
        i = int(np.argmax(got >= e_target)) if (got >= e_target).any() else len(grid) - 1
        lo, hi = grid[max(i - 1, 0)], grid[i]
    return float(0.5 * (lo + hi))


def _restitution_at(law, speeds) -> np.ndarray:
    """Restitution of a taimill contact at impact speeds (m/s), F ≥ 0 clamp included."""
    return laws_np.simulate_impact(law.model, law.k, law.c, law.d, law.m_eff, np.asarray(speeds))["e"]


def contact_mapping(preset: Preset, *, strict: bool = False) -> Mapping:
    """The LIGGGHTS contact models of a preset; ConfigError for what has no equivalent
    (with `strict`, also for what would only be approximated)."""
    bb, bw = preset.ball_ball, preset.ball_wall
    law = bb.law
    mu_r, rolling_models, r_notes, r_warnings = _rolling(preset, strict)  # its refusals first, as before
    mu, models, settings, notes, warnings = _tangential(preset, strict)
    m = Mapping(normal="hertz", tangential=models["ball_ball"], tangential_models=models,
                tangential_settings=settings, friction=mu, rolling=mu_r, rolling_models=rolling_models,
                notes=notes + r_notes, warnings=warnings + r_warnings)
    if law == "hertz-mindlin":
        for name, c in (("ball_ball", bb), ("ball_wall", bw)):
            m.restitution[name] = _liggghts_restitution(c.c)
        m.notes.append(
            "normal: hertz-mindlin = LIGGGHTS `model hertz` with limitForce on (same k = 4/3 E* √R*, same "
            "damping 2√(5/6) β √(S_n m*)); LIGGGHTS' input e is the one whose β gives taimill's calibrated "
            f"damping: ball-ball {m.restitution['ball_ball']:.4f}, ball-wall {m.restitution['ball_wall']:.4f} "
            f"(both rebound with e = {bb.e:g} once the force is clamped at 0)")
    elif law == "kelvin-voigt":
        m.normal = "hooke/stiffness"
        m.stiffness = {"ball_ball": (bb.k, bb.c), "ball_wall": (bw.k, bw.c)}
        m.notes.append(
            "normal: kelvin-voigt = LIGGGHTS `model hooke/stiffness` with absolute_damping on and limitForce on "
            f"(kn = {bb.k:.4g} / {bw.k:.4g} N/m, gamman = {bb.c:.4g} / {bw.c:.4g} N·s/m ball-ball / ball-wall); "
            "its tangential spring kt = 2/7 kn, tangential damping off")
        mindlin = [(k, f.tangential) for k, f in zip(("ball_ball", "ball_wall"), preset.frictions)
                   if TANGENTIAL_EXPORT[f.tangential].mindlin]
        if mindlin:  # LIGGGHTS' hooke/stiffness spring is the constant kt above, taimill's Mindlin's
            kind, name = mindlin[0]
            text = (f"tangential = {name} with kelvin-voigt: taimill's tangential spring is Mindlin's "
                    "k_t = 8 G* √(R* u) whatever the normal law, LIGGGHTS' `hooke/stiffness` one is the constant kt "
                    "= 2/7 kn; the same cap μ_d |F_n|")
            if strict:
                raise ConfigError(preset.source, _key(preset, kind, "tangential"), name,
                                  text + "; use law = \"hertz-mindlin\", or export without --strict to map it")
            m.warnings.append(text)
    else:
        speeds = np.array([0.5, 2.0, 6.0])
        e_bb = _restitution_at(bb, [bb.u_ref])[0]
        e_bw = _restitution_at(bw, [bw.u_ref])[0]
        spread = _restitution_at(bw, speeds)
        text = (f"{law} has no LIGGGHTS equivalent (its restitution depends on the impact speed: ball-wall e = "
                + ", ".join(f"{e:.3f}" for e in spread) + " at " + ", ".join(f"{v:g}" for v in speeds) + " m/s)")
        if strict:
            raise ConfigError(preset.source, "law", law,
                              f"{text}; use law = \"hertz-mindlin\" (constant restitution), or export without "
                              "--strict to map it")
        m.restitution = {"ball_ball": _hertz_input_e(round(float(e_bb), 4)), "ball_wall": _hertz_input_e(round(float(e_bw), 4))}
        m.warnings.append(
            f"normal: {text}; mapped to LIGGGHTS `model hertz` (same Hertz stiffness) with the constant "
            f"restitution it has at u_ref = {bb.u_ref:g} m/s: ball-ball {e_bb:.3f}, ball-wall {e_bw:.3f}")
    return m


# Each taimill tangential / rolling sub-model (by its registry name) and how the export
# writes it: LIGGGHTS' pair_style sets the models of ball-ball contacts and the wall fix
# its own, so each contact kind is written with its own sub-models (the installed 3.8
# accepts different ones in the two commands).


@dataclass(frozen=True)
class TangentialExport:
    """How one tangential sub-model is written for LIGGGHTS."""

    keyword: str  #: LIGGGHTS `tangential` model
    settings: tuple  #: settings it needs after the model (none: LIGGGHTS' defaults)
    stiction: bool  #: reads μ_s, which one Coulomb coefficient cannot express when μ_s > μ_d
    note: str  #: the mapping line; {mu} is μ_d (-), {v_s} v_s (mm/s)
    mindlin: bool = False  #: taimill's spring is Mindlin's k_t: exact only under LIGGGHTS' `model hertz`


@dataclass(frozen=True)
class RollingExport:
    """How one rolling sub-model is written for LIGGGHTS: `exact` (a note), `approximate`
    (a warning; refused with --strict) or `refused` per contact kind."""

    keyword: str  #: LIGGGHTS `rolling_friction` model
    ball_ball: str  #: exact | approximate
    ball_wall: str  #: approximate | refused
    text: dict  #: kind -> the mapping line (or the refusal); {mu_r} is μ_r (-)


TANGENTIAL_EXPORT = {
    tangential.REGULARISED_COULOMB.name: TangentialExport(
        "history", (), True,
        "Coulomb μ = {mu:g} (LIGGGHTS `tangential history`: a tangential spring capped at μ F_n; taimill's "
        "regularisation below v_s = {v_s:g} mm/s has no counterpart, the sliding force is the same)"),
    tangential_history.HISTORY.name: TangentialExport(
        "history", ("tangential_damping off",), False,
        "tangential = history, μ_d = {mu:g}: LIGGGHTS `tangential history` with `tangential_damping off` and "
        "coefficientFriction μ_d, exact (the same spring k_t = 8 G* √(R* δ) on the same projected history, capped "
        "at μ_d |F_n|; μ_s, v_s and v_d are not read by this model)", mindlin=True),
}
ROLLING_EXPORT = {
    rolling.CONSTANT_TORQUE.name: RollingExport("cdt", "approximate", "refused", {
        "ball_ball": "μ_r = {mu_r:g} as LIGGGHTS `rolling_friction cdt` (the same torque μ_r R* F_n against "
                     "ω_i − ω_j), except that LIGGGHTS takes F_n without its damping part and has no cap: near "
                     "ω_r = 0 its torque flips sign every step where taimill's settles the rolling",
        "ball_wall": "ball-wall rolling resistance has no LIGGGHTS equivalent in a turning jar (its wall contacts "
                     "brake the ball's ground-frame spin, taimill's the spin relative to the wall); set it to 0 to "
                     "export, or use rolling = \"epsd2\""}),
    rolling_epsd2.EPSD2.name: RollingExport("epsd2", "exact", "approximate", {
        "ball_ball": "rolling = epsd2, μ_r = {mu_r:g}: LIGGGHTS `rolling_friction epsd2` with "
                     "coefficientRollingFriction μ_r, exact (the same spring k_r = k_t R*² on ω_i − ω_j "
                     "projected on the tangent plane, capped at μ_r R* |F_n|, no dashpot)",
        "ball_wall": "rolling = epsd2, μ_r = {mu_r:g}: LIGGGHTS `rolling_friction epsd2` on the wall fix, the same "
                     "spring and cap, except the spin it loads: LIGGGHTS' wall contacts take the ball's ground-frame "
                     "spin (a mesh has no spin of its own), taimill's the spin relative to the jar wall, which turns "
                     "with the jar; a ball carried round by the wall at the jar's spin loads LIGGGHTS' spring until it "
                     "slips at μ_r R |F_n| and taimill's not at all"}),
}


def _key(preset: Preset, kind: str, name: str) -> str:
    """The preset key a refusal names: friction.NAME, or friction_KIND.NAME when the
    contact kinds have their own friction."""
    return f"friction.{name}" if preset.wall_friction is None else f"friction_{kind}.{name}"


def _tangential(preset: Preset, strict: bool) -> tuple[dict, dict, dict, list, list]:
    """(μ, LIGGGHTS model, its settings; each per kind, notes, warnings) of the
    tangential sub-models (TANGENTIAL_EXPORT):
    LIGGGHTS' `coefficientFriction` is a per-type-pair property and the wall is its own
    atom type, so a coated jar (`pair_ball_wall`) maps exactly. Stiction μ_s > μ_d of
    the regularised Coulomb model has no counterpart: μ = μ_d with a warning, or
    refused with `strict`."""
    mu, models, settings, notes, warnings = {}, {}, {}, [], []
    fbb, fbw = preset.frictions
    same = (fbb.tangential, fbb.mu_s, fbb.mu_d) == (fbw.tangential, fbw.mu_s, fbw.mu_d)
    for kind, f in zip(("ball_ball", "ball_wall"), preset.frictions):
        t = TANGENTIAL_EXPORT[TANGENTIAL[f.tangential].name]
        mu[kind], models[kind], settings[kind] = f.mu_d, t.keyword, list(t.settings)
        where = "" if same else f" ({kind.replace('_', '-')})"
        stiction = t.stiction and f.mu_s != f.mu_d
        if stiction and strict:
            key = "pair" if preset.wall_friction is None else f"pair_{kind}"
            raise ConfigError(preset.source, key, f.name,
                              f"stiction μ_s = {f.mu_s:g} > μ_d = {f.mu_d:g} ({kind.replace('_', '-')}) has no "
                              "LIGGGHTS equivalent (set mu_s = mu_d or tangential = \"history\", or export without "
                              "--strict to map μ = μ_d)")
        if same and kind == "ball_wall":
            continue  # one line for both kinds
        if stiction:
            warnings.append(f"friction{where}: stiction μ_s = {f.mu_s:g} (below v_d = {f.v_d * 1e3:g} mm/s) has no "
                            f"LIGGGHTS equivalent; mapped to one Coulomb coefficient μ = μ_d = {f.mu_d:g} "
                            "(`tangential history`)")
        else:
            notes.append(f"friction{where}: " + t.note.format(mu=f.mu_d, v_s=f.v_s * 1e3))
    return mu, models, settings, notes, warnings


def _rolling(preset: Preset, strict: bool) -> tuple[dict, dict, list, list]:
    """(μ_r per kind, LIGGGHTS rolling model per kind, notes, warnings) of the rolling
    sub-models (ROLLING_EXPORT); μ_r = {} and no model when neither kind has rolling
    resistance. A kind with μ_r = 0 has no rolling_friction in its command."""
    mu_r, models, notes, warnings = {}, {}, [], []
    for kind, f in zip(("ball_ball", "ball_wall"), preset.frictions):
        if f.mu_r == 0:
            continue
        r = ROLLING_EXPORT[ROLLING[f.rolling].name]
        how = getattr(r, kind)
        text = r.text[kind].format(mu_r=f.mu_r)
        if how == "refused" or (how == "approximate" and strict):
            raise ConfigError(preset.source, _key(preset, kind, "mu_r"), f.mu_r,
                              text + ("" if how == "refused" else "; export without --strict to map it"))
        (notes if how == "exact" else warnings).append(f"rolling resistance ({kind.replace('_', '-')}): {text}")
        mu_r[kind], models[kind] = f.mu_r, r.keyword
    if not models:
        notes.append("rolling resistance: none in either code")
        return {}, {}, notes, warnings
    return {"ball_ball": 0.0, "ball_wall": 0.0, **mu_r}, models, notes, warnings


def motion_lines(preset: Preset) -> list[str]:
    """The deck's planetary motion: two superposed rotate/variable movers (module doc)."""
    d = preset.drive
    rel = d.jar_spin - d.plate_omega
    T = d.ramp_time
    return [
        "# planetary motion: the plate turns the jar about the mill axis at Omega(t); the jar turns",
        "# about its own axis at omega(t) = w(t) - Omega(t) relative to the plate (the second mover's",
        "# origin is carried by the first). taimill's start-up: both speeds follow",
        f"# step(s) = s^2 (3 - 2 s), s = t/T, T = {T:g} s, evaluated at the middle of each step.",
        "variable tmid equal (step-0.5)*dt",
        f"variable s equal v_tmid/{_n(T)}",
        "variable ramp equal v_s*(v_s>0.0)*(v_s<1.0)+(v_s>=1.0)",
        "variable smooth equal v_ramp*v_ramp*(3.0-2.0*v_ramp)",
        f"variable plate_omega equal {_n(d.plate_omega)}*v_smooth",
        f"variable jar_omega_rel equal {_n(rel)}*v_smooth",
        "fix plate all move/mesh mesh jar rotate/variable origin 0. 0. 0. axis 0. 0. 1. omega v_plate_omega",
        f"fix spin all move/mesh mesh jar rotate/variable origin {_n(preset.plate_radius)} 0. 0. axis 0. 0. 1. "
        "omega v_jar_omega_rel",
    ]


def time_step_check(preset: Preset, dt: float) -> dict:
    """dt against the Rayleigh time of the balls and the Hertz time of the fastest
    ball-ball and ball-wall impacts the drive can produce (LIGGGHTS' own formulas)."""
    mat = preset.balls.material
    r, m = preset.balls.radius, preset.balls.mass
    shear = mat.youngs_modulus / (2.0 * (1.0 + mat.poisson))
    t_r = math.pi * r * math.sqrt(mat.density / shear) / (0.1631 * mat.poisson + 0.8766)
    wall = load_material(preset.jar.wall_material)
    v = max_impact_speed(preset.drive.plate_omega, preset.drive.jar_spin, preset.plate_radius, preset.jar,
                         preset.gravity)

    def y_eff(a, b):
        return 1.0 / ((1 - a.poisson**2) / a.youngs_modulus + (1 - b.poisson**2) / b.youngs_modulus)

    t_h = min(2.87 * (m_e**2 / (r_e * y_eff(mat, other) ** 2 * v)) ** 0.2
              for m_e, r_e, other in ((m / 2, r / 2, mat), (m, r, wall)))
    return {"dt": dt, "rayleigh_time": t_r, "hertz_time": t_h, "v_max": v,
            "dt_over_rayleigh": dt / t_r, "dt_over_hertz": dt / t_h,
            "ok": dt < RAYLEIGH_FRACTION * t_r and dt < HERTZ_FRACTION * t_h}


@dataclass
class Export:
    out: Path
    mesh: JarMesh
    mapping: Mapping
    check: dict
    steps: int
    every: int
    positions: np.ndarray  #: (N, 3) jar frame, m

    def describe(self) -> str:
        c = self.check
        lines = [
            f"LIGGGHTS case in {self.out}: ./run.sh P  (mpirun -np P liggghts -in {DECK})",
            f"jar.stl: {self.mesh.side_facets} side-wall facets, {len(self.mesh.triangles)} triangles; "
            f"the wall deviates at most {self.mesh.deviation * 1e6:.2f} µm from the true profile "
            f"(limit {TOLERANCE * 1e6:g} µm)",
            f"time step {c['dt'] * 1e6:.4g} µs = {c['dt_over_rayleigh']:.1%} of the Rayleigh time "
            f"({c['rayleigh_time'] * 1e6:.4g} µs), {c['dt_over_hertz']:.1%} of the Hertz time at "
            f"{c['v_max']:.1f} m/s ({c['hertz_time'] * 1e6:.4g} µs): "
            + ("ok" if c["ok"] else f"ABOVE LIGGGHTS' advice ({RAYLEIGH_FRACTION:.0%}, {HERTZ_FRACTION:.0%})"),
            f"{self.steps} steps, a dump every {self.every} steps",
            *("mapped: " + n for n in self.mapping.notes),
        ]
        return "\n".join(lines)


def export_case(preset: Preset, out, *, strict: bool = False, dump_mesh: bool = False,
                liggghts: str = "liggghts", mapping: Mapping | None = None) -> Export:
    """Write the LIGGGHTS case of `preset` into directory `out` (module doc). ConfigError
    for what LIGGGHTS cannot express; approximations are in the returned mapping's
    warnings (the command line prints them). `mapping`: contact_mapping(preset, strict=…)
    if the caller already made it (to refuse before touching `out`)."""
    out = Path(out)
    mapping = mapping or contact_mapping(preset, strict=strict)
    spec = from_preset(preset)
    mesh = jar_mesh(preset.jar.profile, preset.jar.height)
    check = time_step_check(preset, preset.dt)
    steps = spec.steps - 1  # taimill takes its frames at steps 0, every, …, steps − 1
    out.mkdir(parents=True, exist_ok=True)
    (out / "dumps").mkdir(exist_ok=True)
    write_stl(out / "jar.stl", mesh.triangles, preset.jar.name)
    _write_data(out / "start.data", preset, spec.position)
    deck = _deck(preset, mapping, spec, steps, check, dump_mesh)
    (out / DECK).write_text(deck)
    script = out / "run.sh"
    script.write_text(_run_script(liggghts))
    script.chmod(0o755)
    config = preset.as_dict()
    config["initial_positions"] = spec.position.tolist()
    manifest = {
        "format": FORMAT, "version": VERSION, "config": plain(config), "radii": spec.radius.tolist(),
        "dt": spec.dt, "frame_every": spec.frame_every, "steps": steps,
        "dump": DUMP, "dump_columns": list(DUMP_COLUMNS), "mesh_dump": MESH_DUMP if dump_mesh else None,
        "ball_type": BALL_TYPE, "wall_type": WALL_TYPE,
        "jar_mesh": {"side_facets": mesh.side_facets, "triangles": len(mesh.triangles),
                     "deviation": mesh.deviation, "tolerance": TOLERANCE},
        "mapping": {"normal": mapping.normal, "tangential": mapping.tangential,
                    "tangential_models": mapping.tangential_models, "tangential_settings": mapping.tangential_settings,
                    "restitution": mapping.restitution, "friction": mapping.friction,
                    "rolling": mapping.rolling, "rolling_models": mapping.rolling_models,
                    "notes": mapping.notes, "warnings": mapping.warnings},
        "time_step_check": check,
    }
    (out / MANIFEST).write_text(json.dumps(plain(manifest), indent=1))
    return Export(out, mesh, mapping, check, steps, spec.frame_every, spec.position)


def _write_data(path: Path, preset: Preset, positions: np.ndarray) -> None:
    """read_data file: the simulation box around the jar's whole path and the balls at
    t = 0, in the ground frame (the jar's centre at (R_p, 0, 0), both angles 0)."""
    r = preset.balls.radius
    reach = preset.plate_radius + preset.jar.radius + 4 * r
    lo_z, hi_z = -4 * r, preset.jar.height + 4 * r
    ground = positions + np.array([preset.plate_radius, 0.0, 0.0])
    rows = [f"{i + 1} {BALL_TYPE} {_n(2 * r)} {_n(preset.balls.material.density)} {_n(x)} {_n(y)} {_n(z)}"
            for i, (x, y, z) in enumerate(ground)]
    path.write_text("\n".join([
        f"taimill start positions ({preset.source}), ground frame, m",
        "",
        f"{len(ground)} atoms",
        "2 atom types",
        "",
        f"{_n(-reach)} {_n(reach)} xlo xhi",
        f"{_n(-reach)} {_n(reach)} ylo yhi",
        f"{_n(lo_z)} {_n(hi_z)} zlo zhi",
        "",
        "Atoms",
        "",
        *rows,
        "",
    ]))


def _n(x) -> str:
    """A number as LIGGGHTS reads it, exactly (shortest round-trip form)."""
    return repr(float(x))


def _pair_matrix(bb: float, bw: float) -> str:
    """A 2×2 per-type-pair matrix (1 = balls, 2 = jar wall); wall-wall never meets."""
    return f"2 {_n(bb)} {_n(bw)} {_n(bw)} {_n(bw)}"


def _deck(preset: Preset, m: Mapping, spec, steps: int, check: dict, dump_mesh: bool) -> str:
    ball, wall = preset.balls.material, load_material(preset.jar.wall_material)
    r = preset.balls.radius
    if m.normal == "hertz":
        normal, keywords = "model hertz", ["limitForce on"]
        props = [f"fix m3 all property/global coefficientRestitution peratomtypepair "
                 f"{_pair_matrix(m.restitution['ball_ball'], m.restitution['ball_wall'])}"]
    else:
        (kbb, cbb), (kbw, cbw) = m.stiffness["ball_ball"], m.stiffness["ball_wall"]
        normal = "model hooke/stiffness"
        keywords = ["absolute_damping on", "limitForce on", "tangential_damping off"]
        props = [f"fix m3 all property/global kn peratomtypepair {_pair_matrix(kbb, kbw)}",
                 f"fix m5 all property/global kt peratomtypepair {_pair_matrix(2 / 7 * kbb, 2 / 7 * kbw)}",
                 f"fix m6 all property/global gamman_abs peratomtypepair {_pair_matrix(cbb, cbw)}",
                 f"fix m7 all property/global gammat_abs peratomtypepair {_pair_matrix(0.0, 0.0)}"]

    def models(kind):
        """(models, settings) of one contact kind: pair_style (ball-ball) and the wall fix
        (ball-wall) each take their own."""
        rolling_model = m.rolling_models.get(kind)
        settings = [*keywords, *(s for s in m.tangential_settings.get(kind, ()) if s not in keywords)]
        rolling_part = f" rolling_friction {rolling_model}" if rolling_model else ""
        return f"{normal} tangential {m.tangential_models[kind]}{rolling_part}", " ".join(settings)

    d = preset.drive
    lines = [
        f"# LIGGGHTS-PUBLIC 3.8 case exported by taimill from {preset.source}",
        f"# {preset.jar.name} jar, {preset.balls.count} balls of {r * 1e3:g} mm ({ball.name}), pair {preset.pair},",
        f"# plate {d.plate_rpm:g} rpm, K = {d.ratio:g} (jar {d.jar_rpm:g} rpm relative to the plate), "
        f"R_p = {preset.plate_radius * 1e3:g} mm, ramp {d.ramp_time:g} s, {steps * preset.dt:g} s simulated.",
        "# SI units; the ground frame: the mill axis is z through the origin, gravity along -z.",
        *(f"# mapped: {n}" for n in m.notes),
        *(f"# APPROXIMATED: {w}" for w in m.warnings),
        "",
        "atom_style granular",
        "atom_modify map array",
        "boundary f f f",
        "newton off",
        "communicate single vel yes",
        "units si",
        "hard_particles yes",
        "processors * * 1",
        "read_data start.data",
        f"neighbor {_n(0.25 * r)} bin",
        "neigh_modify delay 0",
        "",
        "# materials: type 1 balls, type 2 the jar wall",
        f"fix m1 all property/global youngsModulus peratomtype {_n(ball.youngs_modulus)} {_n(wall.youngs_modulus)}",
        f"fix m2 all property/global poissonsRatio peratomtype {_n(ball.poisson)} {_n(wall.poisson)}",
        *props,
        f"fix m4 all property/global coefficientFriction peratomtypepair "
        f"{_pair_matrix(m.friction['ball_ball'], m.friction['ball_wall'])}",
        *([f"fix m8 all property/global coefficientRollingFriction peratomtypepair "
           f"{_pair_matrix(m.rolling['ball_ball'], m.rolling['ball_wall'])}"] if m.rolling else []),
        "pair_style gran {} {}".format(*models("ball_ball")),
        "pair_coeff * *",
        f"timestep {_n(preset.dt)}",
        "",
        "fix jar all mesh/surface file jar.stl type 2 move "
        f"{_n(preset.plate_radius)} 0. 0.",
        "fix walls all wall/gran {} mesh n_meshes 1 meshes jar {}".format(*models("ball_wall")),
        "fix integrate all nve/sphere",
    ]
    if preset.gravity > 0:
        lines.append(f"fix gravity all gravity {_n(preset.gravity)} vector 0. 0. -1.")
    lines += ["", *motion_lines(preset), ""]
    lines += [
        f"# time step: {check['dt_over_rayleigh']:.1%} of the Rayleigh time, {check['dt_over_hertz']:.1%} of the "
        f"Hertz time at {check['v_max']:.2f} m/s",
        f"fix dtcheck all check/timestep/gran {max(1, steps // 20)} {RAYLEIGH_FRACTION} {HERTZ_FRACTION} "
        f"vmax {_n(check['v_max'])}",
        "thermo_style custom step atoms ke",
        f"thermo {max(1, steps // 20)}",
        "thermo_modify lost error norm no",
        "",
        f"# dumps at the preset's trajectory rate ({preset.trajectory_rate:g} /s): every {spec.frame_every} steps",
        f"dump balls all custom {spec.frame_every} {DUMP} {' '.join(DUMP_COLUMNS)}",
        f"dump_modify balls sort id format \"%d %d{' %.17g' * (len(DUMP_COLUMNS) - 2)}\"",
    ]
    if dump_mesh:
        lines.append(f"dump jarmesh all mesh/stl {spec.frame_every} {MESH_DUMP} jar")
    lines += ["", f"run {steps}", ""]
    return "\n".join(lines)


def _run_script(liggghts: str) -> str:
    return "\n".join([
        "#!/bin/sh",
        "# Runs this case: ./run.sh [P]  (P MPI processes, default 1). LIGGGHTS=path, MPIRUN=\"mpirun --flags\"",
        "# override the binary and the launcher. Then: taimill import liggghts DIR --out RUN.zarr",
        "set -e",
        'cd "$(dirname "$0")"',
        'P="${1:-1}"',
        f'LIGGGHTS="${{LIGGGHTS:-{shlex.quote(liggghts)}}}"',
        "mkdir -p dumps",
        'if [ "$P" -gt 1 ]; then',
        f'  exec ${{MPIRUN:-mpirun}} -np "$P" "$LIGGGHTS" -in {DECK} -log log.liggghts',
        "else",
        f'  exec "$LIGGGHTS" -in {DECK} -log log.liggghts',
        "fi",
        "",
    ])
