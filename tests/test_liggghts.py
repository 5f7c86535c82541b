"""Export to LIGGGHTS and import of its dumps (docs/liggghts.md).

The tests that run LIGGGHTS need the `liggghts` binary on PATH (Debian package
`liggghts`, LIGGGHTS-PUBLIC 3.8.0; .ci/run installs it when apt works) and skip saying
so otherwise. They simulate 0.02-0.03 s each (~5-10 s of wall time). The acceptance
comparison (12 balls, 5 s) is `-m full` and scripts/liggghts_compare.py.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import subprocess

import numpy as np
import pytest

from taimill.analysis.compare import compare
from taimill.analysis.rungeometry import RunGeometry
from taimill.bridge import dumps
from taimill.bridge.contact_map import contact_mapping
from taimill.bridge.liggghts import export_case
from taimill.bridge.mesh import TOLERANCE, jar_mesh, read_stl
from taimill.errors import ConfigError
from taimill.model.contact import registry
from taimill.model.jars import jar_names, load_jar
from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink

LIGGGHTS = shutil.which("liggghts")
needs_liggghts = pytest.mark.skipif(LIGGGHTS is None, reason="liggghts binary not on PATH (apt-get install liggghts)")
G = 9.81

FREE_FLIGHT = """\
jar = "CY"
pair = "steel-steel"
law = "hertz-mindlin"
plate_rpm = 50
ratio = -2.2
duration = 0.03
analysis_start = 0.0
ramp_time = 0.01
initial_positions = "start.csv"

[balls]
count = 1
material = "steel-c1020"
radius_mm = 6

[friction]
mu_s = 0.8
mu_d = 0.8

