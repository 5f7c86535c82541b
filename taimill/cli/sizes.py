"""`taimill sizes check SIZES.csv`, `taimill sizes fit SIZES.csv --out FIT.toml` and
`taimill sizes predict PARAMS.toml|--fit FIT.toml CONDITION…`: measured particle size
distributions read and summarised (x10, x50, x90), the population balance fitted to
them with intervals, and its distributions over milling time at runs, sweep points or
condition files, with bands from a fit (docs/outcome.md, "Particle sizes")."""

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
    f = s.add_parser("fit", help="fit the population balance to measured size distributions (two conditions or more)")
    f.add_argument("sizes", type=path_text, help="CSV of measured distributions (as for check; optional sigma_pct|"
                   "sigma_fraction column); the distribution at time 0 of a condition is its feed")
    f.add_argument("--out", type=path_text, required=True, help="the fit, written as TOML")
    f.add_argument("--figure", type=path_text, help="distributions, x50 and x90 with bands, selection rates (PNG or SVG)")
    f.add_argument("--fix", action="append", default=[], metavar="NAME=VALUE",
                   help="hold a parameter at a value (f_mat, xw_min, capture_g, k_att, phi, gamma, beta)")
    f.add_argument("--free", action="append", default=[], metavar="NAME",
                   help="fit a parameter held by default (capture_g, beta, k_att)")
    f.add_argument("--feed-x50", type=number, metavar="UM",
                   help="the feed's median size (µm, log-normal) for conditions without a distribution at time 0")
    f.add_argument("--feed-spread", type=number, default=0.5, help="the feed's σ of ln x (default 0.5)")
    f.add_argument("--measure", default="dissipated_normal", help="energy measure of the impact route (default "
                   "dissipated_normal)")
    f.add_argument("--all-contacts", action="store_true", help="every contact drives the impact route (default: "
                   "stress events only)")
    f.add_argument("--level", type=number, default=0.95, help="confidence level of the intervals (default 0.95)")
    f.add_argument("--overwrite", action="store_true", help="replace an existing --out or --figure that taimill sizes wrote")
    f.add_argument("--json", action="store_true", help="print one JSON object")
    f.set_defaults(fn=cmd_fit)
    q = s.add_parser("predict", help="size distributions over milling time from a parameter file or a fit, at conditions")
    q.add_argument("inputs", type=path_text, nargs="+", metavar="FILE",
                   help="PARAMS.toml CONDITION… without --fit, CONDITION… with it: a grinding parameter file (TOML: "
                   "[breakage], [impact], [attrition]), then run stores, SWEEP.zarr#INDEX, a whole sweep SWEEP.zarr, "
                   "or condition files NAME.json")
    q.add_argument("--fit", type=path_text, metavar="FIT.toml", help="a fit file of taimill sizes fit: bands on "
                   "x10, x50, x90 and on the time to target")
    q.add_argument("--rank", action="store_true", help="order the conditions by time to --target-x90, fastest first")
    q.add_argument("--figure", type=path_text, help="distributions, x50 and x90 with bands, selection rates (PNG or SVG)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing --figure that taimill drew")
    q.add_argument("--feed-x50", type=number, metavar="UM",
                   help="the feed's median size (µm), log-normal (with --fit: default the fit's feed)")
    q.add_argument("--feed-spread", type=number, default=0.5, help="the feed's σ of ln x (default 0.5)")
    q.add_argument("--top", type=number, metavar="UM", help="coarsest size class edge (µm; default 4 × feed x50)")
    q.add_argument("--finest", type=number, metavar="UM", help="finest size class edge (µm; default 0.1)")
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


def cmd_predict(a) -> int:
    from taimill.errors import ConfigError

    if a.fit is not None:
        return _predict_fit(a)
    if len(a.inputs) < 2:
        raise ConfigError("command line", "CONDITION", None, "missing: give PARAMS.toml and one condition or more "
                          "(or --fit FIT.toml and the conditions)")
    if a.figure:
        raise ConfigError("command line", "--figure", a.figure, "draws a fit's bands: give --fit FIT.toml")
    if a.rank and a.target_x90 is None:
        raise ConfigError("command line", "--rank", "", "orders by the time to a target: give --target-x90")
    a.params, a.conditions = a.inputs[0], a.inputs[1:]
    return _predict_params(a)


