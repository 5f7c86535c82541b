"""`taimill` command line. Heavy imports (taichi, zarr) happen inside the commands so
`taimill --help` stays fast. Bad input: one line on stderr, exit code 2."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

EXIT_BAD_INPUT, EXIT_UNSTABLE = 2, 3

# (key in the summary, label, unit, scale)
SUMMARY_ROWS = (
    ("sim_seconds", "simulated time", "s", 1),
    ("wall_seconds", "wall time", "s", 1),
    ("realtime_factor", "simulated s per wall s", "", 1),
    ("dt", "time step", "µs", 1e6),
    ("events", "collision events in window", "", 1),
    ("events_ball_ball", "  ball-ball", "", 1),
    ("events_ball_wall", "  ball-wall", "", 1),
    ("collision_rate", "collision rate", "1/s", 1),
    ("impact_power", "impact power E_I/τ (eq 3.8)", "W", 1),
    ("impact_power_normal", "  normal", "W", 1),
    ("impact_power_tangential", "  tangential", "W", 1),
    ("mean_se", "mean stress energy", "mJ", 1e3),
    ("mean_se_normal", "  normal", "mJ", 1e3),
    ("mean_se_tangential", "  tangential", "mJ", 1e3),
    ("normal_fraction", "normal / total SE", "", 1),
    ("dissipated_power", "dissipated power", "W", 1),
    ("energy_balance_error", "energy balance error", "%", 100),
    ("randomness_index", "randomness index 1/σ", "", 1),
    ("regime", "motion regime", "", None),
    ("regime_confidence", "  confidence (share of 1 s pieces)", "", 1),
    ("critical_ratio", "critical ratio K_c (one ball)", "", 1),
    ("single_ball_se", "one-ball hit energy (Burgio-type)", "mJ", 1e3),
)


def dt_option(text: str | None):
    """--dt as given: None, "auto" or seconds; any other text is passed on for
    load_preset to reject with the allowed range."""
    if text is None or text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        return text


def _overrides(a) -> dict:
    dt = dt_option(a.dt)
    return {
        "ratio": a.ratio, "jar_rpm": a.jar_rpm, "plate_rpm": a.plate_rpm, "pair": a.pair,
        "jar": a.jar, "balls.count": a.balls, "seed": a.seed, "duration": a.duration, "dt": dt,
        "law": a.law, "analysis_start": a.analysis_start,
    }


def _add_overrides(p):
    g = p.add_argument_group("preset overrides")
    g.add_argument("--ratio", type=float, help="K = ω/Ω + 1 (jar spin / plate spin)")
    g.add_argument("--jar-rpm", type=float, help="ω, jar speed relative to the plate (rpm)")
    g.add_argument("--plate-rpm", type=float, help="Ω (rpm)")
    g.add_argument("--pair", help="friction pair, e.g. steel-fluorite")
    g.add_argument("--jar", help="jar name (jars/NAME.toml) or path")
    g.add_argument("--balls", type=int, help="number of balls")
    g.add_argument("--seed", type=int)
    g.add_argument("--duration", type=float, help="simulated seconds (a preset's analysis start that no longer fits becomes duration/6)")
    g.add_argument("--analysis-start", type=float, help="start of the analysis window (s)")
    g.add_argument("--dt", help="time step in s, or 'auto'")
    g.add_argument("--law", help="normal contact law (adams-impact, kelvin-voigt, hertz-damper, hunt-crossley, hertz-mindlin)")


def _fmt(value, scale):
    if scale is None or isinstance(value, str):
        return str(value)
    if isinstance(value, int):
        return f"{value:d}"
    if value is None or not math.isfinite(value):
        return str(value)
    return f"{value * scale:.4g}"


def summary_table(s: dict) -> str:
    rows = [(label, _fmt(s.get(key), scale), unit) for key, label, unit, scale in SUMMARY_ROWS if key in s]
    w = max(len(r[0]) for r in rows)
    text = "\n".join(f"{label:<{w}}  {value:>12} {unit}" for label, value, unit in rows)
    return text + _hot_spot_line(s.get("wear_hot_spot") or {})


def _hot_spot_line(h: dict) -> str:
    if not h.get("surface"):
        return ""
    where = (f"side wall at {h['angle_deg']:.0f}°, z = {h['z'] * 1e3:.1f} mm" if h["surface"] == "side"
             else f"{h['surface']} at x = {h['x'] * 1e3:.1f}, y = {h['y'] * 1e3:.1f} mm")
    return (f"\nwear hot spot: {where}, {h['power_per_area']:.4g} W/m² "
            f"({h['concentration']:.3g}× the wall mean)")


def cmd_run(a) -> int:
    from taimill.errors import SimulationUnstable
    from taimill.params import load_preset

    preset = load_preset(a.preset, _overrides(a))
    if a.out and Path(a.out).exists() and not a.overwrite:
        from taimill.errors import ConfigError

        raise ConfigError("command line", "--out", a.out, "exists; pass --overwrite to replace it")
    if a.rrd:
        from taimill.cli_record import check_output

        check_output(a.rrd, a.overwrite)
    from taimill.physics.simulation import run
    from taimill.sinks import NullSink

    sink = NullSink()
    if a.out:
        from taimill.store import ZarrSink

        sink = ZarrSink(a.out)
    if a.rrd:
        from taimill.recording import RerunSink
        from taimill.sinks import FanOut

        sink = FanOut(sink, RerunSink(a.rrd))
    show_bar = not a.json or sys.stderr.isatty()
    try:
        if show_bar:
            summary = _run_with_bar(run, preset, sink)
        else:
            summary = run(preset, sink)
    except SimulationUnstable as err:
        print(f"taimill: {err}" + (f" (everything up to it is in {a.out})" if a.out else ""), file=sys.stderr)
        return EXIT_UNSTABLE
    if a.json:
        print(json.dumps(_plain(summary)))
    else:
        print(f"{preset.source}: {preset.jar.name} jar, {preset.balls.count} balls, {preset.pair}, "
              f"Ω = {preset.plate_omega * 30 / math.pi:g} rpm, K = {preset.ratio:g}")
        print(summary_table(summary))
        if a.out:
            print(f"stored in {a.out}")
        if a.rrd:
            print(f"recorded in {a.rrd} (open it with `taimill view {a.rrd}`)")
    return 0


def _run_with_bar(run, preset, sink):
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("simulating"), BarColumn(), TextColumn("{task.completed:.2f}/{task.total:.1f} s"),
                  TimeRemainingColumn(), transient=True, console=_stderr_console()) as bar:
        task = bar.add_task("run", total=preset.duration)
        return run(preset, sink, progress=lambda t: bar.update(task, completed=t))


def _stderr_console():
    from rich.console import Console

    return Console(stderr=True)


def _plain(v):
    """JSON-safe, recursively: numpy scalars to Python, non-finite floats to null."""
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def cmd_presets(a) -> int:
    from taimill.params import ROOT

    for p in sorted((ROOT / "presets").glob("*.toml")):
        first = p.read_text().splitlines()[0].lstrip("# ")
        print(f"{p.relative_to(ROOT)}  {first}")
    return 0


def cmd_jars(a) -> int:
    from taimill.jarplot import draw_jar, jar_row
    from taimill.params import jar_names, load_jar

    if getattr(a, "jar_command", None) == "show":
        jar = load_jar(a.name, "command line")
        print(draw_jar(jar, a.out or f"jar-{jar.name}.png"))
        return 0
    names = jar_names()
    cy = load_jar("CY").volume if "CY" in names else None
    rows = [jar_row(load_jar(n), cy) for n in names]
    if a.json:
        print(json.dumps(rows, indent=1, ensure_ascii=False))
        return 0
    print(f"{'jar':6} {'area mm²':>9} {'vol ml':>7} {'/CY':>6} {'pieces':>6} {'fillet mm':>9}  description")
    for r in rows:
        ratio = "-" if r["ratio_to_CY"] is None else f"{r['ratio_to_CY']:.3f}"
        print(f"{r['name']:6} {r['area_mm2']:9.1f} {r['volume_ml']:7.2f} {ratio:>6} {r['pieces']:6d} "
              f"{r['fillet_mm']:9g}  {r['description']}")
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="taimill", description="Planetary ball mill simulator (Taichi DEM in the jar frame).")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="simulate a preset, summarise, store")
    r.add_argument("preset", help="preset TOML file, e.g. presets/p4-cy-steel.toml")
    r.add_argument("--out", help="zarr store to write (RUN.zarr)")
    r.add_argument("--overwrite", action="store_true", help="replace an existing --out store or --rrd file")
    r.add_argument("--rrd", help="rerun recording to write (RUN.rrd); open it with `taimill view RUN.rrd`")
    r.add_argument("--json", action="store_true", help="print the summary as one JSON object on stdout")
    _add_overrides(r)
    r.set_defaults(fn=cmd_run)

    from taimill import cli_calibrate
    cli_calibrate.register(sub)

    sub.add_parser("presets", help="list presets").set_defaults(fn=cmd_presets)
    j = sub.add_parser("jars", help="list jars (area, volume, pieces); 'jars show NAME' draws one")
    j.add_argument("--json", action="store_true", help="print the table as a JSON list")
    j.set_defaults(fn=cmd_jars)
    jsub = j.add_subparsers(dest="jar_command")
    js = jsub.add_parser("show", help="draw a jar's outline and signed-distance field")
    js.add_argument("name", help="jar name (jars/NAME.toml) or path to a jar TOML")
    js.add_argument("--out", help="image to write, .png or .svg (default jar-NAME.png)")
    from taimill import cli_record, cli_report, cli_sweep
    cli_sweep.register(sub)
    cli_report.register(sub)
    cli_record.register(sub)
    from taimill import cli_tui
    cli_tui.register(sub)
    return p


def main(argv=None) -> int:
    from taimill.errors import ConfigError

    a = parser().parse_args(argv)
    try:
        return a.fn(a)
    except ConfigError as err:
        print(f"taimill: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("taimill: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
