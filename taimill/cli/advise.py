"""`taimill advise [PRESET] --mill … --plate-rpm …`: which plate speed for a mill,
bowl and charge, and what that answer hinges on. One sweep (the points of `taimill
sweep`) over plate speed × the friction μ nobody measured × replicas
(taimill.runs.advise), then a table per plate speed, a "hinges on μ" flag and a
recommendation by the measure chosen (taimill.analysis.advise); docs/advise.md."""

from __future__ import annotations

import json
import math
import sys

from taimill.cli.common import DEFAULT_PRESET, PRESET_HELP, integer, name_text, number, path_text
from taimill.errors import ConfigError

# The run length when none is given: long enough that the 1 s start-up ramp is over and
# a bed has settled (window from 2 s, or the first third of a shorter run left out),
# short enough for 30 points (docs/advise.md, cost).
DURATION, ANALYSIS_START = 6.0, 2.0
REPLICAS = 2  #: seeds per point: two starts show whether a state depends on its start


def register(subparsers) -> None:
    from taimill.analysis.advise import MEASURES, SPREAD_FACTOR
    from taimill.runs.advise import DEFAULT_SPEEDS, HIGH_MU, LOW_MU

    s = subparsers.add_parser(
        "advise", help="which plate speed for your mill, bowl and charge, and what the answer hinges on (friction μ)",
        description="Sweeps the plate speed × the friction μ of the pair (where it is not measured) × replicas, and "
                    "prints per speed the dissipated power, the regime classes and power-led verdict across μ, the "
                    "impact power, whether the answer hinges on μ, and the best speed by --measure (docs/advise.md).")
    s.add_argument("preset", type=path_text, nargs="?", default=DEFAULT_PRESET, help=PRESET_HELP)
    c = s.add_argument_group("the mill, bowl and charge (one value each)")
    c.add_argument("--mill", type=name_text, help="planetary mill: a name (`taimill mills`) or a mill file NAME.toml")
    c.add_argument("--jar-volume", type=integer, metavar="ML", help="the mill's bowl of this volume (ml)")
    c.add_argument("--jar", type=name_text, help="a jar by name or a jar file NAME.toml, instead of --jar-volume")
    c.add_argument("--jar-material", type=name_text, help="the bowl's wall material, e.g. zirconia (taimill materials)")
    c.add_argument("--ball-material", type=name_text, help="ball material, e.g. zirconia")
    c.add_argument("--ball-diameter", type=number, metavar="MM", help="ball diameter (mm)")
    c.add_argument("--balls", type=integer, help="number of balls")
    c.add_argument("--pair", type=name_text, help="friction pair, e.g. dry-ceramic-powder, or a pair file NAME.toml")
    c.add_argument("--powder-mass", type=number, metavar="G",
                   help="powder charged (g): the power is then shown per gram (recorded, not simulated)")
    c.add_argument("--ratio", type=number, help="K = ω/Ω + 1 on a free-gear mill (a fixed gear sets it)")
    g = s.add_argument_group("what is swept")
    g.add_argument("--plate-rpm", help=f"plate speeds Ω (rpm): A:B:STEP or v1,v2,… (default: {DEFAULT_SPEEDS} spread "
                                       "over the mill's range, rounded to 10 rpm)")
    g.add_argument("--mu", help=f"friction levels μ = μ_s = μ_d instead of the automatic ones (default: a measured "
                                f"pair as it is; else {LOW_MU:g}, the pair's μ_d and {HIGH_MU:g})")
    g.add_argument("--replicas", type=integer, default=REPLICAS,
                   help=f"seeds per point (default {REPLICAS}: whether a state depends on its start)")
    g.add_argument("--measure", choices=tuple(MEASURES), metavar="KEY",
                   help=f"what the recommendation maximises: {', '.join(MEASURES)} (default: dissipated_power, "
                        "specific_power_W_per_g with --powder-mass)")
    o = s.add_argument_group("run")
    o.add_argument("--duration", type=number, help=f"simulated seconds per point (default {DURATION:g})")
    o.add_argument("--analysis-start", type=number, help=f"start of the analysis window (s; default {ANALYSIS_START:g})")
    o.add_argument("--seed", type=integer, help="seed of the first replica (integer ≥ 0)")
    o.add_argument("--workers", type=integer, help="local worker processes (default: one per core)")
    s.add_argument("--out", type=path_text, help="sweep store to write (SWEEP.zarr); the same command resumes it")
    s.add_argument("--figure", type=path_text, metavar="FILE.png",
                   help="draw the measure against plate speed, one curve per μ, the replicas' range and the classes")
    s.add_argument("--overwrite", action="store_true", help="replace an existing --out store and --figure")
    s.add_argument("--json", action="store_true",
                   help=f"print the rows (one per plate speed) as JSON; hinges_on_mu where the class or power-led "
                        f"verdict changes across μ or the power spreads by more than ×{SPREAD_FACTOR:g}")
    s.set_defaults(fn=cmd_advise)


