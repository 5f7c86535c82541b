"""`taimill sweep PRESET --ratio A:B:STEP …`: the cartesian product of the
swept values, R replicas per point, batched mills on local processes or a dask cluster,
an optional refinement of the maximum, a sweep store and a table or JSON (with the
share of the replicas in each regime at every K)."""

from __future__ import annotations

import contextlib
import json
import math
import sys

from taimill.cli.common import LAW_HELP, DEFAULT_PRESET, PRESET_HELP, add_backend, backend, integer, name_text, number, path_text
from taimill.errors import ConfigError

REFINE_METRICS = ("mean_se", "mean_se_normal", "mean_se_tangential", "impact_power", "impact_power_normal",
                  "impact_power_tangential", "randomness_index", "normal_fraction", "collision_rate", "dissipated_power")
# The printed table: the point, its swept values (point_columns: the axes that vary,
# taimill.analysis.sweep.sweep_axes), then these (column, header, scale, format). Powers
# are of one jar; "mill" columns the whole mill's (stations × one jar), where the
# point's stored config names the mill's stations.
COLUMNS = (("seed", "seed", 1, "d"),
           ("mean_se", "SE mJ", 1e3, ".4g"), ("mean_se_normal", "SE_n mJ", 1e3, ".4g"),
           ("mean_se_tangential", "SE_t mJ", 1e3, ".4g"), ("impact_power", "P_I W", 1, ".4g"),
           ("impact_power_mill", "P_I mill W", 1, ".4g"), ("dissipated_power", "P_diss W", 1, ".4g"),
           ("dissipated_power_mill", "P_diss mill W", 1, ".4g"), ("specific_power_W_per_g", "P_diss/g W/g", 1, ".4g"),
           ("friction_share", "friction", 1, ".2f"),
           ("randomness_index", "1/σ", 1, ".3g"),
           ("wall_lag", "wall lag", 1, ".3g"), ("regime", "regime", None, "s"), ("regime_class", "class", None, "s"),
           ("wall_seconds", "wall s", 1, ".1f"))


def register(subparsers) -> None:
    # K is mostly negative: "--ratio -2:-4:0.2" and "--ratio -1,-2" are values (common.Parser)
    s = subparsers.add_parser("sweep", help="sweep K (and Ω, pair, balls, jar) with batched mills on all cores")
    s.add_argument("preset", type=path_text, nargs="?", default=DEFAULT_PRESET, help=PRESET_HELP)
    g = s.add_argument_group("swept values: A:B:STEP (inclusive; e.g. 0:-4:0.2), v1,v2,… or one value")
    g.add_argument("--ratio", help="K = ω/Ω + 1 values")
    g.add_argument("--plate-rpm", help="Ω values (rpm)")
    g.add_argument("--pair", help="friction pairs, e.g. steel-steel,steel-fluorite")
    g.add_argument("--pair-ball-wall", help="ball-wall friction pairs (a coated jar), e.g. steel-fluorite; ball-ball keeps --pair's")
    g.add_argument("--mu", help="Coulomb friction μ = μ_s = μ_d of the pair (both contact kinds, or ball-ball with --pair-ball-wall)")
    g.add_argument("--mu-r", help="rolling resistance μ_r of the pair (0: off)")
    g.add_argument("--balls", help="ball counts, e.g. 6,12,24")
    g.add_argument("--jar", help="jars, e.g. CY,HM")
    g.add_argument("--mill", help="planetary mills (names or mill files), e.g. retsch-pm100,fritsch-p7-premium")
    g.add_argument("--jar-volume", help="the mill's bowls by volume (ml), e.g. 50,80,125")
    g.add_argument("--plate-radius", help="plate radii R_p (mm) instead of the mill's, e.g. 70,125")
    g.add_argument("--jar-material", help="jar wall materials, e.g. aisi-304,zirconia (taimill materials)")
    g.add_argument("--ball-material", help="ball materials, e.g. steel-c1020,zirconia")
    g.add_argument("--ball-diameter", help="ball diameters (mm), e.g. 6,12")
    g.add_argument("--replicas", type=integer, default=1, help="R seeds per point (seed … seed+R-1): mean ± 95%% band")
    g.add_argument("--refine", action="store_true", help="add points around the maximum of --refine-metric")
    g.add_argument("--refine-metric", default=None, choices=REFINE_METRICS, metavar="KEY",
                   help=f"summary figure to maximise: {', '.join(REFINE_METRICS)} (default mean_se)")
    g.add_argument("--refine-rounds", type=integer, default=2, help="refinement rounds, each halving the spacing (default 2)")
    o = s.add_argument_group("run overrides (every point)")
    o.add_argument("--seed", type=integer, help="seed of the random ball placement of the first replica (integer ≥ 0)")
    o.add_argument("--powder-mass", type=number, metavar="G",
                   help="powder charged per jar (g): the table and figures then give the power per gram (recorded, not simulated)")
    o.add_argument("--duration", type=number, help="simulated seconds per point")
    o.add_argument("--analysis-start", type=number, help="start of the analysis window (s)")
    o.add_argument("--dt", help="time step in s, or 'auto' (per point)")
    o.add_argument("--law", help=LAW_HELP)
    x = s.add_argument_group("execution")
    x.add_argument("--workers", type=integer, help="local worker processes (default: one per core)")
    x.add_argument("--batch", type=integer, help="mills per kernel, B (default: 1 for small sweeps, see sweep.auto_batch)")
    x.add_argument("--scheduler", metavar="ADDRESS", type=name_text, help="dask.distributed scheduler, e.g. tcp://host:8786")
    add_backend(x)
    s.add_argument("--out", type=path_text, help="sweep store to write (SWEEP.zarr); the same command resumes it")
    s.add_argument("--map", type=path_text, metavar="MAP.png",
                   help="draw the (K, μ) regime map of the sweep (sweep --ratio and --mu; docs/regimes.md)")
    s.add_argument("--overwrite", action="store_true", help="replace an existing --out store (and --map figure)")
    s.add_argument("--json", action="store_true", help="print a JSON list of the points' summaries (each with its units) with the swept values and their K's "
                   "regime_fractions and bistable (replicas in different regimes)")
    s.set_defaults(fn=cmd_sweep)