def _predict_params(a) -> int:
    from taimill.cli.common import plain
    from taimill.cli.kinetics import _conditions, _expand
    from taimill.errors import ConfigError
    from taimill.model.files import reads
    from taimill.outcome.grinding import (
        SizeClasses,
        feed,
        grind,
        passing,
        quantile_size,
        selection,
        time_to_x90,
    )

    with reads():
        g = read_params(a.params)
    a.finest = 0.1 if a.finest is None else a.finest
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
    if a.rank:
        rows.sort(key=lambda r: r["time_to_target_x90_s"])
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


def _fixes(texts: list[str], frees: list[str]) -> tuple[dict, list[str]]:
    """--fix NAME=VALUE and --free NAME, each name checked (taimill.outcome.sizes_fit.PARAMS)."""
    from taimill.errors import ConfigError
    from taimill.outcome.sizes_fit import HELD, PARAMS

    out = {}
    for text in texts:
        name, eq, value = (x.strip() for x in text.partition("="))
        if name not in PARAMS:
            raise ConfigError("command line", "--fix", text, f"NAME=VALUE with NAME one of {', '.join(PARAMS)}")
        try:
            v = float(value) if eq else math.nan
        except ValueError:
            v = math.nan
        _, lo, hi, unit = PARAMS[name]
        zero_ok = name in ("xw_min", "k_att")
        if not (math.isfinite(v) and (v >= 0 if zero_ok else v > 0) and v <= (1.0 if name == "phi" else hi)):
            raise ConfigError("command line", "--fix", text, f"{name} allowed range {'[0' if zero_ok else '(0'}, "
                              f"{1 if name == 'phi' else hi:g}] {unit}")
        out[name] = v
    for name in frees:
        if name not in HELD:
            raise ConfigError("command line", "--free", name, f"one of {', '.join(HELD)} (the others are fitted unless --fix)")
        if name in out:
            raise ConfigError("command line", "--free", name, "is also held by --fix")
    return out, list(frees)


def _measured_quantile(x, q, share: float) -> float:
    import numpy as np

    return math.exp(float(np.interp(share, q, np.log(x)))) if q[0] <= share <= q[-1] else math.nan


def _figure_rows(fit, conds: dict, feeds: dict, times_s: list, until_s: float, label=lambda c: c) -> list[dict]:
    """What taimill.figures.sizes draws for each condition: distributions at `times_s`,
    x50 and x90 with bands up to `until_s`, the selection rates."""
    import numpy as np

    from taimill.outcome import sizes_fit as sf

    rows = []
    curve_t = np.linspace(0.0, until_s, 25)
    for c, cond in conds.items():
        q = sf.quantiles(fit, cond, feeds[c], curve_t, (0.5, 0.9))
        s = sf.selection_rates(fit, cond)
        rows.append({"label": label(c), "edges_m": fit.classes.edges, "times_s": times_s,
                     "passing": sf.distribution(fit, cond, feeds[c], times_s),
                     "curve": {"time_s": curve_t, "x50": q[0.5], "x90": q[0.9]},
                     "impact": s["impact"], "attrition": s["attrition"], "sizes_m": fit.classes.sizes})
    return rows


