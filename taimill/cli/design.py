"""`taimill design PRESET --out DIR --objective KEY:max …`: search a jar family for the
objective on the preset's mill, speeds, media and charge (docs/designer.md). The study
lives in DIR (SQLite); the same command resumes it."""

from __future__ import annotations

import contextlib
import json
import math
import os
import sqlite3
import sys
from pathlib import Path

from taimill.cli.common import DEFAULT_PRESET, LAW_HELP, PRESET_HELP, add_backend, backend, integer, name_text, number, path_text
from taimill.errors import ConfigError

THESIS_JARS = "HM,1L,3L,T,CY"
# K step of the references' grid: CY steel's normal power peaks at K = -2.9, just before the
# charge collapses; a 0.4 grid (-2.6, -3) missed the peak by 0.26 W, ten replica spreads
REFERENCE_STEP = 0.1


def register(sub) -> None:
    d = sub.add_parser("design", help="search jar shapes (lifters, flats, fillets) for an objective of the run summary")
    d.add_argument("preset", type=path_text, nargs="?", default=DEFAULT_PRESET, help=PRESET_HELP)
    d.add_argument("--out", required=True, help="study folder (created; an existing study there is resumed)")
    d.add_argument("--family", default="lifters", help="jar family: lifters, flats or mixed (default lifters)")
    d.add_argument("--objective", action="append", metavar="KEY:max|min",
                   help="a number of the run summary to maximise or minimise, e.g. impact_power_normal:max; "
                        "give it twice or more for a Pareto front (NSGA-II); one objective uses TPE")
    d.add_argument("--floor", action="append", default=[], metavar="KEY=VALUE",
                   help="a design is feasible only if this figure's mean is at least VALUE, e.g. impact_power=2.5")
    d.add_argument("--ratio", metavar="LO:HI | K",
                   help="K searched in [LO, HI], or one K (default: the preset's); a free-gear mill only: "
                        "a fixed-gear mill's K is its gear's")
    d.add_argument("--trials", type=integer, default=40, help="designs to evaluate (default 40)")
    d.add_argument("--batch", type=integer, default=8,
                   help="designs asked and run together as one sweep (NSGA-II: the population; default 8)")
    d.add_argument("--replicas", type=integer, default=3, help="runs per design with seeds seed … seed+R-1 (default 3)")
    d.add_argument("--seed", type=integer, default=1, help="study seed: the sampler's and the first replica's (default 1)")
    d.add_argument("--tolerance", type=number, default=0.3,
                   help="allowed |V/V_nominal - 1|, nominal = the preset jar's volume (default 0.3: the thesis' T is 0.29 below CY)")
    d.add_argument("--min-wall", type=number, default=1.0, metavar="MM",
                   help="thinnest insert (flat or lifter) a maker accepts, mm (default 1)")
    d.add_argument("--fix", action="append", default=[], metavar="NAME=VALUE", help="hold a family parameter fixed, e.g. n_lifters=3")
    d.add_argument("--references", help=f"reference jars run by the same protocol: jar or bowl names (`taimill jars`, "
                                        f"e.g. retsch-80ml) or jar files (default {THESIS_JARS}, or the --jar-volume "
                                        "bowl; 'none')")
    d.add_argument("--reference-ratios", metavar="A:B:STEP | K1,K2,…",
                   help=f"K values the references run at, each taken at its best (default: every {REFERENCE_STEP} across --ratio)")
    d.add_argument("--confirm", type=number, metavar="SECONDS",
                   help="afterwards run design 1 and the references at their best K this long (same replicas)")
    d.add_argument("--keep", type=integer, default=3, help="best designs written to DIR/best (one objective; default 3)")
    d.add_argument("--workers", type=integer, help="local worker processes (default: one per core)")
    d.add_argument("--scheduler", metavar="ADDRESS", type=name_text, help="dask.distributed scheduler, e.g. tcp://host:8786")
    d.add_argument("--json", action="store_true", help="print the summary as JSON instead of markdown")
    add_backend(d)
    o = d.add_argument_group("run overrides (every run)")
    o.add_argument("--duration", type=number, default=4.0, help="simulated seconds per short run (default 4)")
    o.add_argument("--analysis-start", type=number, default=1.0, help="start of the analysis window, s (default 1: after the 1 s start-up)")
    o.add_argument("--plate-rpm", type=number, help="Ω (rpm)")
    o.add_argument("--pair", type=name_text, help="friction pair")
    o.add_argument("--balls", type=integer, help="number of balls")
    o.add_argument("--ball-material", type=name_text, help="ball material")
    o.add_argument("--ball-diameter", type=number, metavar="MM", help="ball diameter (mm)")
    o.add_argument("--mill", type=name_text, help="planetary mill (name or mill file)")
    o.add_argument("--jar-volume", type=integer, metavar="ML",
                   help="the mill's bowl of this volume (ml) as the reference jar: the designs keep its radius, "
                        "height and wall material (instead of the preset's jar)")
    o.add_argument("--jar-material", type=name_text,
                   help="the designed and reference jars' wall material, e.g. zirconia (taimill materials)")
    o.add_argument("--powder-mass", type=number, metavar="G",
                   help="powder charged (g): recorded with every run, not simulated; per-gram keys "
                        "(specific_power_W_per_g) become objectives and floors")
    o.add_argument("--dt", help="time step in s, or 'auto'")
    o.add_argument("--law", help=LAW_HELP)
    d.set_defaults(fn=cmd_design)