[outputs]
trajectory_rate = 500
"""


def free_flight_preset(tmp_path):
    # one ball off the axis near the lid: in 0.03 s it falls 4.4 mm and the jar centre
    # moves 16 mm while the jar turns by -0.29 rad; the wall never reaches it
    (tmp_path / "start.csv").write_text("-0.005,0.003,0.017\n")
    (tmp_path / "free.toml").write_text(FREE_FLIGHT)
    return load_preset(tmp_path / "free.toml")


def run_liggghts(case):
    done = subprocess.run([LIGGGHTS, "-in", "in.taimill", "-log", "log.liggghts"], cwd=case, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "ERROR" not in done.stdout, done.stdout[-2000:]
    return done.stdout


# ---------------------------------------------------------------- without LIGGGHTS
@pytest.mark.parametrize("name", jar_names())
def test_jar_stl_is_closed_and_within_tolerance_of_the_profile(name, tmp_path):
    jar = load_jar(name)
    mesh = jar_mesh(jar.profile, jar.height)
    assert mesh.deviation < TOLERANCE  # measured with the exact SDF on every facet
    t = mesh.triangles
    volume = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6
    assert volume == pytest.approx(jar.volume, rel=1e-3)  # closed, outward normals
    # every edge is shared by exactly two triangles, in opposite directions
    edges = {}
    for tri in np.round(t * 1e9).astype(np.int64):
        for a, b in ((0, 1), (1, 2), (2, 0)):
            key = (tuple(tri[a]), tuple(tri[b]))
            edges[key] = edges.get(key, 0) + 1
    assert all(edges.get((b, a)) == 1 for (a, b) in edges)


def test_start_positions_round_trip_through_the_data_file(tmp_path):
    p = load_preset("presets/p4-3l-steel.toml", {"duration": 0.02, "law": "hertz-mindlin"})
    export_case(p, tmp_path / "case")
    text = (tmp_path / "case" / "start.data").read_text()
    rows = [line.split() for line in text.split("\nAtoms\n")[1].splitlines() if line.strip()]
    ground = np.array([[float(v) for v in r[4:]] for r in rows])
    expected = from_preset(p).position
    assert np.abs(ground - [p.plate_radius, 0.0, 0.0] - expected).max() < 1e-15
    assert float(rows[0][2]) == 2 * p.balls.radius and float(rows[0][3]) == p.balls.material.density


def test_mapping_is_exact_for_hertz_mindlin_and_refuses_or_warns_otherwise():
    p = load_preset("presets/p4-cy-steel.toml", {"law": "hertz-mindlin"})
    m = contact_mapping(p)
    assert m.normal == "hertz" and not any("normal" in w for w in m.warnings)
    # LIGGGHTS' input e reproduces taimill's calibrated damping c = 2√(5/6) β
    beta = -math.log(m.restitution["ball_ball"]) / math.hypot(math.log(m.restitution["ball_ball"]), math.pi)
    assert 2 * math.sqrt(5 / 6) * beta == pytest.approx(p.ball_ball.c, rel=1e-12)
    assert any("stiction" in w for w in m.warnings)  # μ_s = 1.0 > μ_d = 0.8
    with pytest.raises(ConfigError, match="stiction"):
        contact_mapping(p, strict=True)
    adams = load_preset("presets/p4-cy-steel.toml", {"friction.mu_s": 0.8})
    assert any("adams-impact has no LIGGGHTS equivalent" in w for w in contact_mapping(adams).warnings)
    with pytest.raises(ConfigError, match="adams-impact has no LIGGGHTS equivalent"):
        contact_mapping(adams, strict=True)
    kv = contact_mapping(load_preset("presets/p4-cy-steel.toml", {"law": "kelvin-voigt", "friction.mu_s": 0.8}),
                         strict=True)
    assert kv.normal == "hooke/stiffness" and not kv.warnings


def test_cli_export_refuses_in_one_line_with_exit_code_2(tmp_path):
    from taimill.cli import main

    rc = main(["export", "liggghts", "presets/p4-cy-steel.toml", "--strict", "--out", str(tmp_path / "c")])
    assert rc == 2 and not (tmp_path / "c").exists()


def _deck_line(case, start):
    return next(line for line in (case / "in.taimill").read_text().splitlines() if line.startswith(start))


def test_friction_per_contact_kind_is_exported_per_type_pair(tmp_path):
    # a coated jar: ball-ball steel-steel μ_d = 0.8, ball-wall the pair's μ_d (type 2 = the wall)
    p = load_preset("presets/p4-cy-steel.toml", {"law": "hertz-mindlin", "friction.mu_s": 0.8,
                                                  "pair_ball_wall": "steel-fluorite", "duration": 0.01})
    m = contact_mapping(p)
    assert m.friction == {"ball_ball": 0.8, "ball_wall": p.frictions[1].mu_d} and p.frictions[1].mu_d != 0.8
    assert m.rolling == {} and any("stiction" in w and "ball-wall" in w for w in m.warnings)  # fluorite: 0.25/0.2
    with pytest.raises(ConfigError, match="pair_ball_wall = 'steel-fluorite'.*stiction"):
        contact_mapping(p, strict=True)
    export_case(p, tmp_path / "c")
    assert _deck_line(tmp_path / "c", "fix m4 ").split()[-5:] == ["2", "0.8", repr(m.friction["ball_wall"]),
                                                                  repr(m.friction["ball_wall"]), repr(m.friction["ball_wall"])]
    assert "rolling_friction" not in (tmp_path / "c" / "in.taimill").read_text()


def test_rolling_resistance_is_cdt_for_ball_ball_and_refused_for_the_turning_wall(tmp_path):
    base = {"law": "hertz-mindlin", "friction.mu_s": 0.8, "duration": 0.005, "outputs.trajectory_rate": 1000, "ramp_time": 0.002}
    p = load_preset("presets/p4-cy-steel.toml", {**base, "friction_ball_ball.mu_r": 0.05})
    m = contact_mapping(p)
    assert m.rolling == {"ball_ball": 0.05, "ball_wall": 0.0} and any("rolling_friction cdt" in w for w in m.warnings)
    with pytest.raises(ConfigError, match=r"friction_ball_ball\.mu_r = 0\.05"):
        contact_mapping(p, strict=True)
    export_case(p, tmp_path / "c")
    assert _deck_line(tmp_path / "c", "pair_style").startswith("pair_style gran model hertz tangential history "
                                                               "rolling_friction cdt")
    assert "rolling_friction" not in _deck_line(tmp_path / "c", "fix walls")
    assert _deck_line(tmp_path / "c", "fix m8 ").endswith("peratomtypepair 2 0.05 0.0 0.0 0.0")
    for key in ("friction.mu_r", "friction_ball_wall.mu_r"):  # both kinds, or the wall only
        with pytest.raises(ConfigError, match=rf"{key.replace('.', '[.]')} = 0\.1: ball-wall rolling resistance"):
            contact_mapping(load_preset("presets/p4-cy-steel.toml", {**base, key: 0.1}))
    if LIGGGHTS:  # the deck is valid LIGGGHTS: ~0.005 s of the mill
        run_liggghts(tmp_path / "c")


SAME_MODELS = {"law": "hertz-mindlin", "friction.tangential": "history", "friction.rolling": "epsd2",
               "friction.mu_r": 0.05, "duration": 0.005, "outputs.trajectory_rate": 1000, "ramp_time": 0.002}
SAME_MODELS_DECK = "model hertz tangential history rolling_friction epsd2"
SAME_MODELS_SETTINGS = "limitForce on tangential_damping off"


def test_history_and_epsd2_are_exported_exactly(tmp_path):
    # tangential = history: LIGGGHTS `tangential history` without tangential damping and
    # μ = μ_d (this preset's μ_s = 1.0 is not read by the model: no stiction warning);
    # rolling = epsd2: `rolling_friction epsd2` with μ_r, on the pair style and the wall fix
    p = load_preset("presets/p4-cy-steel.toml", SAME_MODELS)
    assert p.friction.mu_s == 1.0 and p.friction.mu_d == 0.8
    m = contact_mapping(p)
    assert m.friction == {"ball_ball": 0.8, "ball_wall": 0.8}
    assert m.rolling == {"ball_ball": 0.05, "ball_wall": 0.05}
    assert m.rolling_models == {"ball_ball": "epsd2", "ball_wall": "epsd2"}
    assert any("tangential = history" in n and "exact" in n for n in m.notes)
    assert any("rolling resistance (ball-ball): rolling = epsd2" in n and "exact" in n for n in m.notes)
    # the only approximation: the wall contact's spin (ground frame in LIGGGHTS)
    assert len(m.warnings) == 1 and "ground-frame spin" in m.warnings[0] and "ball-wall" in m.warnings[0]
    with pytest.raises(ConfigError, match=r"friction\.mu_r = 0\.05: rolling = epsd2.*ground-frame spin"):
        contact_mapping(p, strict=True)
    export_case(p, tmp_path / "c")
    case = tmp_path / "c"
    assert _deck_line(case, "pair_style") == f"pair_style gran {SAME_MODELS_DECK} {SAME_MODELS_SETTINGS}"
    assert _deck_line(case, "fix walls") == (f"fix walls all wall/gran {SAME_MODELS_DECK} mesh n_meshes 1 meshes jar "
                                             f"{SAME_MODELS_SETTINGS}")
    assert _deck_line(case, "fix m4 ").endswith("coefficientFriction peratomtypepair 2 0.8 0.8 0.8 0.8")
    assert _deck_line(case, "fix m8 ").endswith("coefficientRollingFriction peratomtypepair 2 0.05 0.05 0.05 0.05")
    # with rolling resistance on ball-ball contacts only, the whole mapping is exact
    bb_only = contact_mapping(load_preset("presets/p4-cy-steel.toml", {**SAME_MODELS, "friction_ball_wall.mu_r": 0.0}),
                              strict=True)
    assert not bb_only.warnings and bb_only.rolling_models == {"ball_ball": "epsd2"}
    assert bb_only.rolling == {"ball_ball": 0.05, "ball_wall": 0.0}
    # under kelvin-voigt LIGGGHTS' tangential spring is hooke/stiffness' constant kt, not Mindlin's
    kv = load_preset("presets/p4-cy-steel.toml", {**SAME_MODELS, "law": "kelvin-voigt", "friction.mu_r": 0.0})
    assert any("kelvin-voigt" in w and "2/7 kn" in w for w in contact_mapping(kv).warnings)
    with pytest.raises(ConfigError, match=r"friction\.tangential = 'history': tangential = history with kelvin"):
        contact_mapping(kv, strict=True)


def test_each_contact_kind_is_written_with_its_own_sub_models(tmp_path):
    # pair_style holds the ball-ball models and the wall fix its own, so mixed sub-models
    # map kind by kind (LIGGGHTS 3.8 accepts different models in the two commands)
    base = {"law": "hertz-mindlin", "friction.mu_s": 0.8, "duration": 0.005, "outputs.trajectory_rate": 1000, "ramp_time": 0.002}
    p = load_preset("presets/p4-cy-steel.toml", {**base, "friction_ball_ball.tangential": "history",
                                                  "friction_ball_ball.mu_r": 0.05,
                                                  "friction_ball_wall.rolling": "epsd2",
                                                  "friction_ball_wall.mu_r": 0.02})
    m = contact_mapping(p)
    assert m.tangential_settings == {"ball_ball": ["tangential_damping off"], "ball_wall": []}
    assert m.rolling_models == {"ball_ball": "cdt", "ball_wall": "epsd2"}
    assert any(n.startswith("friction (ball-ball): tangential = history") for n in m.notes)
    assert any(n.startswith("friction (ball-wall): Coulomb μ = 0.8") for n in m.notes)
    export_case(p, tmp_path / "c")
    assert _deck_line(tmp_path / "c", "pair_style") == ("pair_style gran model hertz tangential history "
                                                         "rolling_friction cdt limitForce on tangential_damping off")
    assert _deck_line(tmp_path / "c", "fix walls").endswith("tangential history rolling_friction epsd2 mesh n_meshes 1 "
                                                            "meshes jar limitForce on")
    assert _deck_line(tmp_path / "c", "fix m8 ").endswith("peratomtypepair 2 0.05 0.02 0.02 0.02")
    # constant-torque rolling at the turning wall stays refused, whatever the ball-ball model
    with pytest.raises(ConfigError, match=r"friction_ball_wall\.mu_r = 0\.02: ball-wall rolling resistance"):
        contact_mapping(load_preset("presets/p4-cy-steel.toml", {**base, "friction_ball_ball.rolling": "epsd2",
                                                                 "friction_ball_wall.mu_r": 0.02}))
    if LIGGGHTS:  # the mixed deck is valid LIGGGHTS (~0.005 s of the mill)
        run_liggghts(tmp_path / "c")


def _running(kind: str, name: str, like: str):
    """The CY steel preset with the sub-model `name` of `kind` on both contact kinds;
    like: the registered sub-model whose coefficients the preset gets (`name` itself, or
    the one a planted sub-model copies)."""
    if kind == "normal":
        p = load_preset("presets/p4-cy-steel.toml", {"law": like})
        return dataclasses.replace(p, ball_ball=dataclasses.replace(p.ball_ball, law=name),
                                   ball_wall=dataclasses.replace(p.ball_wall, law=name))
    p = load_preset("presets/p4-cy-steel.toml")
    given = {"tangential": {"tangential": name}, "rolling": {"rolling": name, "mu_r": 0.05}}[kind]
    return dataclasses.replace(p, friction=dataclasses.replace(p.friction, **given))


@pytest.mark.parametrize("kind, table", [("normal", registry.LAWS), ("tangential", registry.TANGENTIAL),
                                         ("rolling", registry.ROLLING)])
def test_every_registered_sub_model_is_exported_or_refused_in_one_line(kind, table, monkeypatch):
    # every sub-model registered for runs, and a planted copy of one as a new sub-model
    # would be, is written for LIGGGHTS or refused in one ConfigError line: never a
    # KeyError from a model without a row in the export's tables (the springs and
    # dampings are exported through the normal laws that compose them)
    first = next(iter(table))
    monkeypatch.setitem(table, "planted", dataclasses.replace(table[first], name="planted"))
    for name in table:
        p = _running(kind, name, first if name == "planted" else name)
        for strict in (False, True):
            try:
                contact_mapping(p, strict=strict)
            except ConfigError as e:
                assert "\n" not in str(e), (name, strict, str(e))
    if kind != "normal":  # a normal law without an exact counterpart is approximated or refused by name
        with pytest.raises(ConfigError, match=rf"friction\.{kind} = 'planted': has no LIGGGHTS export; the export "
                                              rf"writes {kind} = .*, .*"):
            contact_mapping(_running(kind, "planted", first))


@needs_liggghts
def test_history_and_epsd2_case_runs_in_liggghts(tmp_path):
    # 0.02 s of the CY start-up (12 balls settling onto the floor and the wall: sticking
    # contacts load both springs) with history and epsd2 on both kinds: no error, no
    # lost atom, the dumps complete and every ball still inside the jar (~5 s)
    p = load_preset("presets/p4-cy-steel.toml", {**SAME_MODELS, "duration": 0.02, "ramp_time": 0.01})
    export_case(p, tmp_path / "case")
    run_liggghts(tmp_path / "case")
    log = (tmp_path / "case" / "log.liggghts").read_text().splitlines()  # the commands LIGGGHTS ran, echoed
    assert f"pair_style gran {SAME_MODELS_DECK} {SAME_MODELS_SETTINGS}" in log
    assert any(line.startswith("fix walls") and line.endswith(SAME_MODELS_SETTINGS) for line in log)
    assert dumps.import_case(tmp_path / "case", tmp_path / "run.zarr")["status"] == "complete"
    x = open_run(tmp_path / "run.zarr").frames["position"]
    assert x.shape[1] == p.balls.count
    phi = RunGeometry.from_config(p.as_dict(), np.full(p.balls.count, p.balls.radius)).sdf(x[-1, :, :2])[0]
    assert (phi > p.balls.radius - 1e-4).all()


def test_a_refused_export_leaves_an_existing_case_alone(tmp_path):
    from taimill.cli import main

    case = tmp_path / "c"
    assert main(["export", "liggghts", "presets/p4-cy-steel.toml", "--duration", "0.01", "--out", str(case)]) == 0
    before = {f: f.read_bytes() for f in case.rglob("*") if f.is_file()}
    rc = main(["export", "liggghts", "presets/p4-cy-steel.toml", "--strict", "--overwrite", "--out", str(case)])
    assert rc == 2 and {f: f.read_bytes() for f in case.rglob("*") if f.is_file()} == before


def _synthetic_dump(path, steps, x, v, s, radius, mass):
    with open(path, "w") as f:
        for k, step in enumerate(steps):
            f.write(f"ITEM: TIMESTEP\n{step}\nITEM: NUMBER OF ATOMS\n{len(x[k])}\nITEM: BOX BOUNDS ff ff ff\n"
                    "-1 1\n-1 1\n-1 1\nITEM: ATOMS id type x y z vx vy vz omegax omegay omegaz radius mass\n")
            for i in range(len(x[k])):
                f.write(" ".join([str(i + 1), "1", *(repr(float(q)) for q in (*x[k, i], *v[k, i], *s[k, i])),
                                  repr(radius), repr(mass)]) + "\n")


def test_import_converts_a_ground_frame_free_flight_to_the_jar_frame(tmp_path):
    # dumps written by hand: a ball in free fall in the ground frame, spinning; the store
    # holds its jar-frame state per docs/outputs.md, as taimill's own formulas give it
    p = free_flight_preset(tmp_path)
    case = tmp_path / "case"
    export_case(p, case)
    man = dumps.read_manifest(case)
    dt = man["dt"]
    steps = np.arange(0, man["steps"] + 1, man["frame_every"])
    t = steps * dt
    x0 = np.array([p.plate_radius - 0.005, 0.003, 0.017])
    x = (x0 + np.outer(t * t, [0, 0, -0.5 * G]))[:, None]
    v = np.outer(t, [0, 0, -G])[:, None]
    s = np.tile([1.0, -2.0, 3.0], (len(t), 1, 1))
    _synthetic_dump(case / "dumps" / "balls.dump", steps, x, v, s, p.balls.radius, p.balls.mass)
    dumps.import_case(case, tmp_path / "ff.zarr")
    run = open_run(tmp_path / "ff.zarr")
    f = run.frames
    plate, jar = p.drive.start_up()
    for k in (0, len(t) // 2, len(t) - 1):
        om, _, pp = plate.at(f["time"][k])
        w, _, pj = jar.at(f["time"][k])
        rot = np.array([[np.cos(pj), -np.sin(pj), 0], [np.sin(pj), np.cos(pj), 0], [0, 0, 1]])
        c = p.plate_radius * np.array([np.cos(pp), np.sin(pp), 0])
        cv = om * p.plate_radius * np.array([-np.sin(pp), np.cos(pp), 0])
        xj = (x[k, 0] - c) @ rot
        vj = (v[k, 0] - cv) @ rot - np.cross([0, 0, w], xj)
        assert np.allclose(f["position"][k, 0], xj, atol=1e-12)
        assert np.allclose(f["velocity"][k, 0], vj, atol=1e-12)
        assert np.allclose(f["spin"][k, 0], s[k, 0] @ rot, atol=1e-12)
        assert f["jar_angle"][k] == pytest.approx(pj) and f["plate_speed"][k] == pytest.approx(om)
    assert len(run.events["t_start"]) == 0 and len(run.energy["time"]) == 0
    assert "reconstructed from frames" in run.attrs["events_source"] and run.attrs["energy_source"]
    assert run.status == "complete"
    # a run killed while dumping: the cut snapshot is left out and the store says so
    dump = case / "dumps" / "balls.dump"
    dump.write_text(dump.read_text()[:-40])
    assert dumps.import_case(case, tmp_path / "cut.zarr")["status"] == "incomplete dumps"
    assert len(open_run(tmp_path / "cut.zarr").frames["time"]) == len(t) - 1


def test_reconstructed_impact_has_the_onset_speed_of_the_free_flight():
    # one ball flying at the floor between two frames: the event is found by its flight
    # and its onset speeds are the flight's at the touch
    # a mill at rest (presets refuse plate_rpm = 0, where K is undefined: set in the config)
    p = load_preset("presets/p4-cy-steel.toml", {"law": "hertz-mindlin"})
    config = {**p.as_dict(), "plate_omega": 0.0, "plate_rpm": 0.0, "jar_rpm": 0.0, "ratio": 0.0}
    geom = RunGeometry.from_config(config, np.array([p.balls.radius]))
    r = p.balls.radius
    t = np.array([0.0, 1e-3])
    xg = np.array([[[p.plate_radius, 0.0, r + 1e-3]], [[p.plate_radius + 1e-3, 0.0, r + 1e-4]]])
    vg = np.array([[[1.0, 0.0, -2.0]], [[1.0, 0.0, 1.0]]])
    sg = np.array([[[0.0, 10.0, 0.0]], [[0.0, 0.0, 0.0]]])
    ev = dumps.reconstruct_events(geom, [r], [p.balls.mass], t, xg, vg, sg, G)
    assert len(ev["t_start"]) == 1 and ev["body_j"][0] == -2  # the floor
    tau = (math.sqrt(4.0 + 2 * G * 1e-3) - 2.0) / G  # 1 mm fall at 2 m/s under gravity
    assert ev["t_start"][0] == pytest.approx(tau, rel=1e-9)
    assert ev["un"][0] == pytest.approx(2.0 + G * tau, rel=1e-9)
    assert ev["ut"][0] == pytest.approx(1.0 - 10.0 * r, rel=1e-9)  # slip: v + s × a, a = −r ẑ
    assert ev["duration"][0] == pytest.approx(1e-3 - tau)  # upper bound: to the next frame


# ---------------------------------------------------------------- with LIGGGHTS
@pytest.fixture(scope="module")
def free_flight(tmp_path_factory):
    if LIGGGHTS is None:
        pytest.skip("liggghts binary not on PATH (apt-get install liggghts)")
    tmp = tmp_path_factory.mktemp("free")
    p = free_flight_preset(tmp)
    export_case(p, tmp / "case", dump_mesh=True)
    run_liggghts(tmp / "case")
    dumps.import_case(tmp / "case", tmp / "liggghts.zarr")
    from taimill.runs.simulation import run

    run(p, ZarrSink(tmp / "taimill.zarr"))
    return p, tmp


@needs_liggghts
def test_mesh_motion_reproduces_the_jar_centre_and_angle(free_flight):
    # the dumped mesh, fitted as a rigid motion of jar.stl: centre within 2 µm and angle
    # within 2e-5 rad of taimill's ramps (measured: 0.1 µm and 2e-6 rad, the mesh dump
    # has 6 significant digits) through the ramp and after it
    p, tmp = free_flight
    man = dumps.read_manifest(tmp / "case")
    ref = read_stl(tmp / "case" / "jar.stl").reshape(-1, 3)
    plate, jar = p.drive.start_up()
    files = sorted((tmp / "case" / "dumps").glob("jar_*.stl"), key=lambda f: int(f.stem.split("_")[1]))
    assert len(files) == man["steps"] // man["frame_every"] + 1
    turned = 0.0
    for f in files:
        t = int(f.stem.split("_")[1]) * man["dt"]
        cur = read_stl(f).reshape(-1, 3)
        a, b = ref[:, :2], cur[:, :2]
        h = (a - a.mean(0)).T @ (b - b.mean(0))
        ang = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
        rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
        centre = b.mean(0) - rot @ a.mean(0)
        _, _, phi_p = plate.at(t)
        _, _, phi_j = jar.at(t)
        assert np.hypot(*(centre - p.plate_radius * np.array([math.cos(phi_p), math.sin(phi_p)]))) < 2e-6
        assert abs((ang - phi_j + math.pi) % (2 * math.pi) - math.pi) < 2e-5
        assert np.abs(cur[:, 2] - ref[:, 2]).max() < 1e-9
        turned = phi_j
    assert abs(turned) > 0.2  # the check covered a real turn


@needs_liggghts
def test_free_flight_through_liggghts_follows_taimill(free_flight):
    # jar-frame position within 1 µm, velocity within 1e-4 m/s of taimill's own run
    # (velocity Verlet against symplectic Euler: the velocities differ by g dt/2)
    p, tmp = free_flight
    a, b = open_run(tmp / "taimill.zarr").frames, open_run(tmp / "liggghts.zarr").frames
    assert np.array_equal(a["time"], b["time"])
    assert np.abs(a["position"] - b["position"]).max() < 1e-6
    assert np.abs(a["velocity"] - b["velocity"]).max() < 1e-4
    for k in ("plate_angle", "plate_speed", "jar_angle", "jar_spin"):
        assert np.allclose(a[k], b[k], rtol=0, atol=1e-12)
    moved = np.abs(b["position"][-1, 0] - b["position"][0, 0]).max()
    assert moved > 5e-3  # a real flight across the turning jar


@needs_liggghts
def test_start_positions_round_trip_through_liggghts(free_flight):
    p, tmp = free_flight
    assert np.abs(open_run(tmp / "liggghts.zarr").frames["position"][0] - p.initial_positions).max() < 1e-15


@needs_liggghts
def test_compare_two_stores(free_flight, capsys):
    from taimill.cli import main

    p, tmp = free_flight
    result = compare(tmp / "taimill.zarr", tmp / "liggghts.zarr")
    rows = {r["key"]: r for r in result["rows"]}
    assert rows["randomness_index"]["relative_difference"] == pytest.approx(0.0, abs=1e-9)
    assert rows["events"]["a"] == rows["events"]["b"] == 0
    assert main(["compare", str(tmp / "taimill.zarr"), str(tmp / "liggghts.zarr")]) == 0
    out = capsys.readouterr().out
    assert "randomness index" in out and "(B-A)/|A|" in out


@needs_liggghts
@pytest.mark.parametrize("preset", ["presets/p4-hm-steel.toml", "presets/p4-3l-steel.toml"])
def test_hm_and_3l_jars_run_in_liggghts_without_lost_atoms(preset, tmp_path):
    # 0.02 s of the start-up with the shipped laws (mapped, with warnings): LIGGGHTS stops
    # with an error on a lost atom (thermo_modify lost error), and every dump holds all balls
    p = load_preset(preset, {"duration": 0.02})
    export_case(p, tmp_path / "case")
    out = run_liggghts(tmp_path / "case")
    assert "atoms" in out.lower()
    steps, _, data = dumps.read_dump(tmp_path / "case" / "dumps" / "balls.dump")
    assert data.shape[1] == p.balls.count and steps[-1] == dumps.read_manifest(tmp_path / "case")["steps"]
    summary = dumps.import_case(tmp_path / "case", tmp_path / "run.zarr")
    assert summary["status"] == "complete"
    x = open_run(tmp_path / "run.zarr").frames["position"]
    phi = RunGeometry.from_config(p.as_dict(), np.full(p.balls.count, p.balls.radius)).sdf(x[-1, :, :2])[0]
    assert (phi > p.balls.radius - 1e-4).all()  # every ball still inside the jar
    from taimill.analysis.run import analyse

    q = analyse(tmp_path / "run.zarr").quantities()  # the imported store is an ordinary run store
    assert q["status"] == "complete" and math.isnan(q["dissipated_power"])  # no ledger: said, not invented


@needs_liggghts
@pytest.mark.full
def test_acceptance_comparison_with_liggghts(tmp_path):
    # CY, 12 steel balls, 200 rpm, K = -2.2, e = 0.516, μ = 0.8, same start, 2-5 s:
    # mean SE within 15 % and 1/σ within 10 %, events reconstructed from frames in both
    # (scripts/liggghts_compare.py; ~10 min of LIGGGHTS on a free core)
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "scripts" / "liggghts_compare.py"
    spec = importlib.util.spec_from_file_location("liggghts_compare", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.main(["--out", str(tmp_path / "cmp"), "--results", str(tmp_path / "cmp.md")]) == 0


# a LIGGGHTS log as LIGGGHTS-PUBLIC 3.8 writes it: one "Loop time" line per `run` of the deck
FAKE_LOG = """\
LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2019-01-09)
run 1500
Loop time of 12.25 on 4 procs for 1500 steps with 1 atoms, 99.8% CPU use with 4 MPI tasks x no OpenMP threads
run 28500
Loop time of 27.75 on 4 procs for 28500 steps with 1 atoms, 99.9% CPU use with 4 MPI tasks x no OpenMP threads
Total wall time: 0:00:41
"""


def _free_flight_case(tmp_path):
    p = free_flight_preset(tmp_path)
    case = tmp_path / "case"
    export_case(p, case)
    man = dumps.read_manifest(case)
    steps = np.arange(0, man["steps"] + 1, man["frame_every"])
    t = steps * man["dt"]
    x = (np.array([p.plate_radius - 0.005, 0.003, 0.017]) + np.outer(t * t, [0, 0, -0.5 * G]))[:, None]
    v = np.outer(t, [0, 0, -G])[:, None]
    _synthetic_dump(case / "dumps" / "balls.dump", steps, x, v, np.zeros_like(v), p.balls.radius, p.balls.mass)
    return case


def test_import_reports_liggghts_own_run_time_from_its_log(tmp_path):
    import json

    from tests.inprocess import main

    case = _free_flight_case(tmp_path)
    (case / "log.liggghts").write_text(FAKE_LOG)
    code, out, err = main("import", "liggghts", case, "--out", tmp_path / "a.zarr", "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["wall_seconds"] == 40.0 and s["realtime_factor"] == pytest.approx(s["sim_seconds"] / 40.0)
    assert open_run(tmp_path / "a.zarr").attrs["source"]["loop_seconds"] == 40.0
    code, out, err = main("import", "liggghts", case, "--out", tmp_path / "b.zarr")
    assert code == 0 and "LIGGGHTS ran them in 40 s on 4 processes (log.liggghts)" in out, out + err
    assert err == ""


def test_import_without_a_log_says_the_run_time_is_unknown(tmp_path):
    import json

    from tests.inprocess import main

    case = _free_flight_case(tmp_path)
    code, out, err = main("import", "liggghts", case, "--out", tmp_path / "a.zarr", "--json")
    assert code == 0 and json.loads(out)["wall_seconds"] is None  # not the import's own time
    assert err.startswith("taimill: warning: ") and "LIGGGHTS' run time is unknown" in err and err.count("\n") == 1