def plan_advice(a):
    """(sweep.Request, planned points, the μ line, the measure, the power key) from the
    parsed arguments; everything validated, nothing run or written."""
    from taimill.analysis.advise import default_measure
    from taimill.model.preset import load_preset
    from taimill.runs.advise import default_speeds, mu_levels, request
    from taimill.runs.sweep import plan

    given = {"mill": a.mill, "jar_volume_ml": a.jar_volume, "jar": a.jar, "jar_material": a.jar_material,
             "balls.material": a.ball_material, "balls.diameter_mm": a.ball_diameter, "balls.count": a.balls,
             "pair": a.pair, "powder.mass_g": a.powder_mass, "ratio": a.ratio, "seed": a.seed,
             "duration": DURATION if a.duration is None else a.duration, "analysis_start": a.analysis_start}
    if a.analysis_start is None and isinstance(given["duration"], float) and given["duration"] > 0:
        given["analysis_start"] = min(ANALYSIS_START, given["duration"] / 3)  # a third of a short run settles
    overrides = {k: v for k, v in given.items() if v is not None}
    if a.workers is not None and not 1 <= a.workers <= 256:
        raise ConfigError("command line", "--workers", a.workers, "allowed range [1, 256]")
    base = load_preset(a.preset, overrides)
    speeds = values(a.plate_rpm, "--plate-rpm") if a.plate_rpm is not None else default_speeds(base.mill)
    mus = values(a.mu, "--mu") if a.mu is not None else None
    if mus is not None:
        line = f"friction μ = μ_s = μ_d at {', '.join(f'{m:g}' for m in mus)} (--mu)"
    else:
        mus, line = mu_levels(base)
    per_gram = base.powder is not None
    measure = a.measure or default_measure(per_gram)
    if measure == "specific_power_W_per_g" and not per_gram:
        raise ConfigError("command line", "--measure", measure, "needs the powder's mass: give --powder-mass G")
    req = request(a.preset, overrides, speeds, mus, a.replicas)
    points = plan(req)  # every point validated (speeds in the mill's range, μ, replicas) before anything runs
    return req, points, line, measure, "specific_power_W_per_g" if per_gram else "dissipated_power"


def values(text: str, option: str) -> list[float]:
    """taimill.runs.sweep.parse_values of an option's numbers."""
    from taimill.runs.sweep import MAX_POINTS, parse_values

    try:
        return parse_values(text, option)
    except OverflowError:  # A:B:STEP whose count of values is not even a finite number
        raise ConfigError("command line", option, text, f"a range A:B:STEP of at most {MAX_POINTS} values") from None


def cmd_advise(a) -> int:
    from taimill.analysis.advise import recommendation, speed_rows, with_best
    from taimill.cli.common import plain, print_warnings
    from taimill.cli.sweep import sweep_outputs, sweeping
    from taimill.model.files import reads

    with reads() as inputs:
        req, points, mu_line, measure, power = plan_advice(a)
    with sweep_outputs(a, req, points, inputs, a.figure, "--figure") as store:
        print_warnings(*(p["preset"] for p in points))
        if a.json:  # the table's header says it otherwise
            print(f"taimill: {mu_line}", file=sys.stderr)
        print(f"taimill: {cost_line(req, points, a.workers)}", file=sys.stderr)
        rows, _ = sweeping(req, store, bar=sys.stderr.isatty(), workers=a.workers)
    table = with_best(speed_rows(rows, measure, power))
    advice = recommendation(table, measure)
    if a.figure:
        from taimill.figures.advise import save_advise_figure

        save_advise_figure(table, a.figure, charge_text(points[0]["preset"]))
    if a.json:
        print(json.dumps([plain(r | {"units": units(measure, power)}) for r in table]))
        print(f"taimill: recommendation: {advice}", file=sys.stderr)
        return 0
    print(f"{charge_text(points[0]['preset'])}; {mu_line}")
    print(advice_table(table))
    print()
    print(measure_table(table))
    print(f"\nrecommendation: {advice}")
    if a.out:
        print(f"stored in {a.out} (`taimill report {a.out}` draws every figure of the sweep)")
    if a.figure:
        print(f"figure: {a.figure}")
    return 0