def request(a):
    """Validated sweep.Request from the parsed arguments."""
    from taimill.cli.common import dt_option
    from taimill.runs.sweep import MAX_POINTS, Request, parse_values

    axes = {}
    for key, opt, kind in (("ratio", "--ratio", float), ("plate_rpm", "--plate-rpm", float), ("pair", "--pair", str),
                           ("balls.count", "--balls", int), ("jar", "--jar", str), ("mill", "--mill", str),
                           ("jar_volume_ml", "--jar-volume", int),
                           ("plate_radius_mm", "--plate-radius", float), ("pair_ball_wall", "--pair-ball-wall", str),
                           ("friction.mu", "--mu", float), ("friction.mu_r", "--mu-r", float),
                           ("jar_material", "--jar-material", str), ("balls.material", "--ball-material", str),
                           ("balls.diameter_mm", "--ball-diameter", float)):
        text = getattr(a, opt[2:].replace("-", "_"))
        if text is not None:
            try:
                axes[key] = parse_values(text, opt, kind)
            except OverflowError:  # A:B:STEP whose count of values is not even a finite number
                raise ConfigError("command line", opt, text, f"a range A:B:STEP of at most {MAX_POINTS} values") from None
    overrides = {k: v for k, v in {"seed": a.seed, "duration": a.duration, "analysis_start": a.analysis_start,
                                    "dt": dt_option(a.dt), "law": a.law, "powder.mass_g": a.powder_mass}.items()
                 if v is not None}
    if a.scheduler and a.workers is not None:
        raise ConfigError("command line", "--workers", a.workers, "not used with --scheduler (the cluster's workers run the chunks)")
    if a.workers is not None and not 1 <= a.workers <= 256:
        raise ConfigError("command line", "--workers", a.workers, "allowed range [1, 256]")
    if a.batch is not None and not 1 <= a.batch <= 64:
        raise ConfigError("command line", "--batch", a.batch, "allowed range [1, 64]")
    if not 1 <= a.refine_rounds <= 10:
        raise ConfigError("command line", "--refine-rounds", a.refine_rounds, "allowed range [1, 10]")
    if a.refine and not a.refine_metric:  # impacts or dissipation: the user's measure, never a default
        raise ConfigError("command line", "--refine-metric", None,
                          f"--refine needs the figure to maximise: one of {', '.join(REFINE_METRICS)}; a friction-led "
                          "charge takes its power by friction, not impacts (docs/choosing-conditions.md)")
    if a.refine and len(axes.get("ratio", [])) < 3:
        raise ConfigError("command line", "--ratio", a.ratio, "--refine needs a K range of at least 3 values")
    req = Request(a.preset, overrides, axes, a.replicas, a.refine_metric if a.refine else None,
                  a.refine_rounds if a.refine else 0)
    return req, dict(batch=a.batch, workers=a.workers, scheduler=a.scheduler)


