"""Every kind of bad input, across every subcommand, is refused the same way (docs/outputs.md,
bad input): exit code 2, exactly one line on stderr starting `taimill: error:` and naming
the option or key, no traceback, nothing on stdout, and nothing written or overwritten.

The cases are a table built from the inputs' kinds: every kind of unreadable file × every
option or key that reads a file, bad numbers × every numeric option, conflicting and
degenerate values, bad output paths × every option that writes, and broken contents of
presets, jars, pair files and CSVs. Each runs `taimill.cli.main(argv)` in this process
(argparse's own errors are one line too: `common.Parser`, so they count like any other),
with the stages that would start Taichi, spawn sweep workers or open the viewer replaced
by a stub that fails the case: bad input must be refused before them. A few representative
cases also run through the real CLI in a subprocess. "Nothing written" is checked on the
whole folder the case works in (inputs, existing outputs, the current directory): every
file keeps its bytes and modification time and no file appears.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from texts import GOOD_PRESET

ROOT = Path(__file__).resolve().parent.parent
PRESET = str(ROOT / "presets" / "p4-cy-steel.toml")
TABLE_2_1 = str(ROOT / "taimill" / "data" / "zirconia_drop_table2_1.csv")
IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0

GOOD_JAR = """\
height_mm = 24.1
wall_material = "aisi-304"
fillet_mm = 8

[[profile]]
type = "circle"
radius_mm = 32.5

[[profile]]
type = "cut"
distance_mm = 18
angle_deg = 0
"""
GOOD_PAIR = """\
[pair.mine]
contact = "mine"
mu_s = 0.5
mu_d = 0.4
v_s_mm_s = 1
v_d_mm_s = 10