def cost_line(req, points: list[dict], workers: int | None) -> str:
    """What is swept, how many points and about how much CPU and wall time they take
    (taimill.model.cost)."""
    import os

    from taimill.cli.run import span_text
    from taimill.model.cost import run_seconds

    lo = sum(run_seconds(p["preset"])[1] for p in points)
    hi = sum(run_seconds(p["preset"])[2] for p in points)
    n = max(1, min(workers or os.cpu_count() or 1, len(points)))
    mus = len(req.axes.get("friction.mu", [None]))
    swept = (f"{len(req.axes['plate_rpm'])} plate speeds × {mus} μ level{'s' if mus > 1 else ''} × {req.replicas} "
             f"replica{'s' if req.replicas > 1 else ''}")
    return (f"sweeping {swept}: {len(points)} points of {points[0]['preset'].duration:g} s, "
            f"about {span_text(lo)} to {span_text(hi)} of CPU, "
            f"{span_text(lo / n)} to {span_text(hi / n)} on {n} worker{'s' if n > 1 else ''}")


def charge_text(p) -> str:
    """"retsch-pm100 (K = -1), 80 ml zirconia bowl (B80), 6 × Ø5 mm zirconia balls, pair dry-ceramic-powder, 20 g powder"."""
    from pathlib import Path

    powder = f", {p.powder.mass * 1e3:g} g powder" if p.powder is not None else ""
    return (f"{p.mill.name} (K = {p.drive.ratio:g}), jar {p.jar.name} ({p.jar.wall_material} wall), "
            f"{p.balls.count} × Ø{2e3 * p.balls.radius:.4g} mm {p.balls.material.name} balls, pair {Path(p.pair).name}"
            f"{powder}")


def units(measure: str, power: str) -> dict:
    from taimill.analysis.advise import MEASURES

    unit = MEASURES[measure][1]
    return {"plate_rpm": "rpm", "mu": "1", "power": "W/g" if power.endswith("per_g") else "W", "impact_power": "W",
            "measure": "J" if unit == "mJ" else unit}  # JSON keeps the summary's SI values


def _g(v, scale: float = 1.0) -> str:
    return "-" if not isinstance(v, (int, float)) or not math.isfinite(v) else f"{v * scale:.3g}"


def _range(r: dict, name: str, scale: float = 1.0) -> str:
    """"0.52 (0.41–0.63)", or the mean alone where min and max agree."""
    mean, lo, hi = (r[f"{name}_{k}"] for k in ("mean", "min", "max"))
    if _g(lo, scale) == _g(hi, scale):
        return _g(mean, scale)
    return f"{_g(mean, scale)} ({_g(lo, scale)}–{_g(hi, scale)})"


def flag(r: dict) -> str:
    """The "hinges on μ" cell: "yes: class, power ×2.1", "no", or "- (one μ)"."""
    if r["hinges_on_mu"]:
        return "yes: " + ", ".join(r["hinges_why"])
    return "no" if len(r["by_mu"]) > 1 else "- (one μ)"


def advice_table(table: list[dict]) -> str:
    """One line per plate speed: dissipated power mean (min–max over replicas and μ),
    regime classes and power-led verdict across μ, impact power, hinges on μ."""
    unit = "W/g" if table and table[0]["power"].endswith("per_g") else "W"
    head = ("Ω rpm", f"P_diss {unit}", "regime class across μ", "power led", "P_I W", "hinges on μ")
    cells = [(f"{r['plate_rpm']:g}", _range(r, "power"), r["classes_across_mu"], r["power_led_across_mu"],
              _range(r, "impact_power"), flag(r)) for r in table]
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, h in enumerate(head)]
    right = (True, True, False, False, True, False)

    def fmt(row):
        return "  ".join(f"{x:>{w}}" if rt else f"{x:<{w}}" for x, w, rt in zip(row, widths, right)).rstrip()

    note = ("P_diss: mean (min–max) over the replicas and μ; P_I: impact power (kinematic stress energy); "
            "a / b: replicas at one μ ended in different states (start-dependent)")
    return "\n".join([fmt(head), *(fmt(c) for c in cells), note])


def measure_table(table: list[dict]) -> str:
    """The measure per plate speed and μ: mean (min–max) of the replicas; * the best speed at that μ."""
    from taimill.analysis.advise import MEASURES

    measure = table[0]["measure"]
    what, unit, scale = MEASURES[measure]
    mus = sorted({m["mu"] for r in table for m in r["by_mu"]})
    head = ("Ω rpm", *(f"μ {mu:g}" for mu in mus))
    cells = []
    for r in table:
        by = {m["mu"]: m for m in r["by_mu"]}
        cells.append((f"{r['plate_rpm']:g}", *((_range(by[mu], "measure", scale) + (" *" if mu in r["best_at_mu"] else "")
                                                if mu in by else "-") for mu in mus)))
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, h in enumerate(head)]
    reps = sorted({m["replicas"] for r in table for m in r["by_mu"]})
    title = (f"{what} ({unit}) by μ: mean (min–max) of {'/'.join(map(str, reps))} replica{'s' if reps != [1] else ''}; "
             "* the best speed at that μ")
    return "\n".join([title] + ["  ".join(f"{x:>{w}}" for x, w in zip(row, widths)) for row in (head, *cells)])