def cmd_sweep(a) -> int:
    from taimill.cli.common import plain as _plain, print_warnings
    from taimill.schema import with_units
    from taimill.model.files import reads
    from taimill.analysis.sweep import axis_header
    from taimill.runs.sweep import plan

    backend(a)  # the local workers inherit it (a dask cluster's workers: TAIMILL_BACKEND where they run)
    req, run_kw = request(a)
    with reads() as inputs:
        points = plan(req)  # every point validated before a store is touched or a kernel runs
    with sweep_outputs(a, req, points, inputs, a.map, "--map") as store:
        print_warnings(*(p["preset"] for p in points))  # every distinct one once, after every refusal, before anything runs
        rows, peaks = sweeping(req, store, bar=sys.stderr.isatty(), **run_kw)
    axes = sweep_axes_of(rows, points)
    rows, groups = with_regimes(rows, axes)
    if a.map:
        from taimill.figures.regime_map import save_regime_map

        save_regime_map(rows, a.map, f"{a.preset}: regimes over K and friction μ")
    if a.json:
        print(json.dumps([_plain(with_units(r)) for r in rows]))  # each row a summary object with its units
        for p in peaks:
            print(peak_line(p), file=sys.stderr)
        return 0
    print(sweep_table(rows, axes))
    spread = spread_line(rows, axes)
    if spread:
        print(spread)
    if max(g["replicas"] for g in groups) > 1:
        print(f"\nregimes of the replicas (share per {axis_header(axes.x)}; bistable: they end in different regimes, "
              "so their mean mixes states)")
        print(regime_table(groups, axes))
    for p in peaks:
        print(peak_line(p))
    if a.out:
        print(f"stored in {a.out}")
    return 0


def sweep_outputs(a, req, points, inputs, figure: str | None, figure_key: str):
    """The sweep store of `--out` (a.out) opened for writing, after both outputs were
    checked: its folder must exist and be writable (an existing store: the store's own
    rules), and `figure` (the option `figure_key`) replaced only with --overwrite and only
    if it is a figure taimill drew. Locked; an existing store resumed only with the same
    content, replaced only by a finished sweep, and never if it is not a sweep store
    (store/sweep.py writing). A null context without --out."""
    from taimill.figures import is_figure
    from taimill.model.files import check_output
    from taimill.runs.sweep import content
    from taimill.store.sweep import writing

    if a.out:
        check_output(a.out, "--out", overwrite=None)
    if figure:
        check_output(figure, figure_key, overwrite=a.overwrite, suffixes=(".png", ".svg", ".pdf"), what="figure",
                     ours=is_figure, inputs=inputs)
    return (writing(a.out, req.identity(), content(req, points), overwrite=a.overwrite, inputs=inputs) if a.out
            else contextlib.nullcontext())


def sweeping(req, store, *, bar: bool = True, **run_kw) -> tuple[list[dict], list[dict]]:
    """taimill.runs.sweep.run_sweep(req, store, **run_kw) under a progress bar on stderr
    (`bar`), else with its notices as lines on stderr."""
    from taimill.cli.common import stderr_console
    from taimill.runs.sweep import run_sweep

    if not bar:
        from taimill.cli.run import say

        return run_sweep(req, store, notice=say, **run_kw)
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("sweeping"), BarColumn(), TextColumn("{task.completed:.1f}/{task.total:.1f} mill-s"),
                  TimeRemainingColumn(), transient=True, console=stderr_console()) as progress:
        task = progress.add_task("sweep", total=1.0)  # the real total comes with the first report

        def notice(text):  # above the bar, kept when the bar goes
            progress.console.print(f"taimill: {text}", markup=False, highlight=False)

        return run_sweep(req, store, progress=lambda d, t: progress.update(task, completed=d, total=t),
                         notice=notice, **run_kw)


