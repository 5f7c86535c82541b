"""`taimill sizes check SIZES.csv` and `taimill sizes predict PARAMS.toml CONDITION…`:
measured particle size distributions read and summarised (x10, x50, x90), and the
population balance's distributions over milling time at runs, sweep points or condition
files (docs/outcome.md, "Particle sizes")."""

from __future__ import annotations

import json
import math

from taimill.cli.common import number, path_text

DEFAULT_HOURS = "0,0.25,0.5,1,2,4,8,16,32,64"
QUANTILES = (0.1, 0.5, 0.9)


def register(sub) -> None:
    p = sub.add_parser("sizes", help="particle size distributions: measured ones checked, the population balance's predicted")
    s = p.add_subparsers(dest="sizes", required=True)
    c = s.add_parser("check", help="read a CSV of measured size distributions and give each one's x10, x50, x90")
    c.add_argument("sizes", type=path_text, help="CSV: condition, time_h|time_min|time_s, size_um|size_mm|size_m, "
                   "passing_pct|passing_fraction (docs/outcome.md)")
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.set_defaults(fn=cmd_check)
    q = s.add_parser("predict", help="size distributions over milling time from a parameter file and conditions")
    q.add_argument("params", type=path_text, help="grinding parameters (TOML: [breakage], [impact], [attrition])")
    q.add_argument("conditions", type=path_text, nargs="+",
                   help="run stores, SWEEP.zarr#INDEX, or condition files NAME.json")
    q.add_argument("--feed-x50", type=number, metavar="UM", help="the feed's median size (µm), log-normal")
    q.add_argument("--feed-spread", type=number, default=0.5, help="the feed's σ of ln x (default 0.5)")
    q.add_argument("--top", type=number, metavar="UM", help="coarsest size class edge (µm; default 4 × feed x50)")
    q.add_argument("--finest", type=number, default=0.1, metavar="UM", help="finest size class edge (µm; default 0.1)")
    q.add_argument("--hours", default=DEFAULT_HOURS, help=f"milling times in h (default {DEFAULT_HOURS})")
    q.add_argument("--target-x90", type=number, metavar="UM", help="also the time until x90 falls to this size (µm)")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(fn=cmd_predict)


def _um(x: float) -> str:
    return f"{x * 1e6:.4g}" if math.isfinite(x) else "–"


def cmd_check(a) -> int:
    import numpy as np

    from taimill.cli.common import plain
    from taimill.outcome.sizes import read_distributions

    dists = read_distributions(a.sizes)
    rows = []
    for d in dists:
        logs = np.log(d.sizes)
        row = {"condition": d.condition, "time_s": d.time, "points": len(d.sizes), "line": d.line}
        for f in QUANTILES:
            row[f"x{round(100 * f)}_m"] = (math.exp(float(np.interp(f, d.passing, logs)))
                                          if d.passing[0] <= f <= d.passing[-1] and np.all(np.diff(d.passing) >= 0)
                                          else math.nan)
        rows.append(row)
    if a.json:
        print(json.dumps(plain({"file": a.sizes, "distributions": rows})))
        return 0
    w = max(len("condition"), *(len(r["condition"]) for r in rows))
    print(f"{a.sizes}: {len(rows)} distributions (x: µm; – outside the measured range)")
    print(f"{'condition':<{w}}  {'time (h)':>9}  {'points':>6}  {'x10':>8}  {'x50':>8}  {'x90':>8}")
    for r in rows:
        print(f"{r['condition']:<{w}}  {r['time_s'] / 3600:>9.4g}  {r['points']:>6}  {_um(r['x10_m']):>8}  "
              f"{_um(r['x50_m']):>8}  {_um(r['x90_m']):>8}")
    return 0


