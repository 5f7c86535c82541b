"""What the subcommands share: exit codes, the argument parser whose errors are one
line, argument types that refuse what no command can use (NaN, infinities, empty
paths), the preset overrides every simulating command takes, JSON-safe values and
the printed summary table."""

from __future__ import annotations

import argparse
import math
import re
import sys

from taimill.errors import one_line
from taimill.model.contact.registry import NAMES
from taimill.schema import SUMMARY_ROWS

# exit codes (docs/outputs.md): also 1 calibrate.EXIT_NO_MATCH, 4 record.EXIT_NO_DISPLAY,
# 130 Ctrl-C and 143 SIGTERM (taimill.runs.signals)
EXIT_BAD_INPUT, EXIT_UNSTABLE = 2, 3
EXIT_WRITE_REFUSED = 5  #: the system refused a write (full disk, permissions): taimill.errors.StoreWriteError
EXIT_WORKER_DIED = 6  #: a sweep's worker process died: taimill.errors.WorkerDied
EXIT_INTERNAL = 70  #: the TUI stopped on an error in taimill itself (sysexits' EX_SOFTWARE)
LAW_HELP = f"normal contact law ({', '.join(NAMES)})"
DEFAULT_PRESET = "p4-cy-steel"  #: the base a command's options change when it names no preset
PRESET_HELP = ("a bundled preset by name (`taimill presets`), e.g. p4-cy-steel, or a preset file NAME.toml; "
               f"default {DEFAULT_PRESET} (the thesis' P 4 set-up), which the options below change")
LIVE_IGNORED = ("duration", "analysis_start")  #: overrides a live mill has no use for (it runs until quit)


class Parser(argparse.ArgumentParser):
    """argparse with its errors as one line on stderr, like every other bad input:
    `taimill: error: command line: WHAT (see `taimill CMD --help`)`, exit code 2. The
    usage block argparse prints first is left out; --help shows it. Negative numbers
    in any notation, and lists and ranges that start with one, are values ("--dt -1e-6",
    "--ratio -inf", "--ratio -2:-4:0.2", "--ratio -1,-2"), so the value is what gets
    refused or taken, not the option reported as missing its argument (argparse only
    lets plain negative numbers through; the form --ratio=… always works)."""

    NEGATIVE_NUMBER = re.compile(r"^-\.?\d|^-(?:inf|infinity|nan)$", re.IGNORECASE)  #: no option starts so

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = self.NEGATIVE_NUMBER

    def error(self, message):
        print(f"taimill: error: command line: {one_line(message)} (see `{self.prog} --help`)", file=sys.stderr)
        self.exit(EXIT_BAD_INPUT)


def number(text: str) -> float:
    """A finite number (argparse type): "nan", "inf" and "1e999" are refused."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r}: a finite number is needed")
    return value


def integer(text: str) -> int:
    """An integer (argparse type)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None


def path_text(text: str) -> str:
    """A file or folder name (argparse type): not empty or blank, no NUL character."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: a path is needed, not an empty string")
    if "\0" in text:
        raise argparse.ArgumentTypeError(f"{text!r}: a path cannot contain NUL characters")
    return text


def name_text(text: str) -> str:
    """A name (argparse type): not empty or blank."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: a name is needed, not an empty string")
    return text


def dt_option(text: str | None):
    """--dt as given: None, "auto" or seconds; any other text is passed on for
    load_preset to reject with the allowed range."""
    if text is None or text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        return text


def overrides(a, skip: tuple = ()) -> dict:
    """The preset overrides of parsed arguments (None: not given); those a command does
    not take (the live mill's LIVE_IGNORED, an option it has not, the `skip` keys whose
    options mean something else there, as design's --ratio range and study --seed) are
    left out."""
    def arg(name):
        return getattr(a, name, None)

    dt = dt_option(arg("dt"))
    given = {
        "ratio": arg("ratio"), "jar_rpm": arg("jar_rpm"), "plate_rpm": arg("plate_rpm"), "pair": arg("pair"),
        "jar": arg("jar"), "mill": arg("mill"), "jar_volume_ml": arg("jar_volume"), "balls.count": arg("balls"),
        "balls.filling": arg("filling"), "powder.mass_g": arg("powder_mass"), "seed": arg("seed"),
        "duration": arg("duration"), "dt": dt, "law": arg("law"), "analysis_start": arg("analysis_start"),
        "balls.material": arg("ball_material"), "balls.diameter_mm": arg("ball_diameter"),
        "jar_material": arg("jar_material"), "plate_radius_mm": arg("plate_radius"), "softening": arg("softening"),
    }
    return {k: v for k, v in given.items() if k not in skip and (k not in LIVE_IGNORED or hasattr(a, k))}