def sweep_axes_of(rows: list[dict], points=()):
    """taimill.analysis.sweep.sweep_axes of the rows, the planned points' value columns
    as candidates."""
    from taimill.analysis.sweep import sweep_axes

    return sweep_axes(columns_of(rows), [k for p in list(points)[:1] for k in p["values"]])


def columns_of(rows: list[dict]) -> dict:
    """The rows as a table of columns (None where a row lacks one)."""
    names = dict.fromkeys(k for r in rows for k in r)
    return {c: [r.get(c) for r in rows] for c in names}


def with_regimes(rows: list[dict], axes=None) -> tuple[list[dict], list[dict]]:
    """(each row with `regime_fractions` and `bistable` of its curve and x value (the
    swept axes: sweep_axes_of(rows) unless given), the groups of
    taimill.analysis.sweep.regime_fractions over the rows in the rows' order)."""
    from taimill.analysis.sweep import codes, regime_fractions

    axes = axes or sweep_axes_of(rows)
    cols = axes.columns
    table = columns_of(rows)
    table["regime"] = [r.get("regime", "") for r in rows]
    table["regime_class"] = [r.get("regime_class", "") for r in rows]
    xs = codes(table[axes.x])

    def key(i, r):  # x as regime_fractions codes it (numbers rounded), the curve as it is
        return (*(r.get(c) for c in cols[:-1]), xs[i])

    groups = regime_fractions(table, cols)
    by_key = {tuple(g[c] for c in cols): g for g in groups}
    keys = [key(i, r) for i, r in enumerate(rows)]
    ordered = [by_key[k] for k in dict.fromkeys(keys)]
    return [r | {k: by_key[kk][k] for k in ("regime_fractions", "bistable")} for r, kk in zip(rows, keys)], ordered


def point_columns(axes) -> tuple:
    """(column, header, scale, format) of the point and of its swept values: the axes
    that vary (curves, then x), each headed by its symbol and unit ("Ω rpm")."""
    from taimill.analysis.sweep import axis_header, axis_scale

    return (("point", "point", 1, "d"),) + tuple((c, axis_header(c), axis_scale(c), "g") for c in axes.columns)


def headline(rows: list[dict], axes) -> str:
    """What every point shares: "CY, 12 balls, steel-steel, K = -2.6"."""
    from taimill.analysis.sweep import value_text

    return ", ".join(value_text(c, rows[0][c]) for c in axes.fixed if c in rows[0])


def sweep_table(rows: list[dict], axes=None) -> str:
    """The printed sweep: a line of what every point shares, then one line per point ×
    replica against the swept values; the whole mill's station counts below."""
    from taimill.analysis.sweep import axis_header, axis_scale, companion_columns

    axes = axes or sweep_axes_of(rows)
    fixed = headline(rows, axes)
    companions = tuple((c, axis_header(c), axis_scale(c), "g") for c in companion_columns(columns_of(rows), axes))
    text = (f"every point: {fixed}\n" if fixed else "") + table(rows, point_columns(axes) + companions + COLUMNS)
    text += friction_led_line(rows)
    stations = sorted({r["stations"] for r in rows if isinstance(r.get("stations"), (int, float)) and r["stations"] > 0})
    if stations:
        text += (f"\npowers of one jar; 'mill' columns: the whole mill, stations × one jar "
                 f"({', '.join(f'{n:g}' for n in stations)} station{'s' if stations != [1] else ''})")
    return text


# Replicas of one condition whose dissipated power spreads by more than this (max − min
# over their mean) depend on their start: frozen beds keep the packing they start in.
SPREAD = 0.05
BEDS = ("sliding bed", "rolling bed")  #: classes whose power depends on the packing a start froze into


