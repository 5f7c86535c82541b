"""A preset as a ready-to-run LIGGGHTS-PUBLIC 3.8 case (docs/liggghts.md).

`export_case(preset, DIR)` writes

    jar.stl          the jar (jar frame, m) as a closed surface, facets within 10 µm of the profile
    start.data       the balls at t = 0 in the ground frame (read_data, atom style granular)
    in.taimill       the input deck: materials, contact models, gravity, the planetary
                     motion as two superposed `fix move/mesh rotate/variable` with
                     taimill's start-up ramp, dumps at the preset's trajectory rate
    run.sh           `./run.sh P` runs it on P MPI processes (mpirun -np P liggghts -in in.taimill)
    taimill-case.json the resolved preset, the mapping and what the import needs

How each part of taimill's model is expressed (or refused) is decided in
`contact_map.contact_mapping` (contacts) and here (motion), and documented in
docs/liggghts.md.

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

import json
import math
import shlex
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from taimill.bridge.mesh import TOLERANCE, JarMesh, jar_mesh, write_stl
from taimill.bridge.contact_map import Mapping, contact_mapping
from taimill.model.materials import load_material
from taimill.model.preset import Preset
from taimill.model.rules import max_impact_speed
from taimill.model.spec import from_preset
from taimill.store.layout import plain

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