def add_overrides(p, live: bool = False):
    """The preset overrides; `live`: without those a live mill ignores (LIVE_IGNORED)."""
    g = p.add_argument_group("preset overrides")
    g.add_argument("--ratio", type=number, help="K = ω/Ω + 1 (jar spin / plate spin); or give --jar-rpm, not both")
    g.add_argument("--jar-rpm", type=number, help="ω, jar speed relative to the plate (rpm)")
    g.add_argument("--plate-rpm", type=number, help="Ω (rpm, not 0)")
    g.add_argument("--pair", type=name_text, help="friction pair, e.g. steel-fluorite, or a pair file NAME.toml")
    g.add_argument("--jar", type=name_text,
                   help="a bundled jar or bowl by name (`taimill jars`), or a jar file NAME.toml (from the current folder)")
    g.add_argument("--mill", type=name_text, help="planetary mill: a name (`taimill mills`) or a mill file NAME.toml (default: the preset's, else fritsch-p4)")
    g.add_argument("--jar-volume", type=integer, metavar="ML", help="the mill's bowl of this volume (ml) instead of --jar")
    g.add_argument("--plate-radius", type=number, metavar="MM",
                   help="R_p, plate axis to jar axis (mm) instead of the mill's (a mill of your own: better a mill file)")
    g.add_argument("--balls", type=integer, help="number of balls; or give --filling, not both")
    g.add_argument("--filling", type=number,
                   help="ball filling degree: the ball bed's bulk volume / the jar's (about 1/3 is usual); sets the ball count")
    g.add_argument("--powder-mass", type=number, help="powder charged (g): recorded with the run, not simulated")
    g.add_argument("--ball-material", type=name_text, help="ball material (taimill materials), e.g. zirconia")
    g.add_argument("--ball-diameter", type=number, metavar="MM", help="ball diameter (mm; instead of the preset's size)")
    g.add_argument("--jar-material", type=name_text, help="the jar's wall material instead of its file's, e.g. zirconia")
    g.add_argument("--seed", type=integer, help="seed of the random ball placement (integer ≥ 0; default: the preset's, else 0)")
    if not live:
        g.add_argument("--duration", type=number,
                       help="simulated seconds (a preset's analysis start that no longer fits becomes duration/6)")
        g.add_argument("--analysis-start", type=number, help="start of the analysis window (s)")
    g.add_argument("--dt", help="time step in s, or 'auto'")
    g.add_argument("--law", help=LAW_HELP)
    g.add_argument("--softening", type=number, metavar="F",
                   help="divide the contact stiffness by F ≥ 1, damping recalibrated to keep the restitution "
                        "(a longer time step; docs/softening.md says what it changes)")


def add_backend(p) -> None:
    """--backend: where the kernels run (taimill.physics.backend)."""
    p.add_argument("--backend", metavar="NAME",
                   help="where the kernels run: cpu (default), cuda (the first CUDA device) or auto (cuda where one "
                        "is found, else cpu); the command line wins over TAIMILL_BACKEND (docs/performance.md, backends)")


def backend(a) -> str:
    """The backend --backend (else TAIMILL_BACKEND) names, checked before anything runs
    and handed on to the processes this one spawns (physics.backend.select)."""
    from taimill.runs.simulation import select_backend as select

    return select(getattr(a, "backend", None))


def stations_text(n) -> str:
    """"1 station", "4 stations"."""
    return f"{n} station" if n == 1 else f"{n} stations"


def print_warnings(*presets) -> None:
    """The presets' warnings (estimates, assumptions, implausible values), one line each
    on stderr, each distinct warning once (a sweep's points mostly share theirs)."""
    for w in dict.fromkeys(w for p in presets for w in p.warnings):
        print(f"taimill: warning: {w}", file=sys.stderr)


def _fmt(value, scale):
    if scale is None or isinstance(value, str):
        return str(value)
    if isinstance(value, int):
        return f"{value:d}"
    if value is None or not math.isfinite(value):
        return str(value)
    return f"{value * scale:.4g}"


# The rows of the dissipated power: a friction-led run's table leads with them.
DISSIPATION_ROWS = ("dissipated_power", "friction_share", "specific_power_W_per_g", "specific_power_impact_W_per_g",
                    "shear_power_persistent_wall_W_per_m2", "dissipated_power_impact", "dissipated_power_persistent",
                    "dissipated_power_friction", "dissipated_power_mill")