def cmd_fit(a) -> int:
    import os
    import sys

    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.common import plain
    from taimill.cli.kinetics import (
        _check_outputs,
        _commit,
        _condition_paths,
        _conditions,
        _writing,
    )
    from taimill.errors import ConfigError
    from taimill.figures import is_figure
    from taimill.model.files import reads
    from taimill.model.spectra import MEASURES
    from taimill.outcome import sizes_fit as sf
    from taimill.outcome.sizes import read_distributions
    from taimill.store.output import Outputs

    if not 0.5 <= a.level < 1:
        raise ConfigError("command line", "--level", a.level, "allowed range [0.5, 1)")
    if a.measure not in MEASURES:
        raise ConfigError("command line", "--measure", a.measure, f"allowed: {', '.join(MEASURES)}")
    if a.feed_x50 is not None and not 0.001 <= a.feed_x50 <= 1e5:
        raise ConfigError("command line", "--feed-x50", a.feed_x50, "allowed range [0.001, 100000] µm")
    if not 0.01 <= a.feed_spread <= 5.0:
        raise ConfigError("command line", "--feed-spread", a.feed_spread, "allowed range [0.01, 5]")
    fix, free = _fixes(a.fix, a.free)
    base = os.path.dirname(a.sizes) or "."
    with reads() as inputs:
        dists = read_distributions(a.sizes)
        names = [d.condition for d in dists]
        conds = _conditions(list(dict.fromkeys(names)), base, a.sizes)
    data = sf.prepare(dists, a.sizes, None if a.feed_x50 is None else a.feed_x50 * 1e-6, a.feed_spread)
    inputs = [*inputs, a.sizes, *_condition_paths(names, base)]
    given = _check_outputs([("--out", a.out, "fit file", sf.is_fit_file, ()),
                            ("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES)], a.overwrite, inputs)
    with Outputs() as outs:
        build = _writing(outs, given, a.overwrite, inputs)
        result = sf.fit_sizes(data, conds, fix, free, a.measure, not a.all_contacts, a.level, a.sizes)
        sf.write_fit(build["--out"], result, f"taimill sizes fit {a.sizes}: the population balance on the {a.measure} "
                                             f"spectra{'' if a.all_contacts else ', stress events only'}")
        if a.figure:
            from taimill.figures.sizes import sizes_figure

            measured = {c: [(t, x, q) for t, x, q, _ in data.points[c]] for c in data.conditions}
            last = max(t for rows in measured.values() for t, _, _ in rows)
            times = sorted({0.0, *(t for rows in measured.values() for t, _, _ in rows)})
            sizes_figure(build["--figure"], _figure_rows(result, conds, data.feeds, times, 1.2 * last), measured,
                         title=f"population balance fitted ({result.level:.0%} bands)")
        _commit(outs)
    for w in result.warnings:
        print(f"taimill: warning: {w}", file=sys.stderr)
    if a.json:
        out = vars(result) | {"classes": {"top_m": result.classes.top_m, "n": result.classes.n,
                                          "ratio": result.classes.ratio}}
        print(json.dumps(plain(out)))
    else:
        print(fit_table(result))
        print(f"wrote {a.out}")
    return 0


def fit_table(f) -> str:
    from taimill.outcome.sizes_fit import PARAMS

    lines = [f"population balance fitted to {f.goodness['n_points']} passing shares at {len(f.conditions)} conditions "
             f"(measure {f.measure}, {'stress events' if f.stress_only else 'all contacts'}; sigma {f.sigma})",
             f"{'parameter':<10} {'value':>11}  {'unit':<9} {f.level:.0%} interval ({f.interval_method})"]
    for name, v in f.params.items():
        lo, hi = f.intervals[name]
        flags = [e.split()[1] for e in f.open_ends if e.split()[0] == name]
        shown = f"[{'…' if 'lower' in flags else ''}{lo:.4g}, {hi:.4g}{'…' if 'upper' in flags else ''}]"
        lines.append(f"{name:<10} {v:>11.4g}  {PARAMS[name][3]:<9} {shown}")
    lines += [f"{name:<10} {v:>11.4g}  {PARAMS[name][3]:<9} (held)" for name, v in f.fixed.items()]
    g = f.goodness
    lines.append(f"χ² = {g['chi2']:.4g} for {g['dof']} dof (p = {g['p_value']:.3g}), RMSE {g['rmse']:.4g} (share)")
    return "\n".join(lines)


def _predict_fit(a) -> int:
    import numpy as np

    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.common import plain
    from taimill.cli.kinetics import (
        _check_outputs,
        _commit,
        _condition_paths,
        _conditions,
        _expand,
        _writing,
    )
    from taimill.errors import ConfigError
    from taimill.figures import is_figure
    from taimill.model.files import reads
    from taimill.outcome import sizes_fit as sf
    from taimill.outcome.grinding import HOURS_MAX, feed
    from taimill.store.output import Outputs

    with reads() as inputs:
        fit = sf.read_fit(a.fit)
    classes = fit.classes
    for option in ("top", "finest"):
        if getattr(a, option) is not None:
            raise ConfigError("command line", f"--{option}", getattr(a, option), "not with --fit: the size classes are "
                              "the fit's")
    finest_um, top_um = classes.edges[-1] * 1e6, classes.top_m * 1e6
    if a.feed_x50 is not None:
        for option, v, lo, hi in (("--feed-x50", a.feed_x50, finest_um, top_um), ("--feed-spread", a.feed_spread, 0.01, 5.0)):
            if not lo <= v <= hi:
                raise ConfigError("command line", option, v, f"allowed range [{lo:.4g}, {hi:.4g}] (the fit's classes)")
        m0 = feed(classes, a.feed_x50 * 1e-6, a.feed_spread)
    else:
        m0 = np.asarray(fit.feed) / sum(fit.feed)
    if a.target_x90 is not None and not finest_um < a.target_x90 < top_um:
        raise ConfigError("command line", "--target-x90", a.target_x90,
                          f"allowed range ({finest_um:.4g}, {top_um:.4g}) µm (the fit's classes)")
    if a.rank and a.target_x90 is None:
        raise ConfigError("command line", "--rank", "", "orders by the time to a target: give --target-x90")
    hours = _hours(a.hours)
    with reads() as more:
        names = _expand(a.inputs)
        conds = _conditions(names, ".", "command line")
    inputs = [*inputs, *more, a.fit, *_condition_paths(names, ".")]
    given = _check_outputs([("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES)], a.overwrite, inputs)
    times = [h * 3600.0 for h in hours]
    rows = []
    for name, cond in conds.items():
        q = sf.quantiles(fit, cond, m0, times)
        row = {"condition": name, "hours": hours}
        for f in QUANTILES:
            v, lo, hi = q[f]
            row |= {f"x{round(100 * f)}_m": v, f"x{round(100 * f)}_lower_m": lo, f"x{round(100 * f)}_upper_m": hi}
        if a.target_x90 is not None:
            t, lo, hi = sf.time_to_target(fit, cond, m0, a.target_x90 * 1e-6)
            row |= {"time_to_target_x90_s": t, "lower_s": lo, "upper_s": hi}
        rows.append(row)
    if a.rank:
        rows.sort(key=lambda r: r["time_to_target_x90_s"])
    if a.figure:
        from taimill.figures.sizes import sizes_figure

        with Outputs() as outs:
            path = _writing(outs, given, a.overwrite, inputs)["--figure"]
            order = {r["condition"]: conds[r["condition"]] for r in rows}
            sizes_figure(path, _figure_rows(fit, order, {c: m0 for c in order}, times, max(times) or 3600.0),
                         target_m=None if a.target_x90 is None else a.target_x90 * 1e-6,
                         title=f"population balance predicted from {a.fit} ({fit.level:.0%} bands)")
            _commit(outs)
    if a.json:
        listed = [{k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in r.items()} for r in rows]
        print(json.dumps(plain({"fit": a.fit, "level": fit.level, "feed_x50_m": None if a.feed_x50 is None
                                else a.feed_x50 * 1e-6, "conditions": listed})))
        return 0
    def band(r, k, i):  # time 0: the feed, which no parameter moves
        v, lo, hi = r[k + "_m"][i], r[k + "_lower_m"][i], r[k + "_upper_m"][i]
        return f"{_um(v)} (feed)" if r["hours"][i] == 0 else f"{_um(v)} [{_um(lo)}, {_um(hi)}]"

    print(f"{a.fit}: x10 / x50 / x90 (µm) against milling time, {fit.level:.0%} bands; feed "
          f"{'the fit' + chr(39) + 's' if a.feed_x50 is None else f'log-normal, x50 {a.feed_x50:g} µm'}")
    for r in rows:
        print(f"\n{r['condition']}")
        print(f"{'time (h)':>9}  {'x10':>24}  {'x50':>24}  {'x90':>24}")
        for i, h in enumerate(r["hours"]):
            print(f"{h:>9.4g}  {band(r, 'x10', i):>24}  {band(r, 'x50', i):>24}  {band(r, 'x90', i):>24}")
    if a.target_x90 is not None:
        w = max(len("condition"), *(len(r["condition"]) for r in rows))
        print(f"\ntime until x90 ≤ {a.target_x90:g} µm{' (fastest first)' if a.rank else ''}")
        print(f"{'condition':<{w}}  {'time (h)':>9}  {'band (h)':>21}")
        for r in rows:
            t = r["time_to_target_x90_s"]
            if math.isfinite(t):
                print(f"{r['condition']:<{w}}  {t / 3600:>9.4g}  "
                      f"{'[' + format(r['lower_s'] / 3600, '.4g') + ', ' + format(r['upper_s'] / 3600, '.4g') + ']':>21}")
            else:
                print(f"{r['condition']:<{w}}  {'never':>9}  (not within {HOURS_MAX:g} h)")
    return 0