[contact.mine]
ball = "steel-c1020"
wall = "aisi-304"
law = "adams-impact"
ball_radius_mm = 6
ball_ball = { c_max_Ns_per_mm = 10.1, d_mm = 0.211, e = 0.516, u_ref_mm_s = 3309 }
ball_wall = { c_max_Ns_per_mm = 17.5, d_mm = 0.211, e = 0.516, u_ref_mm_s = 3309 }
"""
GOOD_OVERLAY = "ratio,measured [mJ],measured_err\n-1,1.0,0.1\n-2,2.0,0.2\n"

# ------------------------------------------------------------------ unreadable files
# kind -> (file name stem, a word the message must contain or None)
FILE_KINDS = {
    "missing": ("missing", "no "),
    "folder": ("folder", "folder"),
    "binary": ("binary", "UTF-8"),
    "utf16": ("utf16", "UTF-8"),
    "fifo": ("fifo", "regular file"),
    "device": ("device", "regular file"),
    "symlink loop": ("loop", "symbolic links"),
    "broken symlink": ("broken", None),
    "path through a file": ("afile/x", None),
    "over 64 MiB": ("huge", "MiB"),
    "name too long": ("a" * 300, "too long"),
}
TOML_KINDS = {"syntax error": ("syntax", "not valid TOML"), "nested too deep": ("deep", "not valid TOML"),
              "empty": ("empty", None)}
CSV_KINDS = {"empty": ("empty", None)}

# option or key that reads a TOML file -> (argv with {F} for the file, word naming it)
TOML_READERS = {
    "run PRESET": (["run", "{F}", "--out", "{work}/new.zarr"], "preset"),
    "sweep PRESET": (["sweep", "{F}", "--ratio", "-2", "--out", "{work}/new.zarr"], "preset"),
    "tui PRESET": (["tui", "{F}", "--out-dir", "{work}/rec"], "preset"),
    "run --jar": (["run", PRESET, "--jar", "{F}"], "jar"),
    "run --pair": (["run", PRESET, "--pair", "{F}"], "pair"),
    "tui --jar": (["tui", PRESET, "--jar", "{F}"], "jar"),
    "tui --pair": (["tui", PRESET, "--pair", "{F}"], "pair"),
    "sweep --jar": (["sweep", PRESET, "--jar", "{F}"], "jar"),
    "sweep --pair": (["sweep", PRESET, "--pair", "{F}"], "pair"),
    "jars show NAME": (["jars", "show", "{F}", "--out", "{work}/new.png"], "jar"),
    "export liggghts PRESET": (["export", "liggghts", "{F}", "--out", "{work}/case"], "preset"),
    "export liggghts --pair": (["export", "liggghts", PRESET, "--pair", "{F}", "--out", "{work}/case"], "pair"),
    "calibrate drop --pair": (["calibrate", "drop", "--pair", "{F}", "--h0", "100"], "pair"),
    "calibrate fit --pair": (["calibrate", "fit", "--pair", "{F}", "--data", TABLE_2_1, "--out", "{work}/new.toml"], "pair"),
    "calibrate sensitivity --pair": (["calibrate", "sensitivity", "--pair", "{F}"], "pair"),
    "calibrate oblique --pair": (["calibrate", "oblique", "--pair", "{F}"], "pair"),
    "preset jar key": (["run", "{P:jar}"], "jar"),
    "preset pair key": (["run", "{P:pair}"], "pair"),
    "kinetics predict FIT": (["kinetics", "predict", "{F}", "{in}/condition.json"], "FIT"),
    "sizes predict PARAMS": (["sizes", "predict", "{F}", "{in}/kin/condition-a.json", "--feed-x50", "100"], "PARAMS"),
    "design PRESET": (["design", "{F}", "--out", "{work}/study"], "preset"),
    "wear predict --fit": (["wear", "predict", "{in}/empty.zarr", "--fit", "{F}"], "--fit"),
}
CSV_READERS = {
    "calibrate fit --data": (["calibrate", "fit", "--pair", "steel-steel", "--data", "{F}"], "--data"),
    "report --overlay": (["report", "{in}/sweep.zarr", "--overlay", "{F}"], "--overlay"),
    "preset initial_positions key": (["run", "{P:initial_positions}"], "initial_positions"),
    "kinetics fit POINTS": (["kinetics", "fit", "{F}", "--out", "{work}/new.toml"], "POINTS"),
    "sizes check SIZES": (["sizes", "check", "{F}"], "SIZES"),
    "wear fit MEASURED": (["wear", "fit", "{F}", "--out", "{work}/new.toml"], "MEASURED"),
}


def _file_cases():
    cases = []
    for readers, ext, contents in ((TOML_READERS, "toml", TOML_KINDS), (CSV_READERS, "csv", CSV_KINDS)):
        for opt, (argv, key) in readers.items():
            for kind, (stem, word) in {**FILE_KINDS, **contents}.items():
                path = f"{{in}}/bad/{stem}.{ext}"
                # a file that cannot be read is named with the option; one read but wrong, by its name
                named = f"{stem}.{ext}" if kind in contents else key
                cases.append((f"{opt}: {kind}", argv, path, [named] + ([word] if word else [])))
    out = []
    for name, argv, path, words in cases:
        if any("{P:" in a for a in argv):  # a preset naming the bad file under that key
            key = next(a for a in argv if "{P:" in a)[3:-1]
            argv = [a.replace(f"{{P:{key}}}", f"{{in}}/presets/ref-{key}-{Path(path).stem[:20]}-{Path(path).parent.name}.toml")
                    for a in argv]
            out.append((name, argv, words, {"ref": (key, path)}))
        else:
            out.append((name, [a.replace("{F}", path) for a in argv], words, {}))
    return out


# ------------------------------------------------------------------ numbers and values
FLOAT_JUNK = {"nan": "nan", "inf": "inf", "text": "abc", "empty": ""}
INT_JUNK = {"text": "abc", "fraction": "1.5", "empty": ""}
RUN = ["run", PRESET, "--out", "{work}/new.zarr"]
TUI = ["tui", PRESET, "--out-dir", "{work}/rec"]
SWEEP = ["sweep", PRESET, "--out", "{work}/new.zarr"]
ADVISE = ["advise", PRESET, "--plate-rpm", "100,200", "--out", "{work}/new.zarr"]
ANALYSE = ["analyse", "{in}/empty.zarr"]
REPORT = ["report", "{in}/empty.zarr", "--out", "{work}/rep"]
RECORD = ["record", "{in}/empty.zarr", "--rrd", "{work}/new.rrd"]
DROP = ["calibrate", "drop", "--pair", "steel-steel", "--h0", "100", "--figure", "{work}/new.png"]
FIT = ["calibrate", "fit", "--pair", "zirconia-zirconia", "--data", TABLE_2_1, "--out", "{work}/new.toml"]
SENS = ["calibrate", "sensitivity", "--pair", "steel-steel", "--figure", "{work}/new.png"]
KIN_FIT = ["kinetics", "fit", "{in}/kin/points.csv", "--out", "{work}/new.toml"]
KIN_PREDICT = ["kinetics", "predict", "{in}/kin/fit.toml", "{in}/kin/condition-c.json"]
OBLIQUE = ["calibrate", "oblique", "--pair", "steel-steel", "--figure", "{work}/new.png"]
# (command, option, float or int) for argparse-typed numbers
TYPED_NUMBERS = [
    (RUN, "--ratio", float), (RUN, "--jar-rpm", float), (RUN, "--plate-rpm", float), (RUN, "--balls", int),
    (RUN, "--seed", int), (RUN, "--duration", float), (RUN, "--analysis-start", float),
    (TUI, "--ratio", float), (TUI, "--plate-rpm", float), (TUI, "--balls", int), (TUI, "--window", float),
    (SWEEP + ["--ratio", "-2"], "--seed", int), (SWEEP + ["--ratio", "-2"], "--duration", float),
    (SWEEP + ["--ratio", "-2"], "--analysis-start", float), (SWEEP, "--replicas", int), (SWEEP, "--refine-rounds", int),
    (SWEEP, "--workers", int), (SWEEP, "--batch", int),
    (ADVISE, "--duration", float), (ADVISE, "--powder-mass", float), (ADVISE, "--replicas", int),
    (ANALYSE, "--analysis-start", float), (ANALYSE, "--min-un", float), (ANALYSE, "--sampling-rate", float),
    (REPORT, "--min-un", float), (REPORT, "--sampling-rate", float),
    (RECORD, "--histogram-every", float),
    (["calibrate", "drop", "--pair", "steel-steel"], "--h0", float), (DROP, "--radius-mm", float),
    (FIT, "--scatter", float), (SENS, "--h0", float), (SENS, "--change", float), (OBLIQUE, "--speed", float),
]


def _typed_cases():
    out = []
    for base, opt, kind in TYPED_NUMBERS:
        for junk, value in (FLOAT_JUNK if kind is float else INT_JUNK).items():
            out.append((f"{base[0]}{' ' + base[1] if base[0] == 'calibrate' else ''} {opt}: {junk}",
                        base + [opt, value], [opt]))
    return out


# (name, argv, words)
VALUES = [
    # heat: a store that is none, a programme or limit out of range
    ("heat predict a file that is no store", ["heat", "predict", "{in}/afile.zarr", "--powder-cp", "1200"], ["afile.zarr"]),
    ("heat predict no config", ["heat", "predict", "{in}/noconfig.zarr", "--powder-cp", "1200"], ["noconfig.zarr"]),
    ("heat predict --programme 0:5", ["heat", "predict", "{in}/noconfig.zarr", "--programme", "0:5"], ["--programme"]),
    # the LIGGGHTS bridge: the same overrides and output checks as run
    ("export liggghts --ratio nan", ["export", "liggghts", PRESET, "--ratio", "nan", "--out", "{work}/case"], ["--ratio", "finite"]),
    ("export liggghts --plate-rpm 0", ["export", "liggghts", PRESET, "--plate-rpm", "0", "--out", "{work}/case"], ["plate_rpm", "undefined"]),
    ("export liggghts --out empty", ["export", "liggghts", PRESET, "--out", ""], ["--out", "empty"]),
    ("export liggghts --out unwritable", ["export", "liggghts", PRESET, "--out", "{RO}/case"], ["--out", "not writable"]),
    ("export liggghts no --out", ["export", "liggghts", PRESET], ["--out", "required"]),
    ("import liggghts DIR missing", ["import", "liggghts", "{in}/nocase", "--out", "{work}/imp.zarr"], ["DIR", "nocase"]),
    ("import liggghts DIR not a case", ["import", "liggghts", "{in}", "--out", "{work}/imp.zarr"], ["DIR", "taimill-case.json"]),
    ("import liggghts --out empty", ["import", "liggghts", "{in}", "--out", ""], ["--out", "empty"]),
    ("compare one store", ["compare", "{in}/noconfig.zarr"], ["required"]),
    ("compare --min-un nan", ["compare", "{in}/noconfig.zarr", "{in}/noconfig.zarr", "--min-un", "nan"], ["--min-un", "finite"]),
    ("compare --min-un negative", ["compare", "{in}/noconfig.zarr", "{in}/noconfig.zarr", "--min-un", "-1"], ["--min-un", "allowed range"]),
    ("compare --analysis-start negative", ["compare", "{in}/noconfig.zarr", "{in}/noconfig.zarr", "--analysis-start", "-2"],
     ["--analysis-start", "allowed range"]),
    # the preset overrides of run: each goes through the preset loader's range checks
    ("run --ratio above 10", RUN + ["--ratio", "11"], ["ratio", "11", "[-10, 10]"]),
    ("run --ratio -1e300", RUN + ["--ratio", "-1e300"], ["ratio", "allowed range"]),
    ("run --jar-rpm beyond 3000", RUN + ["--jar-rpm", "1e6"], ["jar_rpm", "[-3000, 3000]"]),
    ("run --plate-rpm 0", RUN + ["--plate-rpm", "0"], ["plate_rpm", "0", "allowed range", "undefined"]),
    ("run --plate-rpm -0", RUN + ["--plate-rpm", "-0"], ["plate_rpm", "allowed range"]),
    ("run --plate-rpm 5000", RUN + ["--plate-rpm", "5000"], ["plate_rpm", "[-1000, 1000]"]),
    ("run --plate-rpm -5000", RUN + ["--plate-rpm", "-5000"], ["plate_rpm", "[-1000, 1000]"]),
    ("run --plate-rpm 1000 --ratio 10: jar at 9000 rpm", RUN + ["--plate-rpm", "1000", "--ratio", "10"],
     ["ratio", "10", "allowed range [-2, 4]", "9000 rpm", "[-3000, 3000]"]),
    ("run --plate-rpm -1000 --ratio -10: jar at 11000 rpm", RUN + ["--plate-rpm", "-1000", "--ratio", "-10"],
     ["ratio", "-10", "allowed range [-2, 4]", "11000 rpm"]),
    ("run --ratio with --jar-rpm", RUN + ["--ratio", "-2", "--jar-rpm", "100"], ["--jar-rpm", "--ratio", "not both"]),
    # mills: unknown, a fixed gear with a jar speed, a plate speed beyond the mill's, a bowl it does not take
    ("mills: unknown name", ["mills", "no-such-mill"], ["mill", "no-such-mill", "known mills", "retsch-pm100"]),
    ("run --mill unknown", RUN + ["--mill", "no-such-mill"], ["mill", "no-such-mill", "known mills"]),
    ("run --mill fixed gear with --ratio", RUN + ["--mill", "retsch-pm100", "--ratio", "-2"],
     ["ratio", "retsch-pm100 has a fixed gear 1:-2 (K = -1)", "cannot be set"]),
    ("run --jar-volume the mill lacks", RUN + ["--jar-volume", "33"], ["jar_volume_ml", "33", "fritsch-p4", "80, 250, 500 ml"]),
    ("run --jar-rpm with --ratio", RUN + ["--jar-rpm", "-700", "--ratio", "-2.6"], ["--jar-rpm", "not both"]),
    ("run --balls 0", RUN + ["--balls", "0"], ["balls.count", "[1,"]),
    ("run --balls negative", RUN + ["--balls", "-3"], ["balls.count", "-3"]),
    ("run --balls beyond the range", RUN + ["--balls", "10000000"], ["balls.count", "allowed range"]),
    ("run --balls overfill", RUN + ["--balls", "500"], ["balls.count", "45%"]),
    ("run --seed negative", RUN + ["--seed", "-1"], ["seed", "-1"]),
    ("run --seed 2**64", RUN + ["--seed", str(2**64)], ["seed", "allowed range"]),
    ("run --duration 0", RUN + ["--duration", "0"], ["duration", "(0,"]),
    ("run --duration negative", RUN + ["--duration", "-1"], ["duration", "-1"]),
    ("run --duration 1e6", RUN + ["--duration", "1e6"], ["duration", "36000"]),
    # one rule for time (rules.frames_fit, rules.auto_steps): a run shorter than one frame interval was
    # stretched to one (0.01 s); an automatic step leading to more than 1e10 steps started without a word
    ("run --duration 1e-12", RUN + ["--duration", "1e-12"], ["duration", "1e-12", "allowed range [0.01, 36000] s", "frame"]),
    ("run --duration below one frame", RUN + ["--duration", "0.004"], ["duration", "0.004", "[0.01, 36000]", "100 Hz"]),
    ("run --duration 36000: auto dt over 1e10 steps", RUN + ["--duration", "36000"],
     ["duration", "36000", "allowed range (0,", "automatic dt", "at most 1e+10"]),
    ("run --analysis-start negative", RUN + ["--analysis-start", "-1"], ["analysis_start", "-1"]),
    ("run --analysis-start after the end", RUN + ["--analysis-start", "1e5"], ["analysis_start", "allowed range"]),
    ("run --dt text", RUN + ["--dt", "fast"], ["dt", "fast", "'auto'"]),
    ("run --dt empty", RUN + ["--dt", ""], ["dt", "'auto'"]),
    ("run --dt nan", RUN + ["--dt", "nan"], ["dt", "'auto'"]),
    ("run --dt inf", RUN + ["--dt", "inf"], ["dt", "'auto'"]),
    ("run --dt 0", RUN + ["--dt", "0"], ["dt", "'auto'"]),
    ("run --dt negative", RUN + ["--dt", "-1e-6"], ["dt", "'auto'"]),
    ("run --dt too large", RUN + ["--dt", "1e-3"], ["dt", "steps per contact"]),
    ("run --dt 1e15 steps", RUN + ["--dt", "2.4e-14"], ["dt", "steps for duration", "at most 1e+10"]),
    ("run --law unknown", RUN + ["--law", "bogus"], ["law", "bogus", "adams-impact"]),
    ("run --law empty", RUN + ["--law", ""], ["law", "adams-impact"]),
    ("run --pair unknown", RUN + ["--pair", "steel-unobtainium"], ["pair", "steel-steel"]),
    ("run --pair empty", RUN + ["--pair", ""], ["--pair", "empty"]),
    ("run --pair blank", RUN + ["--pair", "  "], ["--pair", "empty"]),
    ("run --ball-material unknown", RUN + ["--ball-material", "gold"], ["balls.material", "gold", "zirconia"]),
    ("run --ball-diameter too large", RUN + ["--ball-diameter", "500"], ["balls.diameter_mm", "500", "allowed range"]),
    ("run --jar-material unknown", RUN + ["--jar-material", "oak"], ["jar_material", "oak", "aisi-304"]),
    ("run --jar unknown", RUN + ["--jar", "NOPE"], ["jar", "NOPE", "known jars"]),
    ("run --jar empty", RUN + ["--jar", ""], ["--jar", "empty"]),
    ("run unknown option", RUN + ["--json", "--bogus"], ["unrecognized", "--bogus"]),
    # regime-map sweeps: friction axes and the map figure
    ("sweep --mu negative", SWEEP + ["--ratio", "-2", "--mu", "0.2,-0.1"], ["friction.mu_s", "-0.1", "[0, 10]"]),
    ("sweep --mu words", SWEEP + ["--ratio", "-2", "--mu", "low"], ["--mu", "low", "numbers"]),
    ("sweep --mu-r too large", SWEEP + ["--ratio", "-2", "--mu-r", "0,20"], ["friction.mu_r", "20", "[0, 10]"]),
    ("sweep --mu-r nan", SWEEP + ["--ratio", "-2", "--mu-r", "nan"], ["--mu-r", "finite"]),
    ("sweep --pair-ball-wall unknown", SWEEP + ["--ratio", "-2", "--pair-ball-wall", "steel-butter"],
     ["pair_ball_wall", "steel-butter", "steel-fluorite"]),
    ("sweep --pair-ball-wall other contact set", SWEEP + ["--ratio", "-2", "--pair-ball-wall", "zirconia-zirconia"],
     ["pair_ball_wall", "zirconia-zirconia", "contact set"]),
    ("sweep --map not png", SWEEP + ["--ratio", "-2", "--map", "{work}/map.txt"], ["--map", ".png"]),
    ("sweep --map missing folder", SWEEP + ["--ratio", "-2", "--map", "{work}/nope/map.png"], ["--map", "does not exist"]),
    ("sweep --map existing", SWEEP + ["--ratio", "-2", "--map", "{work}/existing.png"], ["--map", "--overwrite"]),
    ("run without PRESET, a bad option", ["run", "--balls", "0"], ["balls.count", "0"]),
    ("run PRESET empty", ["run", ""], ["preset", "empty"]),
    ("run PRESET NUL", ["run", "a\0b.toml"], ["preset", "NUL"]),
    ("run --out empty", ["run", PRESET, "--out", ""], ["--out", "empty"]),
    ("run --out missing folder", ["run", PRESET, "--out", "{work}/nope/new.zarr"], ["--out", "does not exist"]),
    ("run --out under a file", ["run", PRESET, "--out", "{work}/afile/new.zarr"], ["--out", "afile"]),
    ("run --out unwritable folder", ["run", PRESET, "--out", "{RO}/new.zarr"], ["--out", "not writable"]),
    ("run --rrd empty", ["run", PRESET, "--rrd", ""], ["--rrd", "empty"]),
    ("run --rrd not .rrd", ["run", PRESET, "--rrd", "{work}/new.txt"], ["--rrd", ".rrd"]),
    ("run --rrd missing folder", ["run", PRESET, "--rrd", "{work}/nope/new.rrd"], ["--rrd", "does not exist"]),
    ("run --rrd existing", ["run", PRESET, "--rrd", "{work}/existing.rrd"], ["--rrd", "--overwrite"]),
    ("run --rrd a folder", ["run", PRESET, "--rrd", "{work}/adir.rrd", "--overwrite"], ["--rrd", "folder"]),
    # tui: its own options and the overrides a live mill takes
    ("tui --duration not taken", TUI + ["--duration", "3"], ["unrecognized", "--duration"]),
    # the backend: a name that is none, on every command that runs kernels (cuda without a device: test_backend.py)
    ("run --backend unknown", RUN + ["--backend", "gpu"], ["--backend", "'gpu'", "one of cpu", "cuda", "auto"]),
    ("sweep --backend unknown", SWEEP + ["--ratio", "-2", "--backend", "opencl"], ["--backend", "'opencl'", "one of cpu"]),
    ("design --backend unknown", ["design", PRESET, "--out", "{work}/study", "--backend", "metal"],
     ["--backend", "'metal'", "one of cpu"]),
    ("tui --backend unknown", TUI + ["--backend", "vulkan"], ["--backend", "'vulkan'", "one of cpu"]),
    ("run --backend empty", RUN + ["--backend", ""], ["--backend", "one of cpu"]),
    ("tui --analysis-start not taken", TUI + ["--analysis-start", "1"], ["unrecognized", "--analysis-start"]),
    ("tui --window 0", TUI + ["--window", "0"], ["--window", "[0.1, 600]"]),
    ("tui --window 1e9", TUI + ["--window", "1e9"], ["--window", "[0.1, 600]"]),
    ("tui --plate-rpm 0", TUI + ["--plate-rpm", "0"], ["plate_rpm", "undefined"]),
    ("tui --ratio with --jar-rpm", TUI + ["--ratio", "-2", "--jar-rpm", "100"], ["--jar-rpm", "not both"]),
    ("tui --balls 0", TUI + ["--balls", "0"], ["balls.count"]),
    ("tui --dt 1e15 steps", TUI + ["--dt", "1e-20"], ["dt", "steps for duration"]),
    ("tui --law unknown", TUI + ["--law", "bogus"], ["law", "bogus"]),
    ("tui --out-dir empty", ["tui", PRESET, "--out-dir", ""], ["--out-dir", "empty"]),
    ("tui --out-dir a file", ["tui", PRESET, "--out-dir", "{work}/afile"], ["--out-dir", "not a folder"]),
    ("tui --out-dir under a file", ["tui", PRESET, "--out-dir", "{work}/afile/rec"], ["--out-dir", "not a folder"]),
    ("tui --out-dir unwritable", ["tui", PRESET, "--out-dir", "{RO}/rec"], ["--out-dir", "not writable"]),
    # sweep: swept values, replicas, refinement, execution, store
    ("sweep --ratio step 0", SWEEP + ["--ratio", "0:-4:0"], ["--ratio", "STEP"]),
    ("sweep --ratio two parts", SWEEP + ["--ratio", "1:2"], ["--ratio", "A:B:STEP"]),
    ("sweep --ratio text list", SWEEP + ["--ratio", "a,b"], ["--ratio", "numbers"]),
    ("sweep --ratio repeated", SWEEP + ["--ratio", "-1,-1"], ["--ratio", "repeated"]),
    ("sweep --ratio too many values", SWEEP + ["--ratio", "0:-4000:0.0001"], ["--ratio", "at most"]),
    ("sweep --ratio nan", SWEEP + ["--ratio", "nan"], ["--ratio", "finite"]),
    ("sweep --ratio range too wide to count", SWEEP + ["--ratio", "0:1e308:1e-308"], ["--ratio", "at most 10000"]),
    ("sweep --ratio nan in a range", SWEEP + ["--ratio", "0:nan:1"], ["--ratio", "finite"]),
    ("sweep --ratio empty", SWEEP + ["--ratio", ""], ["--ratio"]),
    ("sweep --ratio out of range", SWEEP + ["--ratio", "-12,-2"], ["ratio", "-12", "[-10, 10]"]),
    ("sweep --plate-rpm 0", SWEEP + ["--ratio", "-2", "--plate-rpm", "0,100"], ["plate_rpm", "undefined"]),
    ("sweep --plate-rpm 5000", SWEEP + ["--ratio", "-2", "--plate-rpm", "5000"], ["plate_rpm", "[-1000, 1000]"]),
    ("sweep --plate-rpm text", SWEEP + ["--ratio", "-2", "--plate-rpm", "x"], ["--plate-rpm"]),
    ("sweep --balls 0", SWEEP + ["--ratio", "-2", "--balls", "0"], ["balls.count"]),
    ("sweep --balls fraction", SWEEP + ["--ratio", "-2", "--balls", "1.5"], ["--balls", "integers"]),
    ("sweep --balls text", SWEEP + ["--ratio", "-2", "--balls", "x"], ["--balls"]),
    ("sweep --pair empty", SWEEP + ["--ratio", "-2", "--pair", ""], ["--pair"]),
    ("sweep --pair empty entry", SWEEP + ["--ratio", "-2", "--pair", "steel-steel,,steel-fluorite"], ["--pair", "empty entry"]),
    ("sweep --pair unknown", SWEEP + ["--ratio", "-2", "--pair", "nope"], ["pair", "nope"]),
    ("sweep --jar unknown", SWEEP + ["--ratio", "-2", "--jar", "CY,NOPE"], ["jar", "NOPE"]),
    ("sweep --replicas 0", SWEEP + ["--ratio", "-2", "--replicas", "0"], ["--replicas", "[1, 1000]"]),
    ("sweep --replicas 1001", SWEEP + ["--ratio", "-2", "--replicas", "1001"], ["--replicas", "[1, 1000]"]),
    ("sweep --refine-rounds 0", SWEEP + ["--ratio", "-2", "--refine-rounds", "0"], ["--refine-rounds", "[1, 10]"]),
    ("sweep --refine-rounds 11", SWEEP + ["--ratio", "-2", "--refine-rounds", "11"], ["--refine-rounds", "[1, 10]"]),
    ("sweep --refine with two K", SWEEP + ["--ratio", "-1,-2", "--refine", "--refine-metric", "mean_se"], ["--ratio", "at least 3"]),
    ("sweep --refine-metric unknown", SWEEP + ["--ratio", "-2", "--refine-metric", "bogus"], ["--refine-metric", "bogus"]),
    ("sweep --workers 0", SWEEP + ["--ratio", "-2", "--workers", "0"], ["--workers", "[1, 256]"]),
    ("sweep --workers 300", SWEEP + ["--ratio", "-2", "--workers", "300"], ["--workers", "[1, 256]"]),
    ("sweep --workers with --scheduler", SWEEP + ["--ratio", "-2", "--workers", "2", "--scheduler", "tcp://x:1"], ["--workers", "--scheduler"]),
    ("sweep --scheduler empty", SWEEP + ["--ratio", "-2", "--scheduler", ""], ["--scheduler", "empty"]),
    ("sweep --batch 0", SWEEP + ["--ratio", "-2", "--batch", "0"], ["--batch", "[1, 64]"]),
    ("sweep --batch 65", SWEEP + ["--ratio", "-2", "--batch", "65"], ["--batch", "[1, 64]"]),
    ("sweep --seed negative", SWEEP + ["--ratio", "-2", "--seed", "-1"], ["seed", "-1"]),
    ("sweep --duration 0", SWEEP + ["--ratio", "-2", "--duration", "0"], ["duration"]),
    ("sweep --analysis-start negative", SWEEP + ["--ratio", "-2", "--analysis-start", "-1"], ["analysis_start"]),
    ("sweep --dt 1e15 steps", SWEEP + ["--ratio", "-2", "--dt", "1e-20"], ["dt", "steps for duration"]),
    ("sweep --dt text", SWEEP + ["--ratio", "-2", "--dt", "fast"], ["dt", "'auto'"]),
    ("sweep --law unknown", SWEEP + ["--ratio", "-2", "--law", "bogus"], ["law", "bogus"]),
    ("sweep --jar-rpm not taken", SWEEP + ["--ratio", "-2", "--jar-rpm", "100"], ["unrecognized", "--jar-rpm"]),
    ("sweep --out empty", ["sweep", PRESET, "--ratio", "-2", "--out", ""], ["--out", "empty"]),
    ("sweep --out missing folder", ["sweep", PRESET, "--ratio", "-2", "--out", "{work}/nope/s.zarr"], ["--out", "does not exist"]),
    ("sweep --out under a file", ["sweep", PRESET, "--ratio", "-2", "--out", "{work}/afile/s.zarr"], ["--out", "afile"]),
    # advise: the measure, the speeds (the thesis' P 4 states no range), μ, replicas, the figure
    ("advise --measure unknown", ADVISE + ["--measure", "bogus"], ["--measure", "bogus", "dissipated_power"]),
    ("advise --measure per gram without powder", ADVISE + ["--measure", "specific_power_W_per_g"],
     ["--measure", "--powder-mass"]),
    ("advise no speeds on a mill without a range", ["advise", PRESET], ["--plate-rpm", "fritsch-p4", "give the speeds"]),
    ("advise --plate-rpm outside the mill's", ["advise", PRESET, "--mill", "retsch-pm100", "--plate-rpm", "50,300"],
     ["plate_rpm", "50", "[100, 650]"]),
    ("advise --plate-rpm words", ADVISE[:2] + ["--plate-rpm", "fast"], ["--plate-rpm", "fast", "numbers"]),
    ("advise --mu negative", ADVISE + ["--mu", "0.2,-0.1"], ["friction.mu_s", "-0.1", "[0, 10]"]),
    ("advise --replicas 0", ADVISE + ["--replicas", "0"], ["--replicas", "[1, 1000]"]),
    ("advise --workers 0", ADVISE + ["--workers", "0"], ["--workers", "[1, 256]"]),
    ("advise --figure not png", ADVISE + ["--figure", "{work}/advice.txt"], ["--figure", ".png"]),
    ("advise --figure existing", ADVISE + ["--figure", "{work}/existing.png"], ["--figure", "--overwrite"]),
    ("advise --out missing folder", ADVISE[:4] + ["--out", "{work}/nope/a.zarr"], ["--out", "does not exist"]),
    # analyse and report: the options, then the store
    ("analyse --analysis-start negative", ANALYSE + ["--analysis-start", "-1"], ["--analysis-start", "-1"]),
    ("analyse --min-un negative", ANALYSE + ["--min-un", "-1"], ["--min-un", "[0,"]),
    ("analyse --min-un 1e9", ANALYSE + ["--min-un", "1e9"], ["--min-un", "[0,"]),
    ("analyse --sampling-rate 0", ANALYSE + ["--sampling-rate", "0"], ["--sampling-rate", "(0,"]),
    ("analyse --sampling-rate negative", ANALYSE + ["--sampling-rate", "-5"], ["--sampling-rate", "(0,"]),
    ("analyse --sampling-rate 1e9", ANALYSE + ["--sampling-rate", "1e9"], ["--sampling-rate", "(0,"]),
    ("report --analysis-start negative", REPORT + ["--analysis-start", "-1"], ["--analysis-start"]),
    ("report --format unknown", REPORT + ["--format", "gif"], ["--format", "gif"]),
    ("report --out empty", ["report", "{in}/empty.zarr", "--out", ""], ["--out", "empty"]),
    ("report --out a file", ["report", "{in}/empty.zarr", "--out", "{work}/afile"], ["--out", "not a folder"]),
    ("report --out under a file", ["report", "{in}/empty.zarr", "--out", "{work}/afile/rep"], ["--out", "not a folder"]),
    ("report --out unwritable", ["report", "{in}/empty.zarr", "--out", "{RO}/rep"], ["--out", "not writable"]),
    ("report --out holding a run figure", ["report", "{in}/empty.zarr", "--out", "{work}/figs"], ["--out", "trajectories.png", "--overwrite"]),
    ("report --out holding a run figure (svg)", ["report", "{in}/empty.zarr", "--out", "{work}/figs", "--format", "svg"], ["--out", "overview.svg", "--overwrite"]),
    ("report --out holding a sweep figure", ["report", "{in}/sweep.zarr", "--out", "{work}/figs"], ["--out", "mean_se.png", "--overwrite"]),
    ("report --out holding a folder named as a figure", ["report", "{in}/empty.zarr", "--out", "{work}/figs", "--format", "pdf", "--overwrite"],
     ["--out", "energy.pdf", "folder"]),
    ("report --overlay on a run store", ["report", "{in}/empty.zarr", "--out", "{work}/rep", "--overlay", "{in}/overlay.csv"], ["--overlay", "sweep"]),
    ("report --overlay empty name", ["report", "{in}/sweep.zarr", "--overlay", ""], ["--overlay", "empty"]),
    # record and view
    ("record --rrd empty", ["record", "{in}/empty.zarr", "--rrd", ""], ["--rrd", "empty"]),
    ("record --rrd not .rrd", ["record", "{in}/empty.zarr", "--rrd", "{work}/new.txt"], ["--rrd", ".rrd"]),
    ("record --rrd missing folder", ["record", "{in}/empty.zarr", "--rrd", "{work}/nope/x.rrd"], ["--rrd", "does not exist"]),
    ("record --rrd unwritable", ["record", "{in}/empty.zarr", "--rrd", "{RO}/x.rrd"], ["--rrd", "not writable"]),
    ("record --rrd existing", ["record", "{in}/empty.zarr", "--rrd", "{work}/existing.rrd"], ["--rrd", "--overwrite"]),
    ("record --rrd a folder", ["record", "{in}/empty.zarr", "--rrd", "{work}/adir.rrd", "--overwrite"], ["--rrd", "folder"]),
    ("record without --rrd", ["record", "{in}/empty.zarr"], ["required", "--rrd"]),
    ("record --histogram-every 0", RECORD + ["--histogram-every", "0"], ["--histogram-every"]),
    ("record --histogram-every negative", RECORD + ["--histogram-every", "-1"], ["--histogram-every"]),
    ("view empty", ["view", ""], ["RUN.rrd", "empty"]),
    ("view missing", ["view", "{work}/missing.rrd"], ["RUN.rrd", "no such file"]),
    ("view a folder", ["view", "{work}/adir.rrd"], ["RUN.rrd", "regular file"]),
    ("view a fifo", ["view", "{in}/bad/fifo.toml"], ["RUN.rrd", "regular file"]),
    ("view a device", ["view", "{in}/bad/device.toml"], ["RUN.rrd", "regular file"]),
    ("view name too long", ["view", "{work}/" + "a" * 300 + ".rrd"], ["RUN.rrd", "no such file"]),
    # calibrate
    ("calibrate without experiment", ["calibrate"], ["required", "experiment"]),
    ("calibrate unknown experiment", ["calibrate", "bounce"], ["invalid choice", "bounce"]),
    ("calibrate drop without --h0", ["calibrate", "drop", "--pair", "steel-steel"], ["required", "--h0"]),
    ("calibrate drop without --pair", ["calibrate", "drop", "--h0", "100"], ["required", "--pair"]),
    ("calibrate drop --h0 0", DROP[:4] + ["--h0", "0"], ["--h0", "(0, 10000]"]),
    ("calibrate drop --h0 negative second", DROP[:4] + ["--h0", "100", "-50"], ["--h0", "-50"]),
    ("calibrate drop --h0 above 10 m", DROP[:4] + ["--h0", "1e9"], ["--h0", "(0, 10000]"]),
    ("calibrate drop --radius-mm 0", DROP + ["--radius-mm", "0"], ["--radius-mm", "(0, 100]"]),
    ("calibrate drop --radius-mm 200", DROP + ["--radius-mm", "200"], ["--radius-mm", "(0, 100]"]),
    ("calibrate drop --target unknown", DROP + ["--target", "wall"], ["--target", "wall"]),
    ("calibrate drop --law unknown", DROP + ["--law", "bogus"], ["law", "bogus"]),
    ("calibrate drop --pair unknown", ["calibrate", "drop", "--pair", "steel-unobtainium", "--h0", "100"], ["pair", "steel-steel"]),
    ("calibrate drop --pair empty", ["calibrate", "drop", "--pair", "", "--h0", "100"], ["--pair", "empty"]),
    ("calibrate drop --figure empty", DROP[:6] + ["--figure", ""], ["--figure", "empty"]),
    ("calibrate drop --figure .pdf", DROP[:6] + ["--figure", "{work}/x.pdf"], ["--figure", ".png or .svg"]),
    ("calibrate drop --figure no suffix", DROP[:6] + ["--figure", "{work}/x"], ["--figure", ".png or .svg"]),
    ("calibrate drop --figure missing folder", DROP[:6] + ["--figure", "{work}/nope/x.png"], ["--figure", "does not exist"]),
    ("calibrate drop --figure unwritable", DROP[:6] + ["--figure", "{RO}/x.png"], ["--figure", "not writable"]),
    ("calibrate drop --figure existing", DROP[:6] + ["--figure", "{work}/existing.png"], ["--figure", "--overwrite"]),
    ("calibrate drop --figure a folder", DROP[:6] + ["--figure", "{work}/adir.png", "--overwrite"], ["--figure", "folder"]),
    ("calibrate fit without --data", ["calibrate", "fit", "--pair", "steel-steel"], ["required", "--data"]),
    ("calibrate fit --scatter 0", FIT + ["--scatter", "0"], ["--scatter", "(0, 1]"]),
    ("calibrate fit --scatter 2", FIT + ["--scatter", "2"], ["--scatter", "(0, 1]"]),
    ("calibrate fit --param unknown", FIT + ["--param", "k"], ["--param", "'k'"]),
    ("calibrate fit --name empty", FIT + ["--name", ""], ["--name", "empty"]),
    ("calibrate fit --out not .toml", FIT[:6] + ["--out", "{work}/x.txt"], ["--out", ".toml"]),
    ("calibrate fit --out empty", FIT[:6] + ["--out", ""], ["--out", "empty"]),
    ("calibrate fit --out existing", FIT[:6] + ["--out", "{work}/existing.toml"], ["--out", "--overwrite"]),
    ("calibrate fit --out missing folder", FIT[:6] + ["--out", "{work}/nope/x.toml"], ["--out", "does not exist"]),
    ("calibrate fit --out a folder", FIT[:6] + ["--out", "{work}/adir.toml", "--overwrite"], ["--out", "folder"]),
    ("calibrate fit --figure existing", FIT + ["--figure", "{work}/existing.svg"], ["--figure", "--overwrite"]),
    ("calibrate sensitivity --h0 0", SENS + ["--h0", "0"], ["--h0", "(0, 10000]"]),
    ("calibrate sensitivity --change 0", SENS + ["--change", "0"], ["--change", "(0, 99]"]),
    ("calibrate sensitivity --change 100", SENS + ["--change", "100"], ["--change", "(0, 99]"]),
    ("calibrate sensitivity --change negative", SENS + ["--change", "-5"], ["--change", "(0, 99]"]),
    ("calibrate sensitivity --target unknown", SENS + ["--target", "wall"], ["--target"]),
    ("calibrate sensitivity --figure existing", SENS[:4] + ["--figure", "{work}/existing.png"], ["--figure", "--overwrite"]),
    ("calibrate oblique --speed 0", OBLIQUE + ["--speed", "0"], ["--speed", "(0, 100000]"]),
    ("calibrate oblique --speed negative", OBLIQUE + ["--speed", "-1"], ["--speed"]),
    ("calibrate oblique --speed 1e9", OBLIQUE + ["--speed", "1e9"], ["--speed", "(0, 100000]"]),
    ("calibrate oblique --offsets step 0", OBLIQUE + ["--offsets", "0:12:0"], ["--offsets", "STEP > 0"]),
    ("calibrate oblique --offsets text", OBLIQUE + ["--offsets", "a"], ["--offsets", "A:B:STEP"]),
    ("calibrate oblique --offsets beyond grazing", OBLIQUE + ["--offsets", "0,13"], ["--offsets", "13", "[0, 12]"]),
    ("calibrate oblique --offsets negative", OBLIQUE + ["--offsets", "-1"], ["--offsets", "-1"]),
    ("calibrate oblique --offsets tiny step", OBLIQUE + ["--offsets", "0:12:1e-9"], ["--offsets", "at most 1000"]),
    ("calibrate oblique --offsets inf", OBLIQUE + ["--offsets", "0:inf:1"], ["--offsets", "A:B:STEP"]),
    ("calibrate oblique --offsets negative range", OBLIQUE + ["--offsets", "-1e308:1e308:1"], ["--offsets", "at most 1000"]),
    ("calibrate oblique --offsets empty range", OBLIQUE + ["--offsets", "5:1:1"], ["--offsets", "1 to 1000"]),
    ("calibrate oblique --offsets empty", OBLIQUE + ["--offsets", ""], ["--offsets"]),
    ("calibrate oblique --offsets nan", OBLIQUE + ["--offsets", "nan"], ["--offsets"]),
    ("calibrate oblique --figure existing", OBLIQUE[:4] + ["--figure", "{work}/existing.png"], ["--figure", "--overwrite"]),
    # jars, presets, the top level
    ("jars show unknown", ["jars", "show", "NOPE", "--out", "{work}/new.png"], ["jar", "NOPE", "known jars"]),
    ("jars show empty name", ["jars", "show", ""], ["name", "empty"]),
    ("materials unknown", ["materials", "gold"], ["material", "gold", "zirconia"]),
    ("materials empty name", ["materials", ""], ["name", "empty"]),
    ("jars show without name", ["jars", "show"], ["required", "name"]),
    ("jars show --out .pdf", ["jars", "show", "CY", "--out", "{work}/x.pdf"], ["--out", ".png or .svg"]),
    ("jars show --out empty", ["jars", "show", "CY", "--out", ""], ["--out", "empty"]),
    ("jars show --out missing folder", ["jars", "show", "CY", "--out", "{work}/nope/x.png"], ["--out", "does not exist"]),
    ("jars show --out unwritable", ["jars", "show", "CY", "--out", "{RO}/x.png"], ["--out", "not writable"]),
    ("jars show --out existing", ["jars", "show", "CY", "--out", "{work}/existing.svg"], ["--out", "--overwrite"]),
    ("jars show default out existing", ["jars", "show", "HM"], ["--out", "jar-HM.png", "--overwrite"]),
    ("jars show --out a folder", ["jars", "show", "CY", "--out", "{work}/adir.png", "--overwrite"], ["--out", "folder"]),
    ("jars unknown subcommand", ["jars", "draw", "CY"], ["invalid choice", "draw"]),
    # wear: a coefficient is needed, the runs must exist, times and levels in range
    ("wear predict without a coefficient", ["wear", "predict", "{in}/empty.zarr"], ["--fit", "--k-friction"]),
    ("wear predict --hours negative", ["wear", "predict", "{in}/empty.zarr", "--k-friction", "1e-4", "--hours", "-1"],
     ["--hours", "[0, ∞)"]),
    ("wear predict missing run", ["wear", "predict", "{work}/nope.zarr", "--k-friction", "1e-4"], ["nope.zarr", "no such"]),
    ("wear fit --level 1", ["wear", "fit", "{in}/kin/points.csv", "--out", "{work}/new.toml", "--level", "1"],
     ["--level", "[0.5, 1)"]),
    # kinetics: outputs checked before the fit, values and fit files in their ranges
    ("kinetics fit --out existing", KIN_FIT[:3] + ["--out", "{work}/existing.toml"], ["--out", "--overwrite"]),
    ("kinetics fit --figure .json", KIN_FIT + ["--figure", "{work}/x.json"], ["--figure", ".png or .svg"]),
    ("kinetics fit --figure missing folder", KIN_FIT + ["--figure", "{work}/nope/x.png"], ["--figure", "does not exist"]),
    ("kinetics fit --figure unwritable", KIN_FIT + ["--figure", "{RO}/x.png"], ["--figure", "not writable"]),
    ("kinetics fit --stress-figure existing", KIN_FIT + ["--stress-figure", "{work}/existing.png"],
     ["--stress-figure", "--overwrite"]),
    ("kinetics fit --figure same as --stress-figure", KIN_FIT + ["--figure", "{work}/k.png", "--stress-figure", "{work}/k.png"],
     ["--stress-figure", "is also --figure"]),
    ("kinetics fit --fix kappa_g negative", KIN_FIT + ["--fix", "kappa_g=-1"], ["--fix", "kappa_g", "(0, ∞)"]),
    ("kinetics fit percent value", ["kinetics", "fit", "{in}/kin/percent.csv", "--out", "{work}/new.toml"],
     ["percent.csv:3", "column 3 (value)", "95", "[0, 1] (a fraction; percent? divide by 100)"]),
    ("kinetics predict --points percent value", KIN_PREDICT + ["--points", "{in}/kin/percent.csv"],
     ["percent.csv:3", "column 3 (value)", "percent?"]),
    ("kinetics predict FIT negative variance", ["kinetics", "predict", "{in}/kin/negvar.toml", "{in}/kin/condition-c.json"],
     ["negvar.toml", "covariance[0][0]", "[0, ∞)"]),
    ("kinetics predict FIT nan parameter", ["kinetics", "predict", "{in}/kin/nan.toml", "{in}/kin/condition-c.json"],
     ["nan.toml", "parameters.kappa_g", "nan"]),
    ("kinetics predict --figure .json", KIN_PREDICT + ["--figure", "{work}/x.json"], ["--figure", ".png or .svg"]),
    ("kinetics predict --figure existing", KIN_PREDICT + ["--figure", "{work}/existing.png"], ["--figure", "--overwrite"]),
    ("presets with an argument", ["presets", "extra"], ["unrecognized", "extra"]),
    ("no command", [], ["required", "command"]),
    ("unknown command", ["simulate"], ["invalid choice", "simulate"]),
    ("unknown top-level option", ["--bogus", "run", PRESET], ["--bogus"]),
]

# RUN stores: (name, path) -> word
STORES = {"missing": ("{in}/missing.zarr", "no such"), "a file": ("{in}/afile.zarr", None),
          "name too long": ("{in}/" + "a" * 300 + ".zarr", "no such"),
          "an empty folder": ("{in}/empty.zarr", "not a taimill run store"), "a folder of junk": ("{in}/junk.zarr", "not a taimill run store"),
          "a zarr group without config": ("{in}/noconfig.zarr", None), "empty": ("", "empty")}
STORE_READERS = {"analyse": ["analyse", "{S}"], "report": ["report", "{S}", "--out", "{work}/rep"],
                 "record": ["record", "{S}", "--rrd", "{work}/new.rrd"],
                 "compare": ["compare", "{S}", "{in}/noconfig.zarr"]}


def _store_cases():
    # the line names the store: by its option (RUN, A) or by its path (a damaged store)
    return [(f"{cmd} RUN: {kind}", [a.replace("{S}", path) for a in argv], [w for w in (Path(path).name[:50], word) if w])
            for cmd, argv in STORE_READERS.items() for kind, (path, word) in STORES.items()]


# ------------------------------------------------------------------ contents of files
def _top(text, line):
    """text with a top-level line added (before the first table)."""
    return text.replace("seed = 1\n", f"seed = 1\n{line}\n", 1)


def _edit(text, *pairs):
    for old, new in zip(pairs[::2], pairs[1::2]):
        assert old in text, old
        text = text.replace(old, new)
    return text


# name -> (preset text, words)
PRESETS = {
    "misspelled key": (_edit(GOOD_PRESET, "duration = 1.0", "duraton = 1.0"), ["duraton", "unknown key", "did you mean 'duration'"]),
    "misspelled balls key": (_edit(GOOD_PRESET, "radius_mm = 6", "radius_m = 6"), ["balls.radius_m", "did you mean 'radius_mm'"]),
    "unknown key": (_top(GOOD_PRESET, "colour = 'red'"), ["colour", "unknown key", "allowed:"]),
    "missing key": (_edit(GOOD_PRESET, "plate_rpm = 200\n", ""), ["plate_rpm", "missing"]),
    "balls not a table": (_edit(GOOD_PRESET, "[balls]\ncount = 12\nmaterial = \"steel-c1020\"\nradius_mm = 6\n", "balls = 3\n"), ["balls", "table"]),
    "balls missing": (GOOD_PRESET.split("[balls]")[0], ["balls", "missing"]),
    "plate_rpm 0": (_edit(GOOD_PRESET, "plate_rpm = 200", "plate_rpm = 0"), ["plate_rpm", "undefined"]),
    "plate_rpm text": (_edit(GOOD_PRESET, "plate_rpm = 200", "plate_rpm = 'fast'"), ["plate_rpm", "number"]),
    "plate_rpm bool": (_edit(GOOD_PRESET, "plate_rpm = 200", "plate_rpm = true"), ["plate_rpm", "number"]),
    "plate_rpm nan": (_edit(GOOD_PRESET, "plate_rpm = 200", "plate_rpm = nan"), ["plate_rpm", "finite"]),
    "plate_rpm inf": (_edit(GOOD_PRESET, "plate_rpm = 200", "plate_rpm = -inf"), ["plate_rpm", "finite"]),
    "plate_rpm huge integer": (_edit(GOOD_PRESET, "plate_rpm = 200", "plate_rpm = 9223372036854775807"), ["plate_rpm", "allowed range"]),
    "plate_radius_mm 0": (_top(GOOD_PRESET, "plate_radius_mm = 0"), ["plate_radius_mm", "(0, 2000]"]),
    "plate_radius_mm negative": (_top(GOOD_PRESET, "plate_radius_mm = -125"), ["plate_radius_mm", "(0, 2000]"]),
    "ratio and jar_rpm": (_top(GOOD_PRESET, "jar_rpm = -700"), ["jar_rpm", "either"]),
    "ratio out of range": (_edit(GOOD_PRESET, "ratio = -2.6", "ratio = -50"), ["ratio", "-50", "[-10, 10]"]),
    "ratio an array": (_edit(GOOD_PRESET, "ratio = -2.6", "ratio = [-2.6]"), ["ratio", "number"]),
    "duration 0": (_edit(GOOD_PRESET, "duration = 1.0", "duration = 0"), ["duration", "(0,"]),
    "analysis_start after duration": (_edit(GOOD_PRESET, "analysis_start = 0.5", "analysis_start = 2.0"), ["analysis_start", "2.0"]),
    "analysis_start at duration": (_edit(GOOD_PRESET, "analysis_start = 0.5", "analysis_start = 1.0"), ["analysis_start", "below duration"]),
    "ramp_time 0": (_top(GOOD_PRESET, "ramp_time = 0"), ["ramp_time", "(0,"]),
    "ramp_time beyond duration": (_top(GOOD_PRESET, "ramp_time = 5"), ["ramp_time", "5"]),
    "gravity negative": (_top(GOOD_PRESET, "gravity = -9.81"), ["gravity", "[0, 1000]"]),
    "seed negative": (_edit(GOOD_PRESET, "seed = 1", "seed = -1"), ["seed", "-1"]),
    "seed fraction": (_edit(GOOD_PRESET, "seed = 1", "seed = 1.5"), ["seed", "integer"]),
    "dt text": (_edit(GOOD_PRESET, 'dt = "auto"', 'dt = "fast"'), ["dt", "fast", "'auto'"]),
    "dt too large": (_edit(GOOD_PRESET, 'dt = "auto"', "dt = 1e-4"), ["dt", "steps per contact"]),
    "dt 1e15 steps": (_edit(GOOD_PRESET, 'dt = "auto"', "dt = 1e-15"), ["dt", "steps for duration"]),
    "dt bool": (_edit(GOOD_PRESET, 'dt = "auto"', "dt = true"), ["dt", "'auto'"]),
    "law unknown": (GOOD_PRESET.replace("seed = 1", 'seed = 1\nlaw = "hooke"'), ["law", "hooke", "adams-impact"]),
    "jar empty name": (_edit(GOOD_PRESET, 'jar = "CY"', 'jar = ""'), ["jar", "empty"]),
    "jar unknown": (_edit(GOOD_PRESET, 'jar = "CY"', 'jar = "XY"'), ["jar", "XY", "known jars"]),
    "jar a number": (_edit(GOOD_PRESET, 'jar = "CY"', "jar = 3"), ["jar", "string"]),
    "pair empty name": (_edit(GOOD_PRESET, 'pair = "steel-steel"', 'pair = ""'), ["pair", "empty"]),
    "pair unknown": (_edit(GOOD_PRESET, 'pair = "steel-steel"', 'pair = "steel-unobtainium"'), ["pair", "steel-steel"]),
    "balls radius and diameter": (_edit(GOOD_PRESET, "radius_mm = 6", "radius_mm = 6\ndiameter_mm = 12"),
                                  ["balls.diameter_mm", "not both"]),
    "jar_material unknown": (_top(GOOD_PRESET, 'jar_material = "oak"'), ["jar_material", "oak"]),
    "material unknown": (_edit(GOOD_PRESET, 'material = "steel-c1020"', 'material = "gold"'), ["material", "gold"]),
    "balls count 0": (_edit(GOOD_PRESET, "count = 12", "count = 0"), ["balls.count", "[1,"]),
    "balls count fraction": (_edit(GOOD_PRESET, "count = 12", "count = 1.5"), ["balls.count", "integer"]),
    "balls count bool": (_edit(GOOD_PRESET, "count = 12", "count = true"), ["balls.count", "integer"]),
    "balls overfill": (_edit(GOOD_PRESET, "count = 12", "count = 200"), ["balls.count", "200"]),
    "balls radius negative": (_edit(GOOD_PRESET, "radius_mm = 6", "radius_mm = -6"), ["balls.radius_mm", "-6"]),
    "balls larger than the jar": (_edit(GOOD_PRESET, "radius_mm = 6", "radius_mm = 12.1"), ["balls.radius_mm"]),
    "balls larger than the corners": (_edit(GOOD_PRESET, 'jar = "CY"', 'jar = "HM"', "count = 12", "count = 2", "radius_mm = 6",
                                            "radius_mm = 9"), ["balls.radius_mm", "(0, 8] mm", "rounded to 8 mm"]),
    "balls larger than the corners, as a diameter": (_edit(GOOD_PRESET, 'jar = "CY"', 'jar = "HM"', "count = 12", "count = 2",
                                                           "radius_mm = 6", "diameter_mm = 18"),
                                                     ["balls.diameter_mm", "18", "(0, 16] mm", "rounded to 8 mm"]),
    "friction not a table": (GOOD_PRESET.replace("seed = 1", "seed = 1\nfriction = 0.5"), ["friction", "table"]),
    "friction misspelled": (GOOD_PRESET + "[friction]\nmu_ss = 0.5\n", ["friction.mu_ss", "did you mean 'mu_s'"]),
    "friction mu_d above mu_s": (GOOD_PRESET + "[friction]\nmu_s = 0.5\nmu_d = 0.8\n", ["friction.mu_d", "mu_s = 0.5"]),
    "friction mu_s negative": (GOOD_PRESET + "[friction]\nmu_s = -0.5\n", ["friction.mu_s", "[0, 10]"]),
    "friction v_d below v_s": (GOOD_PRESET + "[friction]\nv_s_mm_s = 10\nv_d_mm_s = 5\n", ["friction.v_d_mm_s", "must exceed"]),
    "friction mu_r negative": (GOOD_PRESET + "[friction]\nmu_r = -0.1\n", ["friction.mu_r", "-0.1", "[0, 10]"]),
    "friction mu_r too large": (GOOD_PRESET + "[friction]\nmu_r = 11\n", ["friction.mu_r", "11", "[0, 10]"]),
    "friction mu_r text": (GOOD_PRESET + "[friction]\nmu_r = \"high\"\n", ["friction.mu_r", "number"]),
    "pair_ball_wall unknown": (_top(GOOD_PRESET, 'pair_ball_wall = "steel-butter"'), ["pair_ball_wall", "steel-butter", "steel-fluorite"]),
    "pair_ball_wall other contact set": (_top(GOOD_PRESET, 'pair_ball_wall = "zirconia-zirconia"'),
                                         ["pair_ball_wall", "zirconia-zirconia", "contact set"]),
    "pair_ball_ball a number": (_top(GOOD_PRESET, "pair_ball_ball = 3"), ["pair_ball_ball", "string"]),
    "pair_ball_wal misspelled": (_top(GOOD_PRESET, 'pair_ball_wal = "steel-fluorite"'), ["pair_ball_wal", "did you mean 'pair_ball_wall'"]),
    "friction_ball_wall mu_s negative": (GOOD_PRESET + "[friction_ball_wall]\nmu_s = -0.2\n", ["friction_ball_wall.mu_s", "-0.2", "[0, 10]"]),
    "friction_ball_ball mu_d above mu_s": (GOOD_PRESET + "[friction_ball_ball]\nmu_s = 0.2\nmu_d = 0.3\n",
                                           ["friction_ball_ball.mu_d", "0.3", "mu_s = 0.2"]),
    "friction_ball_wall mu_r negative": (GOOD_PRESET + "[friction_ball_wall]\nmu_r = -1\n", ["friction_ball_wall.mu_r", "-1", "[0, 10]"]),
    "friction_ball_wall misspelled": (GOOD_PRESET + "[friction_ball_wall]\nmu_rr = 0.1\n", ["friction_ball_wall.mu_rr", "did you mean 'mu_r'"]),
    "friction_ball_wall not a table": (_top(GOOD_PRESET, "friction_ball_wall = 0.5"), ["friction_ball_wall", "table"]),
    "outputs rate 0": (GOOD_PRESET + "[outputs]\ntrajectory_rate = 0\n", ["outputs.trajectory_rate", "(0,"]),
    "outputs rate 1e-9: a hang": (GOOD_PRESET + "[outputs]\ntrajectory_rate = 1e-9\n",
                                  ["outputs.trajectory_rate", "1e-09", "allowed range [1, ", "Hz", "duration = 1 s"]),
    "outputs rate 1 for a 0.3 s run": (_edit(GOOD_PRESET, "duration = 1.0", "duration = 0.3", "analysis_start = 0.5", "analysis_start = 0.1")
                                       + "[outputs]\ntrajectory_rate = 1\n", ["outputs.trajectory_rate", "1", "[3.333, ", "duration = 0.3 s"]),
    "outputs rate too high": (GOOD_PRESET + "[outputs]\ntrajectory_rate = 2e5\n", ["outputs.trajectory_rate", "200000", "allowed range"]),
    "duration 36000: auto dt over 1e10 steps": (_edit(GOOD_PRESET, "duration = 1.0", "duration = 36000"),
                                                ["duration", "36000", "automatic dt", "at most 1e+10"]),
    "outputs misspelled": (GOOD_PRESET + "[outputs]\ntrajectory_rat = 100\n", ["outputs.trajectory_rat", "did you mean 'trajectory_rate'"]),
    "initial_positions empty name": (_top(GOOD_PRESET, 'initial_positions = ""'), ["initial_positions", "empty"]),
    "initial_positions overlapping": (_top(GOOD_PRESET, 'initial_positions = "../overlap.csv"'), ["initial_positions", "overlap"]),
    "initial_positions outside": (_top(GOOD_PRESET, 'initial_positions = "../outside.csv"'), ["initial_positions", "inside"]),
    "initial_positions wrong shape": (_top(GOOD_PRESET, 'initial_positions = "../short.csv"'), ["initial_positions", "shape"]),
    "initial_positions nan": (_top(GOOD_PRESET, 'initial_positions = "../nan.csv"'), ["initial_positions", "finite"]),
    "initial_positions text": (_top(GOOD_PRESET, 'initial_positions = "../words.csv"'), ["initial_positions", "cannot read"]),
    "initial_positions npz without positions": (_top(GOOD_PRESET, 'initial_positions = "../other.npz"'), ["initial_positions", "positions"]),
    "initial_positions npz not a zip": (_top(GOOD_PRESET, 'initial_positions = "../overlap.npz"'), ["initial_positions", "cannot read"]),
}
# valid presets LIGGGHTS cannot express: name -> (preset text, extra export argv, words)
EXPORT_REFUSALS = {
    "ball-wall rolling resistance": (GOOD_PRESET + "[friction]\nmu_r = 0.05\n", [],
                                     ["friction.mu_r", "0.05", "ball-wall rolling"]),
    "coated jar's ball-wall rolling resistance": (GOOD_PRESET + "[friction_ball_wall]\nmu_r = 0.1\n", [],
                                                  ["friction_ball_wall.mu_r", "0.1", "ball-wall rolling"]),
    "ball-ball rolling resistance with --strict": (GOOD_PRESET + "[friction_ball_ball]\nmu_r = 0.05\n", ["--strict"],
                                                   ["friction_ball_ball.mu_r", "0.05", "rolling_friction cdt"]),
    "epsd2 at the turning wall with --strict": (GOOD_PRESET + '[friction]\nrolling = "epsd2"\nmu_r = 0.05\n', ["--strict"],
                                                ["friction.mu_r", "0.05", "ground-frame spin"]),
}
# name -> (jar text, words); each is given to `run --jar` and to `jars show`
JARS = {
    "cut outside the circle": (_edit(GOOD_JAR, "distance_mm = 18", "distance_mm = 40"), ["profile[1].distance_mm", "40", "(0, 32.5)"]),
    "cut on the circle": (_edit(GOOD_JAR, "distance_mm = 18", "distance_mm = 32.5"), ["profile[1].distance_mm", "outside"]),
    "lifter outside the circle": (_edit(GOOD_JAR, 'type = "cut"\ndistance_mm = 18', 'type = "lifter"\nradius_mm = 5\ndistance_mm = 40'),
                                  ["profile[1].distance_mm", "outside the circle"]),
    "lifter over the axis": (_edit(GOOD_JAR, 'type = "cut"\ndistance_mm = 18', 'type = "lifter"\nradius_mm = 10\ndistance_mm = 5'),
                             ["profile[1].distance_mm", "axis"]),
    "misspelled top key": (_edit(GOOD_JAR, "height_mm", "heigth_mm"), ["heigth_mm", "did you mean 'height_mm'"]),
    "misspelled profile key": (_edit(GOOD_JAR, 'type = "circle"', 'typ = "circle"'), ["profile[0].typ", "did you mean 'type'"]),
    "key of another primitive": (_edit(GOOD_JAR, "angle_deg = 0", "angle_deg = 0\nradius_mm = 3"), ["profile[1].radius_mm", "unknown key"]),
    "unknown primitive": (_edit(GOOD_JAR, 'type = "cut"', 'type = "hexagon"'), ["profile[1].type", "hexagon"]),
    "two circles": (_edit(GOOD_JAR, 'type = "cut"\ndistance_mm = 18\nangle_deg = 0', 'type = "circle"\nradius_mm = 20'), ["profile", "one circle"]),
    "no profile": (GOOD_JAR.split("[[profile]]")[0], ["profile", "non-empty"]),
    "profile of numbers": (GOOD_JAR.split("[[profile]]")[0] + "profile = [1, 2]\n", ["profile[0]", "table"]),
    "height 0": (_edit(GOOD_JAR, "height_mm = 24.1", "height_mm = 0"), ["height_mm", "(0, 1000]"]),
    "circle radius 0": (_edit(GOOD_JAR, "radius_mm = 32.5", "radius_mm = 0"), ["profile[0].radius_mm", "(0, 1000]"]),
    "corners without fillet": (_edit(GOOD_JAR, "fillet_mm = 8", "fillet_mm = 0"), ["fillet_mm", "fillet"]),
    "fillet too large": (_edit(GOOD_JAR, "fillet_mm = 8", "fillet_mm = 30"), ["profile", "cannot build"]),
    "wall material unknown": (_edit(GOOD_JAR, 'wall_material = "aisi-304"', 'wall_material = "oak"'), ["material", "oak"]),
    # a 20-gon: 20 cuts and 20 fillets, more boundary pieces than the engine holds (geometry.MAX_PIECES)
    "more pieces than the engine holds": (_edit(GOOD_JAR, "fillet_mm = 8", "fillet_mm = 2").split("[[profile]]\ntype = \"cut\"")[0]
                                          + "".join(f'[[profile]]\ntype = "cut"\ndistance_mm = 30\nangle_deg = {18 * i}\n\n' for i in range(20)),
                                          ["profile", "40 boundary pieces", "[1, 32]"]),
}
# name -> (pair file text, words); each is given to `run --pair` and to `calibrate drop --pair`
PAIRS = {
    "misspelled friction key": (_edit(GOOD_PAIR, "v_d_mm_s = 10", "v_dd_mm_s = 10"), ["pair.mine.v_dd_mm_s", "did you mean 'v_d_mm_s'"]),
    "misspelled contact key": (_edit(GOOD_PAIR, "ball_radius_mm", "ball_radius"), ["contact.mine.ball_radius", "did you mean 'ball_radius_mm'"]),
    "misspelled law key": (_edit(GOOD_PAIR, "ball_wall = { c_max_Ns_per_mm = 17.5, d_mm", "ball_wall = { c_max_Ns_per_mm = 17.5, d_m"),
                           ["contact.mine.ball_wall.d_m", "did you mean 'd_mm'"]),
    "unknown top table": (GOOD_PAIR + "[material.x]\ndensity = 1\n", ["material", "unknown key"]),
    "two pairs": (GOOD_PAIR + "[pair.other]\ncontact = \"mine\"\n", ["pair", "exactly one"]),
    "no pair": ("[contact.mine]" + GOOD_PAIR.split("[contact.mine]")[1], ["pair", "exactly one"]),
    "pair not a table": ("pair = 3\n", ["pair", "exactly one"]),
    "pair entry not a table": ("[pair]\nmine = 3\n", ["pair.mine", "table"]),
    "contact entry not a table": (_edit(GOOD_PAIR, "[contact.mine]", "[contact.x]") + "[contact]\nmine = 3\n", ["contact"]),
    "contact set missing": (_edit(GOOD_PAIR, 'contact = "mine"', 'contact = "theirs"'), ["pair.mine.contact", "theirs"]),
    "mu_d above mu_s": (_edit(GOOD_PAIR, "mu_d = 0.4", "mu_d = 0.9"), ["pair.mine.mu_d", "0.9"]),
    "mu_r negative": (_edit(GOOD_PAIR, "mu_d = 0.4", "mu_d = 0.4\nmu_r = -0.01"), ["pair.mine.mu_r", "-0.01", "[0, 10]"]),
    "restitution above 1": (_edit(GOOD_PAIR, "e = 0.516, u_ref_mm_s = 3309 }\nball_wall", "e = 1.5, u_ref_mm_s = 3309 }\nball_wall"),
                            ["contact.mine.ball_ball.e", "1.5"]),
    "contact ball material unknown": (_edit(GOOD_PAIR, 'ball = "steel-c1020"', 'ball = "gold"'), ["material", "gold"]),
}
# name -> (drop CSV text, words) for `calibrate fit --data`
SIZE_HEAD = "condition,time_h,size_um,passing_pct\n"
SIZE_CSVS = {  # measured size distributions: each slip named with its line and column
    "no size column": ("condition,time_h,passing_pct\na.json,1,50\n", ["header", "no column for the size", "size_um"]),
    "a column without unit": ("condition,time_h,size,passing_pct\na.json,1,10,50\n", ["'size' has no unit", "size_um"]),
    "sizes not increasing": (SIZE_HEAD + "a.json,1,10,20\na.json,1,30,60\na.json,1,20,70\n",
                             ["line 4", "column 3 (size_um) = '20'", "must increase", "line 3 had 30"]),
    "passing above 100 %": (SIZE_HEAD + "a.json,1,10,20\na.json,1,30,104\n", ["line 3", "column 4 (passing_pct)", "[0, 100]"]),
    "percent under a fraction's name": ("condition,time_h,size_um,passing_fraction\na.json,1,10,45\n",
                                        ["line 2", "passing_fraction", "'45'", "percent under a fraction's name?", "passing_pct"]),
    "metres under µm": (SIZE_HEAD + "a.json,1,0.00001,20\n", ["line 2", "size_um", "[1 nm, 100 mm]", "size_m"]),
    "µm under metres": ("condition,time_h,size_m,passing_pct\na.json,1,12,20\n", ["line 2", "size_m", "size_um"]),
    "passing falls with size": (SIZE_HEAD + "a.json,1,10,40\na.json,1,30,30\n", ["line 3", "cannot fall", "line 2 had 40"]),
    "a distribution interrupted": (SIZE_HEAD + "a.json,1,10,40\nb.json,1,10,30\na.json,1,30,60\n",
                                   ["line 4", "began at line 2", "together"]),
    "negative time": (SIZE_HEAD + "a.json,-1,10,40\n", ["line 2", "time_h", "≥ 0"]),
    "size text": (SIZE_HEAD + "a.json,1,ten,40\n", ["line 2", "size_um", "not a number"]),
}
GRINDING = "[breakage]\nphi = 0.4\ngamma = 0.9\nbeta = 3.5\n[impact]\ncapture_g = 0.001\nf_mat = 0.5\nxw_min = 0.05\n"
GRINDING_FILES = {  # grinding parameter files of taimill sizes predict
    "phi above 1": (GRINDING.replace("phi = 0.4", "phi = 1.4"), ["breakage.phi", "1.4", "(0, 1]"]),
    "gamma above beta": (GRINDING.replace("gamma = 0.9", "gamma = 4"), ["breakage.gamma", "below beta"]),
    "negative capture": (GRINDING.replace("capture_g = 0.001", "capture_g = -1"), ["impact.capture_g", "(0, ∞) g"]),
    "unknown key": (GRINDING + "speed = 3\n", ["impact.speed", "unknown key"]),
    "no breakage": ("[impact]\ncapture_g = 0.001\nf_mat = 0.5\n", ["breakage", "missing"]),
    "unknown measure": (GRINDING + 'measure = "heat"\n', ["impact.measure", "'heat'", "dissipated_normal"]),
}
DROP_CSVS = {
    "no h0 column": ("height,bounce\n100,76\n", ["columns", "h0_mm"]),
    "negative height": ("h0_mm,rebound_mm\n100,76\n-200,150\n", ["h0_mm (line 3)", "-200"]),
    "rebound above the drop": ("h0_mm,rebound_mm\n100,160\n", ["rebound_mm (line 2)", "160"]),
    "restitution text": ("h0_mm,e\n100,high\n", ["e (line 2)", "high"]),
    "restitution above 1": ("h0_mm,e\n100,1.2\n", ["e (line 2)", "(0, 1]"]),
    "restitution nan": ("h0_mm,e\n100,nan\n", ["e (line 2)", "(0, 1]"]),
    "missing cell": ("h0_mm,e\n100\n", ["e (line 2)", "number"]),
    "sigma negative": ("h0_mm,e,sigma_e\n100,0.9,-0.1\n", ["sigma_e (line 2)"]),
    "header only": ("h0_mm,e\n# no rows\n", ["rows", "no data rows"]),
    "over-long field": ("h0_mm,e\n" + "1" * 200_000 + ",0.9\n", ["line 2", "CSV"]),
    "extra cell": ("h0_mm,e\n100,0.9\n200,0.85,0.05\n", ["line 3", "3 cells", "2 columns", "h0_mm,e"]),
}
# name -> (overlay CSV text, words) for `report SWEEP --overlay`
OVERLAYS = {
    "no header": ("# nothing\n", ["header"]),
    "no ratio column": ("K,mean\n-1,2\n", ["line 1", "ratio"]),
    "no series": ("ratio\n-1\n", ["line 1", "at least one series"]),
    "duplicate series": ("ratio,a,a\n-1,2,3\n", ["line 1", "distinct"]),
    "no data line": ("ratio,a\n", ["data", "no data line"]),
    "cell count": ("ratio,a\n-1,2,3\n", ["line 2", "3 cells"]),
    "not a number": ("ratio,a\n-1,high\n", ["line 2, column a", "high"]),
    "infinite": ("ratio,a\n-1,inf\n", ["line 2, column a", "finite"]),
    "missing ratio": ("ratio,a\n,2\n", ["column ratio", "needs a ratio"]),
    "orphan error column": ("ratio,a,b_err\n-1,2,0.1\n", ["header", "b_err"]),
    "negative error": ("ratio,a,a_err\n-1,2,0.1\n-2,3,-0.2\n", ["line 3, column a_err", "-0.2", "[0, ∞)"]),
}
# --overwrite of something taimill did not write, or of an input: name -> (argv, words).
# {in}/presets/mine.toml, {in}/pairs/mine.toml and {in}/case are written for them.
MINE = "{in}/presets/mine.toml"
OVERWRITES = {
    "run --out the preset": (["run", MINE, "--out", MINE, "--overwrite"], ["--out", "mine.toml", "is an input"]),
    "run --out the preset's folder": (["run", MINE, "--out", "{in}/presets", "--overwrite"], ["--out", "holds", "mine.toml"]),
    "run --out a folder of other files": (["run", MINE, "--out", "{work}/figs", "--overwrite"],
                                          ["--out", "figs", "not a run store", "not replaced"]),
    "run --out a pipe": (["run", MINE, "--out", "{in}/bad/fifo.toml", "--overwrite"], ["--out", "not a regular file"]),
    "run --rrd a user's file": (["run", MINE, "--rrd", "{work}/existing.rrd", "--overwrite"],
                                ["--rrd", "existing.rrd", "not a rerun recording", "not replaced"]),
    "sweep --out a folder of other files": (["sweep", MINE, "--ratio", "-2", "--out", "{work}/figs", "--overwrite"],
                                            ["--out", "not a sweep store", "not replaced"]),
    "sweep --out the preset's folder": (["sweep", MINE, "--ratio", "-2", "--out", "{in}/presets"], ["--out", "holds", "mine.toml"]),
    "record --rrd a user's file": (["record", "{in}/empty.zarr", "--rrd", "{work}/existing.rrd", "--overwrite"],
                                   ["--rrd", "not replaced"]),
    "report --overwrite a user's file of a figure's name": (["report", "{in}/empty.zarr", "--out", "{work}/figs", "--overwrite"],
                                                          ["trajectories.png", "not replaced"]),
    "jars show --out a user's picture": (["jars", "show", "CY", "--out", "{work}/existing.png", "--overwrite"],
                                         ["--out", "existing.png", "not a figure", "not replaced"]),
    "calibrate fit --out a user's file": (FIT[:6] + ["--out", "{work}/existing.toml", "--overwrite"], ["--out", "not replaced"]),
    "calibrate fit --out the pair file": (["calibrate", "fit", "--pair", "{in}/pairs/mine.toml", "--data", TABLE_2_1, "--out",
                                           "{in}/pairs/mine.toml", "--overwrite"], ["--out", "is an input"]),
    "import liggghts --out the case": (["import", "liggghts", "{in}/case", "--out", "{in}/case", "--overwrite"],
                                       ["--out", "is an input"]),
    "export liggghts --out the preset's folder": (["export", "liggghts", MINE, "--out", "{in}/presets", "--overwrite"],
                                                  ["--out", "holds", "mine.toml"]),
    "kinetics fit --out the points": (KIN_FIT[:3] + ["--out", "{in}/kin/points.csv", "--overwrite"],
                                      ["--out", "points.csv", "is an input"]),
    "kinetics fit --out a user's file": (KIN_FIT[:3] + ["--out", "{work}/existing.toml", "--overwrite"],
                                         ["--out", "not a fit file written by taimill", "not replaced"]),
    "kinetics predict --figure a user's picture": (KIN_PREDICT + ["--figure", "{work}/existing.png", "--overwrite"],
                                                   ["--figure", "not a figure", "not replaced"]),
}


def _content_cases():
    cases = [(f"preset: {name}", ["run", f"{{in}}/presets/{_slug(name)}.toml", "--out", "{work}/new.zarr"], words,
              {"write": (f"presets/{_slug(name)}.toml", text)}) for name, (text, words) in PRESETS.items()]
    for name, (text, words) in JARS.items():
        file = {"write": (f"jars/{_slug(name)}.toml", text)}
        cases.append((f"jar file via run --jar: {name}", ["run", PRESET, "--jar", f"{{in}}/jars/{_slug(name)}.toml"], words, file))
        cases.append((f"jar file via jars show: {name}", ["jars", "show", f"{{in}}/jars/{_slug(name)}.toml", "--out", "{work}/new.png"], words, file))
    for name, (text, words) in PAIRS.items():
        file = {"write": (f"pairs/{_slug(name)}.toml", text)}
        cases.append((f"pair file via run --pair: {name}", ["run", PRESET, "--pair", f"{{in}}/pairs/{_slug(name)}.toml"], words, file))
        cases.append((f"pair file via calibrate drop: {name}",
                      ["calibrate", "drop", "--pair", f"{{in}}/pairs/{_slug(name)}.toml", "--h0", "100"], words, file))
    for name, (text, words) in DROP_CSVS.items():
        cases.append((f"drop CSV: {name}", ["calibrate", "fit", "--pair", "steel-steel", "--data", f"{{in}}/csv/{_slug(name)}.csv",
                                            "--out", "{work}/new.toml"], words, {"write": (f"csv/{_slug(name)}.csv", text)}))
    for name, (text, extra_argv, words) in EXPORT_REFUSALS.items():
        cases.append((f"export liggghts: {name}", ["export", "liggghts", f"{{in}}/presets/export-{_slug(name)}.toml",
                                                   *extra_argv, "--out", "{work}/case"], words,
                      {"write": (f"presets/export-{_slug(name)}.toml", text)}))
    for name, (text, words) in SIZE_CSVS.items():
        cases.append((f"size CSV: {name}", ["sizes", "check", f"{{in}}/csv/sz-{_slug(name)}.csv"], words,
                      {"write": (f"csv/sz-{_slug(name)}.csv", text)}))
    for name, (text, words) in GRINDING_FILES.items():
        cases.append((f"grinding file: {name}", ["sizes", "predict", f"{{in}}/gr-{_slug(name)}.toml",
                                                 "{in}/kin/condition-a.json", "--feed-x50", "100"], words,
                      {"write": (f"gr-{_slug(name)}.toml", text)}))
    for name, (text, words) in OVERLAYS.items():
        cases.append((f"overlay CSV: {name}", ["report", "{in}/sweep.zarr", "--out", "{work}/rep", "--overlay", f"{{in}}/csv/ov-{_slug(name)}.csv"],
                      words, {"write": (f"csv/ov-{_slug(name)}.csv", text)}))
    mine = [("presets/mine.toml", GOOD_PRESET), ("pairs/mine.toml", GOOD_PAIR), ("case/taimill-case.json", "{}")]
    cases += [(f"overwrite: {name}", argv, words, {"write": mine}) for name, (argv, words) in OVERWRITES.items()]
    return cases


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in name)


def all_cases():
    cases = _file_cases() + [(n, a, w, {}) for n, a, w in _typed_cases() + VALUES + _store_cases()] + _content_cases()
    names = [c[0] for c in cases]
    assert len(names) == len(set(names)), [n for n in names if names.count(n) > 1]
    return cases


CASES = all_cases()


# ------------------------------------------------------------------ the folder the cases work in
@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """in/: inputs, good and bad; work/: existing outputs and the current directory."""
    import zarr

    d = tmp_path_factory.mktemp("bad-input")
    inp, work, bad = d / "in", d / "work", d / "in" / "bad"
    for p in (inp, work, bad, inp / "presets", inp / "jars", inp / "pairs", inp / "csv", work / "figs", work / "adir.rrd",
              work / "adir.png", work / "adir.toml", inp / "empty.zarr", inp / "junk.zarr", work / "figs" / "energy.pdf"):
        p.mkdir(parents=True, exist_ok=True)
    for ext in ("toml", "csv"):
        (bad / f"folder.{ext}").mkdir()
        (bad / f"binary.{ext}").write_bytes(bytes(range(256)) * 4)
        (bad / f"utf16.{ext}").write_bytes(("jar = 'CY'\n" if ext == "toml" else "h0_mm,e\n100,0.9\n").encode("utf-16"))
        os.mkfifo(bad / f"fifo.{ext}")
        os.symlink("/dev/null", bad / f"device.{ext}")
        os.symlink(f"loop.{ext}", bad / f"loop.{ext}")
        os.symlink(f"gone.{ext}", bad / f"broken.{ext}")
        (bad / f"empty.{ext}").write_text("")
        with open(bad / f"huge.{ext}", "wb") as f:
            f.truncate(65 * 2**20)  # sparse: the size alone is refused, nothing is read
    (bad / "afile").write_text("a file, not a folder\n")
    (bad / "syntax.toml").write_text("seed = = 1\n")
    (bad / "deep.toml").write_text("a = " + "[" * 3000 + "]" * 3000 + "\n")
    (inp / "overlay.csv").write_text(GOOD_OVERLAY)
    # kinetics: the shipped synthetic example, a fit of it, damaged copies and percent values
    (inp / "kin").mkdir()
    example = ROOT / "examples" / "outcome"
    for name in ("points.csv", "fit.toml", "condition-a.json", "condition-b.json", "condition-c.json"):
        (inp / "kin" / name).write_bytes((example / name).read_bytes())
    fit = (example / "fit.toml").read_text()
    (inp / "kin" / "negvar.toml").write_text(fit.replace("covariance = [[", "covariance = [[-", 1))
    (inp / "kin" / "nan.toml").write_text(re.sub(r'"kappa_g" = [0-9.e-]+', '"kappa_g" = nan', fit, count=1))
    lines = (example / "points.csv").read_text().splitlines()
    (inp / "kin" / "percent.csv").write_text("\n".join(lines[:2] + [re.sub(r",0\.[0-9]+,", ",95,", lines[2])] + lines[3:]))
    (inp / "afile.zarr").write_text("not a store\n")
    (inp / "junk.zarr" / "zarr.json").write_text("{ not json")
    zarr.open_group(str(inp / "noconfig.zarr"), mode="w")
    zarr.open_group(str(inp / "sweep.zarr"), mode="w").attrs["kind"] = "sweep"
    # initial positions: 12 balls overlapping, outside, too few, nan, words, an npz without 'positions'
    inside = [f"{0.02 * (i % 2) - 0.01:.3f},{0.004 * (i // 2) - 0.01:.3f},0.01" for i in range(12)]
    (inp / "overlap.csv").write_text("\n".join(["0,0,0.01"] * 12))
    (inp / "outside.csv").write_text("\n".join([f"{0.03 + i * 1e-3:.3f},0,0.01" for i in range(12)]))
    (inp / "short.csv").write_text("\n".join(inside[:3]))
    (inp / "nan.csv").write_text("\n".join(["nan,nan,nan"] * 12))
    (inp / "words.csv").write_text("x,y,z\n" * 12)
    import numpy as np

    np.savez(inp / "other.npz", centres=np.zeros((12, 3)))
    (inp / "overlap.npz").write_text("not a zip")
    # presets naming each bad file under a key (relative to the preset, as users write them)
    for name, argv, words, extra in [c for c in _file_cases() if c[3]]:
        key, path = extra["ref"]
        rel = os.path.relpath(path.replace("{in}", str(inp)), inp / "presets")
        text = GOOD_PRESET.replace("seed = 1", f"seed = 1\n{key} = {rel!r}") if key == "initial_positions" else \
            GOOD_PRESET.replace(f'{key} = "{"CY" if key == "jar" else "steel-steel"}"', f"{key} = {rel!r}")
        target = next(a for a in argv if "/presets/" in a).replace("{in}", str(inp))
        Path(target).write_text(text)
    for name, argv, words, extra in CASES:
        if "write" in extra:
            for rel, text in [extra["write"]] if isinstance(extra["write"][0], str) else extra["write"]:
                (inp / rel).parent.mkdir(exist_ok=True)
                (inp / rel).write_text(text)
    # existing outputs that must survive
    for name in ("existing.png", "existing.svg", "jar-HM.png"):
        (work / name).write_bytes(b"\x89PNG old figure")
    (work / "existing.rrd").write_bytes(b"old recording")
    (work / "existing.toml").write_text("# old pair file\n")
    (work / "afile").write_text("a file, not a folder\n")
    (work / "figs" / "trajectories.png").write_bytes(b"old")
    (work / "figs" / "overview.svg").write_bytes(b"old")
    (work / "figs" / "mean_se.png").write_bytes(b"old")
    ro = work / "locked"
    ro.mkdir()
    ro.chmod(0o555)
    unwritable = str(ro) if not IS_ROOT else ("/proc/sys" if not os.access("/proc/sys", os.W_OK) else None)
    yield {"in": str(inp), "work": str(work), "RO": unwritable, "root": d}
    ro.chmod(0o755)


def snapshot(root) -> dict:
    """Every path under root: (mode, size, mtime) from lstat, and the bytes of the small
    regular files under work/ (the existing outputs a case must not touch)."""
    out = {}
    stack = [str(root)]
    while stack:
        with os.scandir(stack.pop()) as it:
            for e in it:
                st = e.stat(follow_symlinks=False)
                data = None
                if e.is_dir(follow_symlinks=False):
                    stack.append(e.path)
                elif "/work/" in e.path and e.is_file(follow_symlinks=False) and st.st_size < 2**16:
                    with open(e.path, "rb") as f:
                        data = f.read()
                out[e.path] = (st.st_mode, st.st_size, st.st_mtime_ns, data)
    return out


@pytest.fixture(scope="module")
def no_run_stage():
    """The stages after validation fail the case: Taichi, sweep workers, the viewer."""
    import taimill.bridge.dumps
    import taimill.bridge.liggghts
    import taimill.cli.record
    import taimill.physics.runner
    import taimill.runs.sweep

    def reached(*a, **k):
        raise AssertionError("bad input reached the run stage")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(taimill.physics.runner, "init_taichi", reached)
        mp.setattr(taimill.runs.sweep, "run_sweep", reached)
        mp.setattr(taimill.cli.record.subprocess, "call", reached)
        mp.setattr(taimill.bridge.liggghts, "export_case", reached)
        mp.setattr(taimill.bridge.dumps, "import_case", reached)
        yield


def fill(argv, base):
    if any("{RO}" in a for a in argv) and base["RO"] is None:
        pytest.skip("no unwritable folder here (root, and /proc/sys is writable)")
    return [a.format(**{k: v for k, v in base.items() if k != "root"}) if "{" in a else a for a in argv]


def check_one_line(code, out, err, words):
    lines = err.splitlines()
    assert code == 2, (code, out, err)
    assert "Traceback" not in err, err
    assert len(lines) == 1 and lines[0].startswith("taimill: error: "), err
    assert out == "", out
    for w in words:
        assert w in lines[0], (w, lines[0])


@pytest.mark.parametrize("name,argv,words,extra", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(base, no_run_stage, capsys, monkeypatch, name, argv, words, extra):
    from taimill.cli import main

    argv = fill(argv, base)
    monkeypatch.chdir(base["work"])
    before = snapshot(base["root"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(argv)
    out, err = capsys.readouterr()
    check_one_line(code, out, err, words)
    shown = [w for w in caught if not issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning))]
    assert not shown, [str(w.message) for w in shown]  # a warning would be a second line on stderr
    assert snapshot(base["root"]) == before


def test_the_table_is_large_and_covers_every_subcommand():
    from taimill.cli import parser

    commands = set(parser()._subparsers._group_actions[0].choices)
    covered = {c[1][0] for c in CASES if c[1]}
    assert commands <= covered, commands - covered
    assert len(CASES) >= 200


# A few through the real command, end to end: the one line really is all a user sees.
SUBPROCESS = ["run PRESET: binary", "run --ratio: nan", "preset: misspelled key", "run --out missing folder",
              "overwrite: run --out the preset", "overwrite: run --out a folder of other files",
              "overwrite: import liggghts --out the case", "overwrite: run --out a pipe", "overlay CSV: negative error",
              "drop CSV: extra cell", "overwrite: kinetics fit --out the points", "size CSV: sizes not increasing",
              "size CSV: percent under a fraction's name",
              "jars show --out existing"]


@pytest.mark.parametrize("name", SUBPROCESS)
def test_the_real_cli_prints_the_same_one_line(base, name):
    _, argv, words, _ = next(c for c in CASES if c[0] == name)
    before = snapshot(base["root"])
    res = subprocess.run([sys.executable, "-m", "taimill.cli", *fill(argv, base)], cwd=base["work"],
                         capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
    check_one_line(res.returncode, res.stdout, res.stderr, words)
    assert snapshot(base["root"]) == before


# ------------------------------------------------------------------ unit tests of the conventions
def test_unknown_key_suggests_the_nearest_known_one(tmp_path):
    from taimill.errors import ConfigError
    from taimill.model.preset import load_preset

    p = tmp_path / "p.toml"
    p.write_text(_edit(GOOD_PRESET, "duration = 1.0", "duraton = 3"))
    with pytest.raises(ConfigError) as e:
        load_preset(p)
    assert "unknown key 'duraton' (did you mean 'duration'?)" in str(e.value)
    assert "missing" not in str(e.value)
    p.write_text(_top(GOOD_PRESET, "zzz = 1"))  # nothing near: the allowed keys are listed
    with pytest.raises(ConfigError, match=r"unknown key 'zzz'; allowed: .*duration"):
        load_preset(p)


def test_version_prints_the_package_version(capsys):
    import tomllib

    from taimill.cli import main

    assert main(["--version"]) == 0
    expected = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert capsys.readouterr().out.strip() == f"taimill {expected}"


def test_tui_help_lists_only_what_a_live_mill_uses(capsys):
    from taimill.cli import main

    assert main(["tui", "--help"]) == 0
    text = capsys.readouterr().out
    for ignored in ("--duration", "--analysis-start"):
        assert ignored not in text
    for used in ("--ratio", "--jar-rpm", "--plate-rpm", "--pair", "--jar", "--balls", "--seed", "--dt", "--law", "--out-dir"):
        assert used in text
    assert main(["run", "--help"]) == 0
    assert "seed of the random ball placement" in capsys.readouterr().out


def test_a_config_error_is_one_line_whatever_it_quotes():
    from taimill.errors import ConfigError

    err = ConfigError("f.toml", "key", "x\n" * 1000, "not valid TOML (line 1\nline 2)")
    assert "\n" not in str(err) and len(str(err)) < 300


def test_negative_numbers_in_any_notation_are_values():
    from taimill.cli import parser

    a = parser().parse_args(["run", PRESET, "--dt", "-1e-6", "--ratio", "-2.6e0", "--jar-rpm", "-7E2"])
    assert (a.dt, a.ratio, a.jar_rpm) == ("-1e-6", -2.6, -700.0)
    a = parser().parse_args(["sweep", PRESET, "--ratio", "-2:-4:0.2", "--dt", "-1e-6", "--plate-rpm", "-1e2,-2e2"])
    assert (a.ratio, a.dt, a.plate_rpm) == ("-2:-4:0.2", "-1e-6", "-1e2,-2e2")
    a = parser().parse_args(["calibrate", "oblique", "--pair", "steel-steel", "--offsets", "-1:2:1"])
    assert a.offsets == "-1:2:1"


def test_an_unreadable_file_is_one_line(tmp_path, monkeypatch):
    """Permission denied (root reads everything, so the error is raised by a stand-in)."""
    from taimill.errors import ConfigError
    from taimill.model.files import read_toml

    p = tmp_path / "locked.toml"
    p.write_text("a = 1\n")

    def denied(self):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_bytes", denied)
    with pytest.raises(ConfigError, match="locked.toml': cannot read: permission denied"):
        read_toml(p, "command line", "preset")


def test_a_non_finite_automatic_time_step_is_refused_by_the_loader(tmp_path, monkeypatch):
    # a contact law whose impacts never end gives no automatic step (NaN): the loader
    # refuses it in one line instead of the engine running with dt = NaN
    import math

    from taimill.errors import ConfigError
    from taimill.model import rules
    from taimill.model.preset import load_preset

    monkeypatch.setattr(rules, "_auto_dt", lambda *a: math.nan)
    with pytest.raises(ConfigError) as e:
        load_preset(PRESET, {"law": "hunt-crossley"})
    assert str(e.value).count("\n") == 0 and "dt = 'auto'" in str(e.value) and "finite" in str(e.value)


def test_a_long_run_says_how_long_it_takes_before_it_starts(tmp_path):
    # over cli.run's LONG_SECONDS (2 min) of expected CPU time, `run` prints its step count and a range of wall
    # times on stderr before anything starts (the process is stopped once it said so)
    proc = subprocess.Popen([sys.executable, "-m", "taimill.cli", "run", PRESET, "--duration", "3000", "--json"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(ROOT)))
    try:
        line = proc.stderr.readline()
    finally:
        proc.kill()
        proc.communicate()
    assert line.startswith("taimill: note: ") and "2.31e+09 steps" in line and "duration = 3000 s" in line, line
    assert " min to " in line or " h" in line, line