def _ratio(text: str | None, preset: str, overrides: dict) -> tuple[float, float]:
    from taimill.model.preset import load_preset

    base = load_preset(preset, overrides)
    gear = base.mill.gear if base.mill is not None else None
    if gear is not None and gear.kind == "fixed":  # K is the gear's: nothing to search or set
        if text is not None:
            raise ConfigError("command line", "--ratio", text, f"{base.mill.name} has a fixed gear {gear.text} "
                              f"({gear.k_text}); K comes from the gear and cannot be searched or set")
        return gear.ks[0], gear.ks[0]
    if text is None:
        k = base.drive.ratio
        return k, k
    parts = text.split(":")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (1, 2) or not all(map(math.isfinite, values)):
        raise ConfigError("command line", "--ratio", text, "LO:HI (K searched between) or one K, finite numbers")
    lo, hi = min(values), max(values)
    return lo, hi


def _fixed(items: list[str]) -> dict:
    out = {}
    for text in items:
        key, sep, value = text.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep:
            raise ConfigError("command line", "--fix", text, "NAME=VALUE with a number, e.g. n_lifters=3")
    return out


def settings_of(a):
    from taimill.design import families
    from taimill.design.protocol import parse_floor, parse_objective
    from taimill.design.study import Settings

    def limit(option, value, lo, hi):
        if not lo <= value <= hi:
            raise ConfigError("command line", option, value, f"allowed range [{lo:g}, {hi:g}]")

    limit("--trials", a.trials, 1, 100_000)
    limit("--batch", a.batch, 1, 1000)
    limit("--replicas", a.replicas, 1, 100)
    limit("--seed", a.seed, 0, 2**31 - 1)
    limit("--keep", a.keep, 1, 1000)
    if not 0 < a.tolerance <= 1:
        raise ConfigError("command line", "--tolerance", a.tolerance, "allowed range (0, 1]: a fraction of the nominal volume")
    limit("--min-wall", a.min_wall, 0, 1000)
    if a.scheduler and a.workers is not None:
        raise ConfigError("command line", "--workers", a.workers, "not used with --scheduler (the cluster's workers run the runs)")
    if a.workers is not None:
        limit("--workers", a.workers, 1, 256)
    families.family(a.family)
    objectives = [parse_objective(t) for t in (a.objective or ["impact_power_normal:max"])]
    if len({o.key for o in objectives}) < len(objectives):
        raise ConfigError("command line", "--objective", ",".join(a.objective), "an objective is repeated")
    floors = dict(parse_floor(t) for t in a.floor)
    # absolute, links kept: the loader names a broken link or a loop in its one line
    preset = os.path.abspath(a.preset) if a.preset.endswith(".toml") else a.preset
    from taimill.cli.common import overrides as given

    # the run overrides as run and sweep read them; --ratio (a range here) and --seed (the study's) are the design's own
    overrides = {k: v for k, v in given(a, skip=("ratio", "seed")).items() if v is not None}
    ratio = _ratio(a.ratio, preset, overrides)
    return Settings(preset, a.family, objectives, floors, ratio, a.replicas, a.seed, a.batch, overrides,
                    a.tolerance, a.min_wall, _fixed(a.fix))


