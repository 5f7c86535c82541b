"""`taimill wear fit MEASURED.csv --out FIT.toml` and `taimill wear predict RUN.zarr…`:
wear of balls and jar as mass from a run's friction work and impact energy (Archard),
the contamination it puts into the powder against milling time, and where the wall
wears deepest (docs/wear.md)."""

from __future__ import annotations

import json
import math
import os
import sys

from taimill.cli.common import number, path_text
from taimill.cli.kinetics import _check_outputs, _commit, _writing

CURVE_POINTS = 60


def _positive(text: str) -> float:
    import argparse

    v = number(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: allowed range [0, ∞)")
    return v


def register(sub) -> None:
    p = sub.add_parser("wear", help="ball and jar wear as mass and the powder's contamination (Archard)")
    w = p.add_subparsers(dest="wear", required=True)
    f = w.add_parser("fit", help="fit the wear coefficient to measured contamination "
                     "(CSV: condition, time, contamination)")
    f.add_argument("measured", type=path_text, help="CSV: condition, time_h|time_min|time_s, "
                   "contamination_pct|contamination_fraction (docs/wear.md)")
    f.add_argument("--out", type=path_text, required=True, help="the fit, written as TOML")
    f.add_argument("--impact", action="store_true", help="fit an impact wear coefficient as well (default: held at 0)")
    f.add_argument("--impact-threshold", type=_positive, default=0.0, metavar="J",
                   help="impact energies counted from this normal stress energy (J; default 0)")
    f.add_argument("--level", type=number, default=0.95, help="confidence level of the intervals (default 0.95)")
    f.add_argument("--figure", type=path_text, help="measured and fitted contamination against time (PNG or SVG)")
    f.add_argument("--overwrite", action="store_true", help="replace an existing --out or --figure that taimill wrote")
    f.add_argument("--json", action="store_true", help="print one JSON object")
    f.set_defaults(fn=cmd_fit)
    q = w.add_parser("predict", help="worn mass by surface, contamination against time, wall wear depth")
    q.add_argument("runs", type=path_text, nargs="+", help="run stores RUN.zarr")
    q.add_argument("--hours", type=_positive, nargs="+", default=[1.0, 8.0, 32.0, 64.0],
                   help="milling times (h) to give the contamination at (default 1 8 32 64)")
    q.add_argument("--fit", type=path_text, help="a wear fit (taimill wear fit --out)")
    q.add_argument("--k-friction", "--k-wall", dest="k_friction", type=_positive,
                   help="wear coefficient on friction work (V = k W_f / H), instead of --fit")
    q.add_argument("--k-impact", type=_positive, default=None, help="wear coefficient on impact energy (default 0)")
    q.add_argument("--impact-threshold", type=_positive, default=None, metavar="J",
                   help="impact energies counted from this normal stress energy (J; default 0, or the fit's)")
    q.add_argument("--figure", type=path_text, help="contamination against time with bands (PNG or SVG)")
    q.add_argument("--map", type=path_text, help="the wall wear-depth map in µm/h of the one run given (PNG or SVG)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing --figure or --map that taimill drew")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(fn=cmd_predict)


def _runs(names, base: str, pts, threshold: float) -> dict:
    """The run stores named, each opened once; a bad one named with the first CSV
    line that gives it (or the command line)."""
    from taimill.outcome.wearfiles import open_wear_condition

    out = {}
    for i, c in enumerate(names):
        if c not in out:
            where, key = (f"{pts.source}:{pts.lines[i]}", f"column {pts.condition_column} (condition)") if pts else \
                ("command line", "RUN")
            out[c] = open_wear_condition(c, base, where, key, threshold)
    return out


def cmd_fit(a) -> int:
    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.common import plain
    from taimill.errors import ConfigError
    from taimill.figures import is_figure
    from taimill.model.files import reads
    from taimill.outcome import fit as fitting
    from taimill.outcome.wear import Wear
    from taimill.outcome.wearfiles import is_fit_file, read_measured, write_fit
    from taimill.store.output import Outputs

    if not 0.5 <= a.level < 1:
        raise ConfigError("command line", "--level", a.level, "allowed range [0.5, 1)")
    base = os.path.dirname(a.measured) or "."
    with reads() as inputs:
        pts = read_measured(a.measured)
        conds = _runs(pts.condition, base, pts, a.impact_threshold)
    if a.impact and any(c.impact_w is None for c in conds.values()):
        bad = next(n for n, c in conds.items() if c.impact_w is None)
        raise ConfigError("command line", "--impact", bad,
                          "runs that kept their event rows (outputs.events = \"rows\")")
    inputs = [*inputs, a.measured, *(n if os.path.isabs(n) else os.path.join(base, n) for n in conds)]
    given = _check_outputs([("--out", a.out, "fit file", is_fit_file, ()),
                            ("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES)], a.overwrite, inputs)
    result = fitting.fit(Wear(), conds, pts, {} if a.impact else {"k_impact": 0.0}, a.level)
    with Outputs() as outs:
        build = _writing(outs, given, a.overwrite, inputs)
        write_fit(build["--out"], result, a.impact_threshold,
                  f"taimill wear fit {a.measured}: Archard wear on friction work"
                  f"{' and impact energy ≥ ' + format(a.impact_threshold, 'g') + ' J' if a.impact else ''}")
        if a.figure:
            _figure(build["--figure"], _curves(conds, _k(result), _intervals(result), None, "fitted"), _measured(pts),
                    f"wear fit ({result.level:.0%} bands)")
        _commit(outs)
    for w in result.warnings:
        print(f"taimill: warning: {w}", file=sys.stderr)
    if a.json:
        print(json.dumps(plain({"params": result.params, "intervals": result.intervals, "fixed": result.fixed,
                                "level": result.level, "goodness": result.goodness, "warnings": result.warnings,
                                "conditions": result.conditions, "impact_threshold_J": a.impact_threshold})))
    else:
        lines = [f"Archard wear fitted to {result.goodness['n_points']} measurements at {len(result.conditions)} runs",
                 f"{'coefficient':<12} {'value':>11}   {result.level:.0%} interval"]
        lines += [f"{n:<12} {v:>11.4g}   [{result.intervals[n][0]:.4g}, {result.intervals[n][1]:.4g}]"
                  for n, v in result.params.items()]
        lines += [f"{n:<12} {v:>11.4g}   (held)" for n, v in result.fixed.items()]
        print("\n".join(lines))
        print(f"wrote {a.out}")
    return 0


def _k(result) -> dict:
    return {**result.fixed, **result.params}


def _intervals(result) -> dict:
    return {n: result.intervals.get(n, (v, v)) for n, v in _k(result).items()}


def _measured(pts) -> dict:
    import numpy as np

    out = {}
    for c in dict.fromkeys(pts.condition):
        sel = [i for i, n in enumerate(pts.condition) if n == c]
        out[c] = (pts.time[sel], 100.0 * np.asarray(pts.value[sel]), None)
    return out


def _curves(conds: dict, k: dict, intervals: dict | None, hours, kind: str = "predicted") -> list[dict]:
    """Contamination (%) against time for each run at k, with the band of the k
    intervals (contamination grows with every k, so the band is the ends together)."""
    import numpy as np

    from taimill.outcome.wear import contamination

    top = max(hours) if hours else 64.0
    t = np.linspace(0.0, 1.1 * top * 3600.0, CURVE_POINTS)
    lo = {n: v[0] for n, v in intervals.items()} if intervals else k
    hi = {n: v[1] for n, v in intervals.items()} if intervals else k
    return [{"label": name, "kind": kind, "time_s": t,
             "value": 100 * contamination(c, k["k_friction"], k["k_impact"], t),
             "lower": 100 * contamination(c, lo["k_friction"], lo["k_impact"], t),
             "upper": 100 * contamination(c, hi["k_friction"], hi["k_impact"], t)} for name, c in conds.items()]


def _figure(path, curves, measured, title) -> None:
    from taimill.figures.kinetics import outcome_figure

    outcome_figure(path, curves, measured, ylabel="contamination (% of the powder)", title=title)


def _map(path, cond, k: dict) -> None:
    from taimill.figures.wear import depth_figure
    from taimill.outcome.wear import WALLS, depth_map

    maps = {s: depth_map(cond, s, k["k_friction"], k["k_impact"]) for s in WALLS}
    depth_figure(path, cond.wall_map, maps, f"{cond.name}: wall wear depth at k_f {k['k_friction']:.3g}, "
                                            f"k_i {k['k_impact']:.3g}")


def cmd_predict(a) -> int:
    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.common import plain
    from taimill.errors import ConfigError
    from taimill.figures import is_figure
    from taimill.model.files import reads
    from taimill.outcome.wear import SURFACES, contamination, depth_summary, mass_rates
    from taimill.outcome.wearfiles import read_fit

    if (a.fit is None) == (a.k_friction is None):
        raise ConfigError("command line", "--fit", a.fit, "give either --fit FIT.toml or --k-friction K (one of them)")
    with reads() as inputs:
        fit = read_fit(a.fit) if a.fit else None
    if fit:
        if a.k_impact is not None:
            raise ConfigError("command line", "--k-impact", a.k_impact, "not with --fit: the fit gives k_impact")
        k, intervals, threshold = fit["k"], fit["intervals"], fit["threshold_j"]
        if a.impact_threshold is not None and a.impact_threshold != threshold:
            raise ConfigError("command line", "--impact-threshold", a.impact_threshold,
                              f"the fit's {threshold:g} J: its k_impact holds for that threshold only")
        intervals = {n: intervals.get(n, (v, v)) for n, v in k.items()}
    else:
        k = {"k_friction": a.k_friction, "k_impact": a.k_impact or 0.0}
        intervals, threshold = None, a.impact_threshold or 0.0
    with reads() as more:
        conds = _runs(a.runs, ".", None, threshold)
    inputs = [*inputs, *more, *([a.fit] if a.fit else []), *a.runs]
    given = _check_outputs([("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES),
                            ("--map", a.map, "figure", is_figure, FIGURE_SUFFIXES)], a.overwrite, inputs)
    if a.map and (len(conds) != 1 or next(iter(conds.values())).wall_map is None):
        raise ConfigError("command line", "--map", a.map, "one run, which kept its event rows (outputs.events = "
                          "\"rows\"): the map is of one run's walls")
    rows = []
    for name, c in conds.items():
        if k["k_impact"] > 0 and c.impact_w is None:
            raise ConfigError("command line", "RUN", name, "a run that kept its event rows: k_impact > 0 needs its "
                              "impact energies (outputs.events = \"rows\")")
        row = {"run": name, "balls": c.balls.material, "wall": c.wall.material, "powder_g": c.powder_g,
               "worn_g_per_h": mass_rates(c, k["k_friction"], k["k_impact"])}
        row["worn_g_per_h_total"] = sum(row["worn_g_per_h"].values())
        hours = list(a.hours)
        row["contamination"] = {"hours": hours, "percent": list(100 * contamination(c, k["k_friction"], k["k_impact"],
                                                                                    [h * 3600 for h in hours]))}
        if intervals:
            for end, side in (("lower", 0), ("upper", 1)):
                kk = {n: v[side] for n, v in intervals.items()}
                row["contamination"][f"{end}_percent"] = list(
                    100 * contamination(c, kk["k_friction"], kk["k_impact"], [h * 3600 for h in hours]))
        if c.wall_map is not None:
            row["wall_depth"] = depth_summary(c, k["k_friction"], k["k_impact"])
        rows.append(row)
    if given:
        from taimill.store.output import Outputs

        with Outputs() as outs:
            build = _writing(outs, given, a.overwrite, inputs)
            if a.figure:
                _figure(build["--figure"], _curves(conds, k, intervals, a.hours), {},
                        "wear: contamination against milling time" + (f" ({fit['level']:.0%} bands)" if fit else ""))
            if a.map:
                _map(build["--map"], next(iter(conds.values())), k)
            _commit(outs)
    out = {"k": k, "intervals": intervals, "impact_threshold_J": threshold, "runs": rows}
    if a.json:
        print(json.dumps(plain(out)))
    else:
        print(predict_table(out, SURFACES))
    return 0


def predict_table(out: dict, surfaces) -> str:
    k = out["k"]
    lines = [f"Archard wear: k_friction {k['k_friction']:.4g}, k_impact {k['k_impact']:.4g} "
             f"(impact energies ≥ {out['impact_threshold_J']:g} J)"]
    for r in out["runs"]:
        lines.append(f"\n{r['run']}: balls {r['balls']}, wall {r['wall']}, powder {r['powder_g']:.4g} g")
        lines.append("worn (mg/h): " + ", ".join(f"{s} {1e3 * r['worn_g_per_h'][s]:.4g}" for s in surfaces)
                     + f"; total {1e3 * r['worn_g_per_h_total']:.4g}")
        c = r["contamination"]
        for i, h in enumerate(c["hours"]):
            band = (f"  [{c['lower_percent'][i]:.3g}, {c['upper_percent'][i]:.3g}]" if "lower_percent" in c else "")
            lines.append(f"  {h:>6g} h: contamination {c['percent'][i]:.4g} %{band}")
        for s, d in (r.get("wall_depth") or {}).items():
            deep = (f", deepest {d['max_um_per_h']:.3g} µm/h (±{100 * d['max_rel_error']:.0f} % counting)"
                    if math.isfinite(d["max_um_per_h"]) else ", too few events a cell to name the deepest")
            lines.append(f"  {s} wall: mean {d['mean_um_per_h']:.3g} µm/h{deep}")
    return "\n".join(lines)