def read_params(path):
    """Grinding (taimill.outcome.grinding) from a parameter file; every key checked,
    a bad one named with its file, key, value and allowed range."""
    from taimill.errors import ConfigError
    from taimill.model.files import read_toml
    from taimill.model.spectra import MEASURES
    from taimill.outcome.grinding import Austin, Grinding

    data = read_toml(path, "command line", "PARAMS", "grinding parameter file")
    tables = {"breakage": ("phi", "gamma", "beta"), "impact": ("capture_g", "f_mat", "xw_min", "measure", "stress_only"),
              "attrition": ("k_att",)}
    for name in data:
        if name not in tables:
            raise ConfigError(path, name, "…", f"unknown table: the tables are {', '.join(tables)}")
    if "breakage" not in data:
        raise ConfigError(path, "breakage", None, "missing: Austin's phi, gamma and beta of the fragments")
    values = {}
    for table, keys in tables.items():
        given = data.get(table, {})
        if not isinstance(given, dict):
            raise ConfigError(path, table, given, "a table")
        for k in given:
            if k not in keys:
                raise ConfigError(path, f"{table}.{k}", given[k], f"unknown key: {table} holds {', '.join(keys)}")
        for k, v in given.items():
            key = f"{table}.{k}"
            if k == "measure":
                if v not in MEASURES:
                    raise ConfigError(path, key, v, f"one of {', '.join(MEASURES)}")
            elif k == "stress_only":
                if not isinstance(v, bool):
                    raise ConfigError(path, key, v, "true or false")
            else:
                lo, hi, text = {"phi": (0, 1, "(0, 1]"), "gamma": (0, math.inf, "(0, ∞)"), "beta": (0, math.inf, "(0, ∞)"),
                                "capture_g": (0, math.inf, "(0, ∞) g"), "f_mat": (0, math.inf, "(0, ∞) kg/(J m)"),
                                "xw_min": (-1, math.inf, "[0, ∞) J m/kg"), "k_att": (-1, math.inf, "[0, ∞) g/J")}[k]
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo < v <= hi) or not math.isfinite(v):
                    raise ConfigError(path, key, v, f"a number in {text}")
                if k in ("xw_min", "k_att") and v < 0:
                    raise ConfigError(path, key, v, f"a number in {text}")
            values[(table, k)] = v
    for k in ("phi", "gamma", "beta"):
        if ("breakage", k) not in values:
            raise ConfigError(path, f"breakage.{k}", None, "missing: Austin's breakage function needs phi, gamma and beta")
    if values[("breakage", "gamma")] >= values[("breakage", "beta")]:
        raise ConfigError(path, "breakage.gamma", values[("breakage", "gamma")],
                          f"below beta = {values[('breakage', 'beta')]!r} (γ describes the fine fragments' tail)")
    impact = {k: values[("impact", k)] for k in tables["impact"] if ("impact", k) in values}
    if impact and not {"capture_g", "f_mat"} <= set(impact):
        missing = sorted({"capture_g", "f_mat"} - set(impact))[0]
        raise ConfigError(path, f"impact.{missing}", None, "missing: the impact route needs capture_g and f_mat")
    k_att = values.get(("attrition", "k_att"), 0.0)
    if not impact and not k_att:
        raise ConfigError(path, "impact", None, "missing: give the impact route ([impact]) or attrition ([attrition] k_att > 0)")
    return Grinding(Austin(*(float(values[("breakage", k)]) for k in ("phi", "gamma", "beta"))),
                    **{k: (float(v) if k not in ("measure", "stress_only") else v) for k, v in impact.items()},
                    k_att=float(k_att))


def _hours(text: str) -> list[float]:
    from taimill.errors import ConfigError

    try:
        hours = [float(h) for h in text.split(",") if h.strip()]
    except ValueError:
        raise ConfigError("command line", "--hours", text, "comma-separated milling times in h, e.g. 0,1,2,4") from None
    if not hours or any(not math.isfinite(h) or h < 0 for h in hours) or max(hours) > 10_000:
        raise ConfigError("command line", "--hours", text, "milling times in h, each in [0, 10000]")
    return sorted(set(hours))