def _reference_ratios(a, ratio) -> list[float]:
    from taimill.runs.sweep import parse_values

    if a.reference_ratios:
        if a.ratio is None and ratio[0] == ratio[1] and _fixed_gear(a):
            raise ConfigError("command line", "--reference-ratios", a.reference_ratios,
                              f"{_fixed_gear(a)}; the references run at its K")
        return parse_values(a.reference_ratios, "--reference-ratios")
    lo, hi = ratio
    if lo == hi:
        return [lo]
    grid = parse_values(f"{hi}:{lo}:{REFERENCE_STEP}", "--ratio")
    return grid + ([] if abs(grid[-1] - lo) < 1e-9 else [lo])


def _bowl_name(jar) -> str:
    """The reference bowl by its name where the name finds it (retsch-80ml), else its file."""
    from taimill.model.jars import load_jar

    try:
        same = Path(load_jar(jar.name, "command line").source).resolve() == Path(jar.source).resolve()
    except ConfigError:
        same = False
    return jar.name if same else str(jar.source)


def _fixed_gear(a) -> str:
    """"MILL has a fixed gear …" when the study's mill has one, else ""."""
    mill = getattr(a, "_mill", None)
    g = mill.gear if mill is not None else None
    return f"{mill.name} has a fixed gear {g.text} ({g.k_text})" if g is not None and g.kind == "fixed" else ""


def _check_out(out: Path) -> None:
    """A new folder or a study's (a lock left by a study killed before its database
    was made is no other file); writable, checked before anything runs."""
    from taimill.design.study import DATABASE
    from taimill.model.files import check_output
    from taimill.store.output import lock_path

    if out.exists() and not out.is_dir():
        raise ConfigError("command line", "--out", str(out), "is a file; give a study folder")
    others = out.is_dir() and any(p.name != lock_path(DATABASE).name for p in out.iterdir())
    if others and not (out / DATABASE).exists():
        raise ConfigError("command line", "--out", str(out), "is a folder with other files and no study.db; give a new or a study folder")
    check_output(str(out), "--out", folder=True, overwrite=None)


def _sqlite_error(err: BaseException) -> str | None:
    """The SQLite error under an Optuna or SQLAlchemy one, if that is what it is."""
    seen = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        orig = getattr(err, "orig", None)  # SQLAlchemy's DBAPIError
        if isinstance(err, sqlite3.Error) or isinstance(orig, sqlite3.Error):
            return str(err if isinstance(err, sqlite3.Error) else orig)
        err = err.__cause__ or err.__context__
    return None


@contextlib.contextmanager
def _kept(study):
    """Faults while the study runs as one line saying what is kept: Ctrl-C (130) and
    SIGTERM (143), a refused write (5: a full disk, SQLite's "database or disk is full"
    too) and a database found damaged only while in use (2). The study database is
    transactional: whatever stopped the study, the same command resumes it."""
    from taimill.design.study import damaged
    from taimill.errors import Interrupted, StoreWriteError
    from taimill.store.output import refused

    def kept():
        if study.database.exists():
            return f"the study so far is in {study.database}; the same command resumes it"
        return f"no study was stored in {study.out} yet"

    try:
        yield
    except KeyboardInterrupt as err:
        raise Interrupted(f"{str(err) or 'interrupted'}; {kept()}", getattr(err, "exit_code", 130)) from None
    except StoreWriteError as err:
        raise StoreWriteError(err.source, err.key, f"{err.allowed}; {kept()}") from None
    except OSError as err:
        raise StoreWriteError(err.filename or study.out, "write", f"write failed ({refused(err)}); {kept()}") from None
    except Exception as err:
        why = _sqlite_error(err)
        if why is None:
            raise
        if "malformed" in why or "not a database" in why:
            raise damaged(study.database, f"damaged ({why})") from None
        raise StoreWriteError(study.database, "study database", f"write failed ({why}); {kept()}") from None