def spread_line(rows: list[dict], axes) -> str:
    """A line on the start dependence of the sweep's conditions: the spread of the
    dissipated power over each condition's replicas where it exceeds SPREAD, or, without
    replicas, the bed points whose start may matter; "" when neither."""
    import numpy as np

    from taimill.analysis.sweep import axis_header

    groups: dict = {}
    for r in rows:
        groups.setdefault(tuple(r.get(c) for c in axes.columns), []).append(r)
    wide, beds = [], []
    for key, rs in groups.items():
        p = [r["dissipated_power"] for r in rs if isinstance(r.get("dissipated_power"), (int, float))]
        name = ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in key)
        if len(p) > 1 and np.mean(p) > 0 and (max(p) - min(p)) / np.mean(p) > SPREAD:
            wide.append(f"{name}: {min(p):.3g}–{max(p):.3g} W")
        elif len(p) == 1 and rs[0].get("regime_class") in BEDS:
            beds.append(name)
    lines = []
    if wide:
        lines.append(f"start-dependent: the replicas' dissipated power spreads by more than {SPREAD:.0%} at "
                     f"{'; '.join(wide)} ({', '.join(axis_header(c) for c in axes.columns)}): a bed keeps the packing "
                     "its start froze into; more replicas (--replicas) narrow the mean")
    if beds:
        lines.append(f"beds at {'; '.join(beds)}: a bed's power depends on the packing its start froze into "
                     "(seed to seed by tens of %); run --replicas 3 or more to see the spread")
    return "\n".join(lines)


def friction_led_line(rows: list[dict]) -> str:
    """A line naming the friction-led points (taimill.analysis.summary.power_lead): their
    impact power understates what the charge takes; "" when there are none."""
    led = [r["point"] for r in rows if r.get("power_led") == "friction-led" and "point" in r]
    if not led:
        return ""
    which = "every point" if len(led) == len(rows) else f"point{'s' if len(led) > 1 else ''} {', '.join(map(str, sorted(set(led))))}"
    from taimill.analysis.summary import FRICTION_LED

    return (f"\nfriction-led: {which} (friction ≥ {FRICTION_LED:.0%} of the dissipated power): read P_diss, not P_I; "
            "impacts carry little of what these charges take")


def regime_table(groups: list[dict], axes=None) -> str:
    """One line per curve and x value: replicas, share in each regime class some replica
    ends in (the summary's and the table's `class`), bistable yes/no."""
    from taimill.analysis.sweep import seen_classes

    labels = seen_classes(groups)
    head = point_columns(axes or sweep_axes_of(groups))[1:]
    cols = (*head, ("replicas", "replicas", 1, "d"), *((lab, lab, 1, ".2f") for lab in labels),
            ("bistable", "bistable", None, "s"))
    flat = [g | g["regime_fractions"] | {"bistable": "yes" if g["bistable"] else "no"} for g in groups]
    return table(flat, cols)


def table(rows: list[dict], columns=COLUMNS) -> str:
    """The rows as a text table of the columns they have; a mill column where mills differ."""
    if len({r.get("mill") for r in rows}) > 1:
        columns = (*columns[:1], ("mill", "mill", None, "s"), *columns[1:])
    cols = [c for c in columns if any(c[0] in r for r in rows)]
    cells = [[_cell(r.get(k), scale, fmt) for k, _, scale, fmt in cols] for r in rows]
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, (_, h, _, _) in enumerate(cols)]
    lines = ["  ".join(f"{h:>{w}}" for (_, h, _, _), w in zip(cols, widths))]
    lines += ["  ".join(f"{c:>{w}}" for c, w in zip(row, widths)) for row in cells]
    return "\n".join(lines)


def _cell(v, scale, fmt) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-" if v is None else str(v)
    if scale is None or isinstance(v, str):
        return str(v)
    return format(int(v) if fmt == "d" else v * scale, fmt)


def peak_line(p: dict) -> str:
    curve = ", ".join(f"{k} {p[k]}" for k in ("mill", "jar", "balls", "pair", "plate_rpm") if k in p)
    return f"maximum of {p['metric']} ({curve}): K = {p['ratio']:.3f}, {p['value']:.4g} ({p['method']})"
