"""What the subcommands share: exit codes, the preset overrides every simulating
command takes, JSON-safe values and the printed summary table."""

from __future__ import annotations

import math

from taimill.model.laws import NAMES
from taimill.schema import SUMMARY_ROWS

EXIT_BAD_INPUT, EXIT_UNSTABLE = 2, 3
LAW_HELP = f"normal contact law ({', '.join(NAMES)})"


def dt_option(text: str | None):
    """--dt as given: None, "auto" or seconds; any other text is passed on for
    load_preset to reject with the allowed range."""
    if text is None or text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        return text


def overrides(a) -> dict:
    dt = dt_option(a.dt)
    return {
        "ratio": a.ratio, "jar_rpm": a.jar_rpm, "plate_rpm": a.plate_rpm, "pair": a.pair,
        "jar": a.jar, "balls.count": a.balls, "seed": a.seed, "duration": a.duration, "dt": dt,
        "law": a.law, "analysis_start": a.analysis_start,
    }


def add_overrides(p):
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
    g.add_argument("--law", help=LAW_HELP)


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
    return _counted_line(s) + text + _main_sink_line(s.get("main_sink") or {}) + _hot_spot_line(s.get("wear_hot_spot") or {})


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
    if not h.get("surface"):
        return ""
    where = (f"side wall at {h['angle_deg']:.0f}°, z = {h['z'] * 1e3:.1f} mm" if h["surface"] == "side"
             else f"{h['surface']} at x = {h['x'] * 1e3:.1f}, y = {h['y'] * 1e3:.1f} mm")
    return (f"\nwear hot spot: {where}, {h['power_per_area']:.4g} W/m² "
            f"({h['concentration']:.3g}× the wall mean)")


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