def cmd_design(a) -> int:
    from taimill.design import report
    from taimill.design.study import Study, evaluate_references

    backend(a)  # the local workers inherit it
    s = settings_of(a)
    from taimill.model.preset import load_preset

    base = load_preset(s.preset, s.overrides)
    a._mill = base.mill
    text = a.references if a.references is not None else (_bowl_name(base.jar) if a.jar_volume else THESIS_JARS)
    refs = [] if text.strip().lower() == "none" else [r.strip() for r in text.split(",") if r.strip()]
    from taimill.model.jars import load_jar

    for r in refs:
        try:
            load_jar(r, "command line")
        except ConfigError as err:
            raise ConfigError("command line", "--references", r, err.allowed) from None
    ratios = _reference_ratios(a, s.ratio)
    out = Path(a.out)
    _check_out(out)

    def log(text):
        print(text, file=sys.stderr, flush=True)

    from taimill.store.output import OutputLock

    study = Study(out, s, workers=a.workers, scheduler=a.scheduler, log=log)
    # one designer per study folder (a second is refused naming the first), for the whole study
    with OutputLock(study.database), _kept(study):
        study.open()
        references = evaluate_references(study, refs, ratios)
        study.run(a.trials)
        res = report.results(study, references, a.keep)
        if a.confirm and res["best"]:
            res["confirmation"] = confirm(study, res, a.confirm)
        report.write_all(study, res)
    if a.json:
        print(json.dumps(res, default=float))
    else:
        print((out / "summary.md").read_text(), end="")
        print(f"jar files: {out / 'best'}; report page: {out / 'report.png'}")
    return 0


def confirm(study, res: dict, duration: float) -> dict:
    """Design 1 and the references at their best K, in runs `duration` long (analysis
    from the preset's own start, the thesis' 4 s for its presets)."""
    from taimill.design import report
    from taimill.design.protocol import Protocol, evaluate, figures
    from taimill.model.preset import load_preset

    start = load_preset(study.s.preset, {k: v for k, v in study.s.overrides.items()
                                         if k not in ("duration", "analysis_start")}).analysis_start
    if not 0 <= start < duration:
        raise ConfigError("command line", "--confirm", duration, f"must exceed the preset's analysis start {start:g} s")
    protocol = Protocol(study.s.preset, study.s.overrides | {"duration": duration, "analysis_start": start},
                        study.s.replicas, study.s.seed, study.protocol.fixed_gear)
    best = res["best"][0]
    cands = {"design 1": (best["jar"], best["ratio"])} | {n: (n, r["ratio"]) for n, r in res["references"].items()}
    path = study.out / "confirmation.json"  # kept: the same command again does not run it again
    identity = json.loads(json.dumps({"settings": study.s.identity(), "duration": duration, "trial": best["trial"],
                                      "candidates": cands}))
    if path.exists() and json.loads(path.read_text()).get("identity") == identity:
        return json.loads(path.read_text())["confirmation"]
    study.log(f"design: confirmation runs of {duration:g} s: {', '.join(cands)}")
    results = evaluate(protocol, list(cands.values()), workers=study.workers, scheduler=study.scheduler)
    jars = {n: {"ratio": k, "figures": {key: list(v) for key, v in figures(r, study.s.objectives, study.s.floors).items()}}
            for (n, (_, k)), r in zip(cands.items(), results)}
    o = study.s.objectives[0]
    comparison = {n: dict(zip(("beats", "margin"), report.beats(jars["design 1"], ref, o)))
                  for n, ref in jars.items() if n != "design 1" and report.comparable(study)}
    out = {"duration": duration, "analysis_start": start, "replicas": study.s.replicas, "jars": jars,
           "comparison": comparison}
    from taimill.store.output import whole_file

    with whole_file(path, "confirmation") as part:
        part.write_text(json.dumps({"identity": identity, "confirmation": out}, indent=1))
    return out
