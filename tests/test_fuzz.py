"""Property tests of the input stage (docs/outputs.md, bad input): whatever a preset, jar
file, pair file, drop-test CSV, overlay CSV or command line holds, the loaders and the
parser either accept it or raise ConfigError (the CLI: exit 2, one line on stderr) —
never another exception.

Nothing is simulated: the stages after validation (Taichi, sweep workers, the calibration
runs, the live mill, the jar drawing) are replaced by a stub that marks the case accepted,
and the automatic time step (a simulated impact, 0.3 s for each new speed) by a stand-in
of the same form, so that hundreds of examples run in seconds. The laws that calibrate
their damping by simulated impacts (seconds per contact set) are left to
tests/test_laws.py; here contact sets use adams-impact or a name that is refused.
Deterministic for CI: derandomize=True, a fixed max_examples, no example database.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from taimill.errors import ConfigError
from taimill.model.materials import FRICTION_KEYS
from taimill.model.jars import JAR_KEYS
from taimill.model.contact_sets import NORMAL_LAW_KEYS
from taimill.model.preset import BALLS_KEYS, PRESET_KEYS

ROOT = Path(__file__).resolve().parent.parent
PRESET = str(ROOT / "presets" / "p4-cy-steel.toml")
TABLE_2_1 = str(ROOT / "taimill" / "data" / "zirconia_drop_table2_1.csv")


def fuzz(n):
    return settings(max_examples=n, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


class Accepted(Exception):
    """The input passed validation and reached a stage this test does not run."""


@pytest.fixture(scope="module")
def stubs():
    import taimill.calibration.fit
    import taimill.calibration.impacts
    import taimill.calibration.runs
    import taimill.cli.record
    import taimill.figures.jars
    import taimill.model.rules
    import taimill.physics.runner
    import taimill.runs.live
    import taimill.runs.simulation
    import taimill.runs.sweep

    def accepted(*a, **k):
        raise Accepted

    with pytest.MonkeyPatch.context() as mp:
        for module, name in ((taimill.physics.runner, "init_taichi"), (taimill.runs.simulation, "run"),
                             (taimill.runs.sweep, "run_sweep"), (taimill.runs.live, "LiveMill"),
                             (taimill.calibration.runs, "drop_tests"), (taimill.calibration.impacts, "sensitivity"),
                             (taimill.calibration.impacts, "oblique"), (taimill.calibration.fit, "fit_drops"),
                             (taimill.figures.jars, "draw_jar"), (taimill.cli.record.subprocess, "call")):
            mp.setattr(module, name, accepted)
        mp.setattr(taimill.model.rules, "_auto_dt", lambda bb, bw, v_max: 1e-4 / (1.0 + v_max))
        yield


@pytest.fixture(scope="module")
def where(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "afile").write_text("a file\n")
    return d


# ------------------------------------------------------------------ TOML out of Python values
def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(map(toml_value, v)) + "]"
    return "{ " + ", ".join(f"{json.dumps(str(k), ensure_ascii=False)} = {toml_value(x)}" for k, x in v.items()) + " }"


def toml_text(d: dict) -> str:
    return "".join(f"{json.dumps(str(k), ensure_ascii=False)} = {toml_value(v)}\n" for k, v in d.items())


NAMES = ["auto", "CY", "HM", "T", "steel-steel", "steel-fluorite", "zirconia-zirconia", "steel-c1020", "aisi-304",
         "zirconia", "adams-impact", "circle", "cut", "lifter", "x.toml", "", " ", "../x.toml", "a\u0000b"]
scalars = st.one_of(
    st.integers(-3, 3), st.integers(-(2**70), 2**70), st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1e4, 1e4), st.booleans(), st.sampled_from(NAMES), st.text(max_size=6))
values = st.one_of(scalars, st.lists(scalars, max_size=3), st.dictionaries(st.sampled_from(["a", "count", "mu_s"]), scalars, max_size=2))


def mutated(base: dict, keys: list[str], edits: int = 4):
    """base with up to `edits` edits: a key (or TABLE.key; mostly a known one) set to any
    value, or deleted."""
    key = st.one_of(st.sampled_from(keys), st.sampled_from(keys), st.sampled_from(keys), st.text(min_size=1, max_size=8))
    edit = st.tuples(st.sampled_from(["set", "set", "delete"]), key, values)

    def apply(edits):
        d = json.loads(json.dumps(base))
        for op, k, v in edits:
            table, _, leaf = k.rpartition(".")
            target = d.get(table) if table else d
            if not isinstance(target, dict):
                continue
            if op == "delete":
                target.pop(leaf, None)
            else:
                target[leaf] = v
        return d

    return st.lists(edit, max_size=edits).map(apply)


def accepts_or_refuses(load, *args):
    try:
        load(*args)
    except ConfigError as err:
        assert "\n" not in str(err)


# ------------------------------------------------------------------ presets, jars, pair files
PRESET_BASE = {"jar": "CY", "pair": "steel-steel", "plate_rpm": 200, "ratio": -2.6, "duration": 1.0,
               "analysis_start": 0.5, "dt": "auto", "seed": 1,
               "balls": {"count": 12, "material": "steel-c1020", "radius_mm": 6}}
PRESET_PATHS = list(PRESET_KEYS) + [f"balls.{k}" for k in BALLS_KEYS] + [f"friction.{k}" for k in FRICTION_KEYS] + [
    "outputs.trajectory_rate", "friction", "outputs", "duraton", "balls.radius"]


@fuzz(150)
@given(preset=mutated(PRESET_BASE, PRESET_PATHS))
def test_preset_contents_are_accepted_or_refused(stubs, where, preset):
    from taimill.model.preset import load_preset

    path = where / "preset.toml"
    path.write_text(toml_text(preset))
    accepts_or_refuses(load_preset, path)


JAR_BASE = {"height_mm": 24.1, "wall_material": "aisi-304", "fillet_mm": 8,
            "profile": [{"type": "circle", "radius_mm": 32.5}, {"type": "cut", "distance_mm": 18, "angle_deg": 0}]}
angles = st.floats(-360, 360)
primitive = st.one_of(
    st.fixed_dictionaries({"type": st.just("cut"), "distance_mm": st.floats(0.5, 40), "angle_deg": angles}),
    st.fixed_dictionaries({"type": st.just("lifter"), "radius_mm": st.floats(0.5, 20), "distance_mm": st.floats(0.5, 60),
                           "angle_deg": angles}),
    st.fixed_dictionaries({"type": st.sampled_from(["circle", "cut", "lifter", "square"])}, optional={
        "radius_mm": st.one_of(st.floats(0.5, 60), scalars), "distance_mm": st.one_of(st.floats(0.5, 60), scalars),
        "angle_deg": st.one_of(angles, scalars), "typ": scalars}))


@fuzz(30)
@given(jar=st.one_of(st.just(JAR_BASE), mutated(JAR_BASE, list(JAR_KEYS), edits=1)), extra=st.lists(primitive, max_size=2),
       fillet=st.floats(0, 20))
def test_jar_files_are_accepted_or_refused(stubs, where, jar, extra, fillet):
    from taimill.model.jars import load_jar

    jar = json.loads(json.dumps(jar))
    if isinstance(jar.get("profile"), list):
        jar["profile"] = jar["profile"] + extra
        jar["fillet_mm"] = fillet if isinstance(jar.get("fillet_mm"), (int, float)) else jar.get("fillet_mm")
    jar = {k: v for k, v in jar.items() if v is not None}
    path = where / "jar.toml"
    path.write_text(toml_text(jar))
    accepts_or_refuses(load_jar, str(path), "fuzz")


PAIR_BASE = {"pair": {"mine": {"contact": "mine", "mu_s": 0.5, "mu_d": 0.4, "v_s_mm_s": 1, "v_d_mm_s": 10}},
             "contact": {"mine": {"ball": "steel-c1020", "wall": "aisi-304", "law": "adams-impact", "ball_radius_mm": 6,
                                  "ball_ball": {"c_max_Ns_per_mm": 10.1, "d_mm": 0.211, "e": 0.516, "u_ref_mm_s": 3309},
                                  "ball_wall": {"c_max_Ns_per_mm": 17.5, "d_mm": 0.211, "e": 0.516, "u_ref_mm_s": 3309}}}}
PAIR_PATHS = ["pair", "contact", "pair.mine", "contact.mine"] + [f"pair.mine.{k}" for k in ("contact", *FRICTION_KEYS)] + [
    f"contact.mine.{k}" for k in ("ball", "wall", "ball_radius_mm", "ball_ball", "ball_wall")]


def pair_edits():
    law = st.tuples(st.sampled_from(["set", "delete"]), st.sampled_from(["ball_ball", "ball_wall"]),
                    st.sampled_from(list(NORMAL_LAW_KEYS) + ["d_m"]), scalars)
    return st.tuples(mutated(PAIR_BASE, PAIR_PATHS), st.lists(law, max_size=2))


@fuzz(120)
@given(case=pair_edits())
def test_pair_files_are_accepted_or_refused(stubs, where, case):
    from taimill.model.contact_sets import pair_contact

    pair, laws = case
    contact = pair.get("contact", {}).get("mine") if isinstance(pair.get("contact"), dict) else None
    for op, table, key, v in laws:  # one entry of a normal law's table set or deleted
        law = contact.get(table) if isinstance(contact, dict) else None
        if isinstance(law, dict):
            law.pop(key, None) if op == "delete" else law.__setitem__(key, v)
    if isinstance(contact, dict) and contact.get("law") not in ("adams-impact", None) and isinstance(contact.get("law"), str):
        from taimill.model.contact.registry import NAMES

        if contact["law"] in NAMES:  # a calibrated law: see the module doc
            contact["law"] = "adams-impact"
    path = where / "pair.toml"
    path.write_text(toml_text(pair))
    accepts_or_refuses(pair_contact, str(path))


@fuzz(60)
@given(data=st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode)))
def test_any_bytes_as_preset_jar_or_pair_file_are_accepted_or_refused(stubs, where, data):
    from taimill.model.jars import load_jar
    from taimill.model.contact_sets import pair_contact
    from taimill.model.preset import load_preset

    path = where / "raw.toml"
    path.write_bytes(data)
    accepts_or_refuses(load_preset, path)
    accepts_or_refuses(load_jar, str(path), "fuzz")
    accepts_or_refuses(pair_contact, str(path))


# ------------------------------------------------------------------ CSV files
CELLS = ["100", "500", "0.9", "0.5", "76", "-200", "0", "1e400", "nan", "inf", "", " ", "high", '"', '"1,2"', "1e-300", "2"]


def csv_text(required, columns):
    """A header (mostly with the required columns) and lines of cells, comments, blanks."""
    header = st.one_of(st.lists(st.sampled_from(columns), max_size=3, unique=True).map(lambda c: ",".join(required + c)),
                       st.lists(st.sampled_from(required + columns), max_size=4).map(",".join))
    row = st.lists(st.sampled_from(CELLS), min_size=0, max_size=5).map(",".join)
    lines = st.lists(st.one_of(row, st.sampled_from(["# comment", "", "   "])), max_size=6)
    return st.tuples(header, lines).map(lambda t: "\n".join([t[0], *t[1]]) + "\n")


@fuzz(150)
@given(text=st.one_of(csv_text(["h0_mm", "e"], ["rebound_mm", "sigma_e", "sigma_mm", "x"]),
                      csv_text(["h0_mm", "rebound_mm"], ["sigma_e", "sigma_mm", "x", "h0_mm "])))
def test_drop_csv_contents_are_accepted_or_refused(where, text):
    from taimill.calibration.data import load_drop_data

    path = where / "drops.csv"
    path.write_text(text)
    accepts_or_refuses(load_drop_data, path)


@fuzz(150)
@given(text=csv_text(["ratio", "a"], ["a_err", "b [mJ]", "b_err", "c_err"]))
def test_overlay_csv_contents_are_accepted_or_refused(where, text):
    from taimill.figures.sweep import read_overlay

    path = where / "overlay.csv"
    path.write_text(text)
    accepts_or_refuses(read_overlay, path)


# ------------------------------------------------------------------ the command line
NUMBERS = ["0", "1", "-1", "2.5", "-2.6", "200", "1e9", "-1e-6", "1e-20", "nan", "inf", "-inf", "", "abc", "1,2", "0:-4:0.2", "12"]
PATHS = ["", "{d}/afile", "{d}/afile/x.png", "{d}/nope/x.png", "{d}", "{d}/x.pdf", "{d}/x.rrd", "{d}/x.toml", PRESET,
         TABLE_2_1, "CY", "HM", "steel-steel", "zirconia-zirconia", "nope.toml"]
LAWS = ["adams-impact", "bogus", ""]  # calibrated laws: see the module doc
OVERRIDES = {"--ratio": NUMBERS, "--jar-rpm": NUMBERS, "--plate-rpm": NUMBERS, "--balls": NUMBERS, "--seed": NUMBERS,
             "--dt": NUMBERS + ["auto"], "--law": LAWS, "--pair": PATHS, "--jar": PATHS}
COMMANDS = {
    ("run", PRESET): {**OVERRIDES, "--duration": NUMBERS, "--analysis-start": NUMBERS, "--out": PATHS[:4],
                      "--rrd": PATHS[:4] + ["{d}/x.txt"], "--json": None},
    ("tui", PRESET): {**OVERRIDES, "--window": NUMBERS, "--out-dir": PATHS[:4], "--paused": None},
    ("sweep", PRESET): {"--ratio": ["-2", "-1,-2", "0:-1:0.5", "nan", "", "0:-4:0", "a,b", "-12", "1:2", "-1,-1"],
                        "--plate-rpm": ["200", "0", "100,200", "x", "5000"], "--balls": ["12", "0", "1.5", "6,12"],
                        "--pair": ["steel-steel", "", "a,,b", "nope"], "--jar": ["CY", "HM,T", "NOPE", ""],
                        "--replicas": NUMBERS, "--refine": None, "--refine-rounds": NUMBERS, "--refine-metric": ["mean_se", "bogus"],
                        "--seed": NUMBERS, "--duration": NUMBERS, "--analysis-start": NUMBERS, "--dt": NUMBERS, "--law": LAWS,
                        "--workers": NUMBERS, "--batch": NUMBERS, "--scheduler": ["", "tcp://x:1"], "--out": PATHS[:4]},
    ("calibrate", "drop"): {"--pair": PATHS, "--h0": NUMBERS, "--target": ["plate", "ball", "wall"], "--radius-mm": NUMBERS,
                            "--law": LAWS, "--figure": PATHS[:6], "--overwrite": None, "--json": None},
    ("calibrate", "fit"): {"--pair": PATHS, "--data": PATHS, "--param": ["d", "c_max", "e", "k"], "--scatter": NUMBERS,
                           "--out": PATHS[:4] + ["{d}/x.toml"], "--name": ["", "x"], "--law": LAWS, "--figure": PATHS[:6]},
    ("calibrate", "sensitivity"): {"--pair": PATHS, "--h0": NUMBERS, "--change": NUMBERS, "--law": LAWS, "--figure": PATHS[:6]},
    ("calibrate", "oblique"): {"--pair": PATHS, "--speed": NUMBERS, "--offsets": NUMBERS + ["0:12:1e-9", "5:1:1"],
                               "--law": LAWS, "--friction": None, "--figure": PATHS[:6]},
    ("jars", "show"): {"--out": PATHS[:6] + ["{d}/x.svg"], "--overwrite": None},
    ("analyse", "{d}"): {"--analysis-start": NUMBERS, "--min-un": NUMBERS, "--sampling-rate": NUMBERS, "--json": None},
    ("record", "{d}"): {"--rrd": PATHS[:4] + ["{d}/x.rrd"], "--histogram-every": NUMBERS, "--lab-frame": None},
}


@st.composite
def command_lines(draw):
    head = draw(st.sampled_from(sorted(COMMANDS)))
    options = COMMANDS[head]
    argv = list(head)
    if head == ("jars", "show"):
        argv.append(draw(st.sampled_from(PATHS)))
    for opt in draw(st.lists(st.sampled_from(sorted(options)), max_size=4, unique=True)):
        argv.append(opt)
        if options[opt] is not None:
            argv.append(draw(st.sampled_from(options[opt])))
    if head == ("calibrate", "drop") and "--h0" not in argv:
        argv += ["--h0", draw(st.sampled_from(NUMBERS[:6]))]
    if head[0] == "calibrate" and "--pair" not in argv:
        argv += ["--pair", "steel-steel"]
    if head == ("calibrate", "fit") and "--data" not in argv:
        argv += ["--data", TABLE_2_1]
    if head == ("record", "{d}") and "--rrd" not in argv:
        argv += ["--rrd", "{d}/x.rrd"]
    return argv


@fuzz(250)
@given(argv=command_lines())
def test_command_lines_are_accepted_or_one_line_exit_2(stubs, where, argv):
    from taimill.cli import main

    argv = [a.replace("{d}", str(where)) for a in argv]
    cwd = os.getcwd()
    os.chdir(where)
    try:
        import contextlib
        import io

        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(argv)
            except Accepted:
                return
    finally:
        os.chdir(cwd)
    lines = err.getvalue().splitlines()
    assert code == 2, (argv, code, err.getvalue())
    assert len(lines) == 1 and lines[0].startswith("taimill: error: "), (argv, err.getvalue())