def time_to_x90(g, classes, cond, m0, target_m: float, hours_max: float = 10_000.0) -> float:
    """s until x90 falls to `target_m` (bisection in log time; inf if not by hours_max)."""
    from taimill.outcome.grinding import grind, passing, quantile_size

    def x90(t):
        v = quantile_size(classes, passing(classes, grind(g, classes, cond, m0, [t])), 0.9)[0]
        return 0.0 if math.isnan(v) else v  # nan: below the finest edge

    if x90(0.0) <= target_m:
        return 0.0
    hi = hours_max * 3600.0
    if x90(hi) > target_m:
        return math.inf
    lo = 1.0
    if x90(lo) <= target_m:
        return lo
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if x90(mid) > target_m else (lo, mid)
        if hi / lo < 1.0001:
            break
    return hi


def cmd_predict(a) -> int:
    from taimill.cli.common import plain
    from taimill.cli.kinetics import _conditions, _expand
    from taimill.errors import ConfigError
    from taimill.model.files import reads
    from taimill.outcome.grinding import SizeClasses, feed, grind, passing, quantile_size, selection

    with reads():
        g = read_params(a.params)
    if a.feed_x50 is None:
        raise ConfigError("command line", "--feed-x50", None, "missing: the feed's median size in µm")
    for option, v, lo, hi in (("--feed-x50", a.feed_x50, 0.001, 1e5), ("--feed-spread", a.feed_spread, 0.01, 5.0),
                              ("--finest", a.finest, 0.001, 1e4)):
        if not lo <= v <= hi:
            raise ConfigError("command line", option, v, f"allowed range [{lo:g}, {hi:g}]")
    top_um = a.top if a.top is not None else 4 * a.feed_x50
    if not a.finest * 2 < top_um <= 1e5:
        raise ConfigError("command line", "--top", top_um, f"allowed range ({2 * a.finest:g}, 1e5] µm (above twice --finest)")
    if a.target_x90 is not None and not a.finest < a.target_x90 < top_um:
        raise ConfigError("command line", "--target-x90", a.target_x90, f"allowed range ({a.finest:g}, {top_um:g}) µm")
    hours = _hours(a.hours)
    with reads():
        conds = _conditions(_expand(a.conditions), ".", "command line")
    classes = SizeClasses.spanning(a.finest * 1e-6, top_um * 1e-6)
    m0 = feed(classes, a.feed_x50 * 1e-6, a.feed_spread)
    rows = []
    for name, cond in conds.items():
        m = grind(g, classes, cond, m0, [h * 3600.0 for h in hours])
        q = passing(classes, m)
        s = selection(g, classes, cond)
        row = {"condition": name, "hours": hours,
               **{f"x{round(100 * f)}_m": quantile_size(classes, q, f) for f in QUANTILES},
               "sizes_m": classes.edges, "passing": q,
               "selection_impact_per_s": s["impact"], "selection_attrition_per_s": s["attrition"]}
        if a.target_x90 is not None:
            row["time_to_target_x90_s"] = time_to_x90(g, classes, cond, m0, a.target_x90 * 1e-6)
        rows.append(row)
    if a.json:
        listed = [{k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in r.items()} for r in rows]
        print(json.dumps(plain({"params": a.params, "feed_x50_m": a.feed_x50 * 1e-6, "conditions": listed})))
        return 0
    print(f"{a.params}: x10 / x50 / x90 (µm) against milling time; feed log-normal, x50 {a.feed_x50:g} µm "
          f"(–: below the finest class edge, {a.finest:g} µm)")
    for r in rows:
        print(f"\n{r['condition']}")
        print(f"{'time (h)':>9}  {'x10':>8}  {'x50':>8}  {'x90':>8}")
        for i, h in enumerate(r["hours"]):
            print(f"{h:>9.4g}  {_um(r['x10_m'][i]):>8}  {_um(r['x50_m'][i]):>8}  {_um(r['x90_m'][i]):>8}")
        if "time_to_target_x90_s" in r:
            t = r["time_to_target_x90_s"]
            print(f"x90 ≤ {a.target_x90:g} µm after {t / 3600:.3g} h" if math.isfinite(t)
                  else f"x90 ≤ {a.target_x90:g} µm: not within 10000 h")
    return 0