def summary_rows(s: dict) -> list[tuple]:
    """SUMMARY_ROWS in the order a run is told: a friction-led run's dissipated power
    (what carries it) before its impact power (the kinematic stress energy)."""
    rows = list(SUMMARY_ROWS)
    if s.get("power_led") == "friction-led":
        first = next(i for i, r in enumerate(rows) if r[0] == "events")
        lead = [r for r in rows if r[0] in DISSIPATION_ROWS]
        rest = [r for r in rows if r[0] not in DISSIPATION_ROWS]
        rows = rest[:first] + lead + rest[first:]
    return rows


# A bed keeps the packing its start froze into, and its power with it. Measured: the PM 100
# powder-coated bed (80 ml zirconia, 25 × 5 mm zirconia, dry-ceramic-powder, 400 rpm, 6 s,
# window 2–6 s) dissipated 0.555, 0.566, 0.387 and 0.354 W from seeds 1–4, each steady.
START_NOTE = ("a bed keeps the packing its start froze into: its power can differ by half between seeds "
              "(0.35–0.57 W over 4 seeds of one PM 100 bed); replicas (taimill sweep … --replicas 3) give the spread")


def lead_line(s: dict) -> str:
    """One line saying what carries the dissipated power (and that impacts do not, for a
    friction-led run); "" without the keys."""
    share, total = s.get("friction_share"), s.get("dissipated_power")
    if not s.get("power_led") or not isinstance(share, float) or not math.isfinite(share):
        return ""
    impacts = s.get("impact_power")
    told = f"; impact power (kinematic stress energy) {impacts:.4g} W" if isinstance(impacts, (int, float)) else ""
    if s["power_led"] == "friction-led":
        return (f"friction-led: friction takes {share:.1%} of the {total:.4g} W dissipated, impacts' normal damping "
                f"{1 - share:.1%}{told}: the powder is worked mostly by shear (friction), not by impacts\n")
    return f"impact-led: impacts' normal damping takes {1 - share:.1%} of the {total:.4g} W dissipated{told}\n"


def summary_table(s: dict) -> str:
    rows = [(label.format(stations=stations_text(s.get("stations"))), _fmt(s.get(key), scale), unit)
            for key, label, unit, scale in summary_rows(s) if key in s]
    w = max(len(r[0]) for r in rows)
    text = "\n".join(f"{label:<{w}}  {value:>12} {unit}" for label, value, unit in rows)
    note = f"\n{s['regime_class_note']}" if s.get("regime_class_note") else ""
    note += f"\n{START_NOTE}" if s.get("regime_class") in ("sliding bed", "rolling bed") else ""
    return (lead_line(s) + _counted_line(s) + text + note + _main_sink_line(s.get("main_sink") or {})
            + _hot_spot_line(s.get("wear_hot_spot") or {}))


def _counted_line(s: dict) -> str:
    """What the stress-energy rows count, and the all-contacts figures beside them."""
    if "counted" not in s:
        return ""
    a = s.get("all_contacts") or {}
    every = (f"; all contacts: {a['events']} events, mean SE {_fmt(a.get('mean_se'), 1e3)} mJ"
             if a.get("events") is not None else "")
    return f"stress-energy rows count {s['counted']}{every}\n"


def _main_sink_line(m: dict) -> str:
    if not m.get("mechanism"):
        return ""
    return f"\nmain sink: {m['mechanism']}, {m['power']:.4g} W ({m['share']:.0%} of the dissipated power)"


def _hot_spot_line(h: dict) -> str:
    from taimill.analysis.spatial import hot_spot_text

    line = hot_spot_text(h)
    return f"\n{line}" if line else ""


def stderr_console():
    from rich.console import Console

    return Console(stderr=True)


def plain(v):
    """JSON-safe, recursively: numpy scalars to Python, non-finite floats to null."""
    if isinstance(v, dict):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def open_run_store(path: str, key: str = "RUN"):
    """A run store named on the command line, opened for reading; anything that is not one
    (missing, a file, a folder of junk, a store without config, damage: StoreError) is
    a one-line ConfigError naming `key` and the path."""
    import os

    from taimill.errors import ConfigError
    from taimill.model.files import kind_of_path, name_kind
    from taimill.store.run import open_run

    if not os.path.exists(path):  # os.path: a name the OS refuses (too long) is no such store either
        raise ConfigError("command line", key, path, "no such run store (RUN.zarr, written by taimill run --out)")
    name_kind("run store", kind_of_path(path), path, "command line", key)  # a preset, jar, …, sweep store
    if not os.path.isdir(path):
        raise ConfigError("command line", key, path, "is a file; need a run store folder (RUN.zarr)")
    try:
        store = open_run(path)
        if not store.config:
            raise ValueError("no config attribute")
    except ConfigError:
        raise
    except Exception as err:  # zarr raises several kinds for a folder that is no store
        raise ConfigError("command line", key, path, f"not a taimill run store ({type(err).__name__}: {err})") from None
    return store
