"""`taimill kinetics fit POINTS.csv` and `taimill kinetics predict FIT.toml CONDITION…`:
an outcome model fitted to the user's measured points, and what it predicts at other
conditions (docs/outcome.md)."""

from __future__ import annotations

import json
import math
import os
import sys

from taimill.cli.common import number, path_text

DEFAULT_MODEL = "critical-collisions"
DEFAULT_MEASURE = "dissipated_normal"
CURVE_POINTS = 60  #: times along a drawn or printed curve


def register(sub) -> None:
    from taimill.model.spectra import MEASURES
    from taimill.outcome.models import MODELS

    p = sub.add_parser("kinetics", help="fit an outcome model to measured points; predict other conditions")
    k = p.add_subparsers(dest="kinetics", required=True)
    f = k.add_parser("fit", help="fit a model to measured points (CSV: condition, time_s, value[, sigma])")
    f.add_argument("points", type=path_text, help="CSV of measured points (docs/outcome.md)")
    f.add_argument("--model", choices=list(MODELS), default=DEFAULT_MODEL, help=f"outcome model (default {DEFAULT_MODEL})")
    f.add_argument("--measure", choices=list(MEASURES), default=DEFAULT_MEASURE,
                   help=f"energy measure of the spectra (default {DEFAULT_MEASURE})")
    f.add_argument("--stress-only", action="store_true", help="count stress events only (default: every contact)")
    f.add_argument("--fix", action="append", default=[], metavar="NAME=VALUE", help="hold a parameter at a value")
    f.add_argument("--level", type=number, default=0.95, help="confidence level of the intervals (default 0.95)")
    f.add_argument("--out", type=path_text, required=True, help="the fit, written as TOML")
    f.add_argument("--figure", type=path_text, help="measured and fitted curves with bands (PNG or SVG)")
    f.add_argument("--stress-figure", type=path_text,
                   help="the stress-model plot: measured values against the stress number above the fitted threshold")
    f.add_argument("--overwrite", action="store_true",
                   help="replace an existing --out, --figure or --stress-figure that taimill kinetics wrote")
    f.add_argument("--json", action="store_true", help="print one JSON object")
    f.set_defaults(fn=cmd_fit)
    q = k.add_parser("predict", help="a fit's curves and time to a target at runs, sweep points or a whole sweep")
    q.add_argument("fit", type=path_text, help="a fit file (taimill kinetics fit --out)")
    q.add_argument("conditions", type=path_text, nargs="+",
                   help="run stores, SWEEP.zarr#INDEX, a whole sweep SWEEP.zarr, or condition files NAME.json")
    q.add_argument("--target", type=number, help="the value to reach (default 0.9 for critical-collisions)")
    q.add_argument("--until", type=number, help="curves up to this milling time (s; default 1.5 × the longest time to target)")
    q.add_argument("--rank", action="store_true", help="order the conditions by time to target, fastest first")
    q.add_argument("--points", type=path_text, help="measured points (CSV) to draw beside the predictions")
    q.add_argument("--figure", type=path_text, help="predicted curves with bands (PNG or SVG)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing --figure that taimill drew")
    q.add_argument("--json", action="store_true", help="print one JSON object")
    q.set_defaults(fn=cmd_predict)


def _fixed(texts: list[str], model) -> dict:
    """--fix NAME=VALUE options: parameters of `model` held at a value."""
    from taimill.errors import ConfigError

    names = [p.name for p in model.params]
    out = {}
    for text in texts:
        name, eq, value = (x.strip() for x in text.partition("="))
        if name not in names:
            raise ConfigError("command line", "--fix", text, f"NAME=VALUE with NAME one of {', '.join(names)}")
        try:
            out[name] = float(value) if eq else math.nan
        except ValueError:
            out[name] = math.nan
        if not math.isfinite(out[name]):
            raise ConfigError("command line", "--fix", text, "NAME=VALUE with a finite number")
        p = next(q for q in model.params if q.name == name)
        if p.log and (out[name] < 0 if p.threshold else out[name] <= 0):
            raise ConfigError("command line", "--fix", text, f"{name} allowed range {'[0' if p.threshold else '(0'}, ∞)")
    return out


def _condition_paths(names, base: str) -> list[str]:
    """The files and folders the conditions `names` are read from (SWEEP.zarr#3: the sweep)."""
    out = []
    for n in names:
        path = n.partition("#")[0]
        out.append(path if os.path.isabs(path) else os.path.join(base, path))
    return out


def _check_outputs(outputs: list[tuple], overwrite: bool, inputs) -> list[tuple]:
    """The outputs (option, path, kind, ours, suffixes) a command will write, each
    checked before any work: a name of the right suffix in an existing, writable folder;
    an existing file replaced only with --overwrite, only if `ours` says taimill wrote
    it, and never one of `inputs`; no two options naming one file."""
    from taimill.errors import ConfigError
    from taimill.model.files import check_output

    given = [o for o in outputs if o[1]]
    seen = {}
    for option, path, kind, ours, suffixes in given:
        check_output(path, option, overwrite=overwrite, suffixes=suffixes, what=kind, ours=ours, inputs=inputs)
        real = os.path.realpath(path)
        if real in seen:
            raise ConfigError("command line", option, path, f"is also {seen[real]}; give each output its own file")
        seen[real] = option
    return given


def _writing(outs, given: list[tuple], overwrite: bool, inputs) -> dict:
    """option -> the path to write each output under (beside its place until `_commit`);
    an interrupt waits until every output is held, so that none leaves its lock behind."""
    from taimill.runs.signals import hold, release

    hold()
    try:
        return {option: outs.add(path, ours=ours, overwrite=overwrite, option=option, what=kind, inputs=inputs,
                                 whole=True, keep=lambda _: False)
                for option, path, kind, ours, _ in given}
    finally:
        release()


def _commit(outs) -> None:
    """Put every finished output in its place; an interrupt waits until all are."""
    from taimill.runs.signals import hold, release

    hold()
    try:
        outs.commit()
    finally:
        release()


def _conditions(names, base: str, source: str, pts=None) -> dict:
    """The conditions named, each opened once; a bad one named with the first line of
    the points file `pts` that gives it (or with `source`)."""
    from taimill.outcome.condition import open_condition

    out = {}
    for i, c in enumerate(names):
        if c not in out:
            where, key = (f"{source}:{pts.lines[i]}", f"column {pts.condition_column} (condition)") if pts else (source, "condition")
            out[c] = open_condition(c, base, where, key)
    return out


def cmd_fit(a) -> int:
    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.common import plain
    from taimill.errors import ConfigError
    from taimill.figures import is_figure
    from taimill.model.files import reads
    from taimill.outcome import fit as fitting, predict
    from taimill.outcome.files import check_values, is_fit_file, read_points, write_fit
    from taimill.outcome.models import MODELS
    from taimill.store.output import Outputs

    if not 0.5 <= a.level < 1:
        raise ConfigError("command line", "--level", a.level, "allowed range [0.5, 1)")
    model = MODELS[a.model](a.measure, a.stress_only)
    fixed = _fixed(a.fix, model)
    base = os.path.dirname(a.points) or "."
    with reads() as inputs:
        pts = check_values(read_points(a.points), model)
        conds = _conditions(pts.condition, base, a.points, pts)
    inputs = [*inputs, a.points, *_condition_paths(pts.condition, base)]
    given = _check_outputs([("--out", a.out, "fit file", is_fit_file, ()),
                            ("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES),
                            ("--stress-figure", a.stress_figure, "figure", is_figure, FIGURE_SUFFIXES)],
                           a.overwrite, inputs)
    with Outputs() as outs:
        build = _writing(outs, given, a.overwrite, inputs)
        result = fitting.fit(model, conds, pts, fixed, a.level)
        write_fit(build["--out"], result, f"taimill kinetics fit {a.points}: {model.name} ({model.quantity}) on the "
                                          f"{a.measure} spectra{', stress events only' if a.stress_only else ''}")
        if a.figure:
            _fit_figure(build["--figure"], result, conds, pts, predict)
        if a.stress_figure:
            _stress_figure(build["--stress-figure"], model, result, conds, pts)
        _commit(outs)
    for w in result.warnings:
        print(f"taimill: warning: {w}", file=sys.stderr)
    if a.json:
        print(json.dumps(plain(vars(result))))
    else:
        print(fit_table(result))
        print(f"wrote {a.out}")
    return 0


def fit_table(f) -> str:
    who = "all contacts" if not f.stress_only else "stress events"
    lines = [f"{f.model} fitted to {f.goodness['n_points']} points at {len(f.conditions)} conditions "
             f"(measure {f.measure}, {who}; sigma {f.sigma})",
             f"{'parameter':<14} {'value':>11}   {f.level:.0%} interval ({f.interval_method})"]
    for name, v in f.params.items():
        lo, hi = f.intervals[name]
        flags = [e.split()[1] for e in f.open_ends if e.split()[0] == name]
        shown = f"[{'…' if 'lower' in flags else ''}{lo:.4g}, {hi:.4g}{'…' if 'upper' in flags else ''}]"
        lines.append(f"{name:<14} {v:>11.4g}   {shown}")
    lines += [f"{name:<14} {v:>11.4g}   (held)" for name, v in f.fixed.items()]
    g = f.goodness
    if "chi2" in g:
        lines.append(f"χ² = {g['chi2']:.4g} for {g['dof']} dof (p = {g['p_value']:.3g}), RMSE {g['rmse']:.4g}, R² {g['r2']:.4g}")
    else:
        lines.append(f"residual sd {g['residual_sd']:.4g} ({g['dof']} dof), R² {g['r2']:.4g}")
    return "\n".join(lines)


def _fit_figure(path, result, conds, pts, predict) -> None:
    import numpy as np

    from taimill.figures.kinetics import outcome_figure

    curves, points = [], {}
    for c in result.conditions:
        sel = [i for i, n in enumerate(pts.condition) if n == c]
        t = np.linspace(0.0, 1.1 * float(pts.time[sel].max()), CURVE_POINTS)
        y, lo, hi = predict.curve(result, conds[c], t)
        curves.append({"label": c, "kind": "fitted", "time_s": t, "value": y, "lower": lo, "upper": hi})
        points[c] = (pts.time[sel], pts.value[sel], None if pts.sigma is None else pts.sigma[sel])
    outcome_figure(path, curves, points, ylabel=predict.model_of(result).quantity,
                   title=f"{result.model} on {result.measure}: fitted ({result.level:.0%} bands)")


def _stress_figure(path, model, result, conds, pts) -> None:
    """Values against the stress number above the fit's threshold: for a model that
    depends on the dose above the threshold only, the conditions fall on one curve."""
    from taimill.figures.kinetics import stress_model_figure
    from taimill.outcome.models import stress_model_points

    name = next(p.name for p in model.params if p.threshold)
    threshold = {**result.params, **result.fixed}[name]
    rows = stress_model_points(conds, zip(pts.condition, pts.time, pts.value), model.measure, threshold,
                               model.stress_only)
    stress_model_figure(path, rows, ylabel=model.quantity,
                        title=f"stress model: {model.measure} ≥ {threshold * 1e3:.3g} mJ ({name})")


def _expand(names: list[str]) -> list[str]:
    """A whole sweep stands for its finished points (SWEEP.zarr#INDEX each)."""
    from taimill.store.sweep import is_sweep, open_sweep

    out = []
    for n in names:
        if "#" not in n and is_sweep(n):
            out += [f"{n}#{i}" for i in sorted(open_sweep(n).done())]
        else:
            out.append(n)
    return out


def cmd_predict(a) -> int:
    import numpy as np

    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.common import plain
    from taimill.errors import ConfigError
    from taimill.figures import is_figure
    from taimill.model.files import reads
    from taimill.outcome import predict
    from taimill.outcome.files import read_fit
    from taimill.store.output import Outputs

    with reads() as inputs:
        fit = read_fit(a.fit)
    target = a.target if a.target is not None else (0.9 if fit.model == "critical-collisions" else None)
    if target is None:
        raise ConfigError("command line", "--target", None, f"missing: {fit.model} has no default target; give the value to reach")
    if fit.model == "critical-collisions" and not 0 < target < 1:
        raise ConfigError("command line", "--target", target, "allowed range (0, 1): a converted fraction")
    if a.until is not None and not a.until > 0:
        raise ConfigError("command line", "--until", a.until, "a time > 0 s")
    with reads() as more:
        names = _expand(a.conditions)
        conds = _conditions(names, ".", "command line")
        measured = _measured(a.points, fit) if a.points else {}
    inputs = [*inputs, *more, a.fit, *_condition_paths(names, "."), *([a.points] if a.points else [])]
    given = _check_outputs([("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES)], a.overwrite, inputs)
    rows = []
    for name, cond in conds.items():
        t, lo, hi = predict.time_to(fit, cond, target)
        spread, origin = predict.scatter(fit, cond)
        rows.append({"condition": name, "time_to_target_s": t, "lower_s": lo, "upper_s": hi,
                     "never_in_band": not math.isfinite(hi), "scatter": spread, "scatter_from": origin})
    if a.rank:
        rows.sort(key=lambda r: (not math.isfinite(r["time_to_target_s"]), r["time_to_target_s"]))
    longest = max((r["time_to_target_s"] for r in rows if math.isfinite(r["time_to_target_s"])), default=3600.0)
    last = max((float(max(t)) for t, _, _ in measured.values()), default=0.0)
    times = np.linspace(0.0, a.until or max(1.5 * longest, 1.1 * last), CURVE_POINTS)
    for r in rows:
        y, lo, hi = predict.curve(fit, conds[r["condition"]], times)
        r["curve"] = {"time_s": times, "value": y, "lower": lo, "upper": hi}
    if a.figure:
        with Outputs() as outs:
            _predict_figure(_writing(outs, given, a.overwrite, inputs)["--figure"], fit, rows, measured, target, predict)
            _commit(outs)
    warnings = fit.warnings + ([] if fit.profiles else [predict.LINEARISED])
    for w in warnings:
        print(f"taimill: warning: {a.fit}: {w}", file=sys.stderr)
    if a.json:
        print(json.dumps(plain({"model": fit.model, "measure": fit.measure, "target": target, "level": fit.level,
                                "warnings": warnings, "band": "profile" if fit.profiles else "linearised",
                                "conditions": [r | {"curve": {k: list(v) for k, v in r["curve"].items()}} for r in rows]})))
    else:
        print(predict_table(fit, rows, target))
    return 0


def predict_table(fit, rows: list[dict], target: float) -> str:
    w = max(len("condition"), *(len(r["condition"]) for r in rows))
    lines = [f"{fit.model} ({fit.measure}): time to reach {target:g}, {fit.level:.0%} band",
             f"{'condition':<{w}}  {'time (s)':>10}  {'(min)':>8}  {'band (s)':>21}"]
    for r in rows:
        t = r["time_to_target_s"]
        band = f"[{_seconds(r['lower_s'])}, {_seconds(r['upper_s'])}]"
        if math.isfinite(t):
            lines.append(f"{r['condition']:<{w}}  {t:>10.4g}  {t / 60:>8.3g}  {band:>21}")
        else:
            lines.append(f"{r['condition']:<{w}}  {'never':>10}  {'':>8}  {band:>21}")
    return "\n".join(lines)


def _seconds(v: float) -> str:
    """A band's end: ∞ is "never" (the parameters the data allow include no conversion)."""
    return "never" if v == math.inf else format(v, ".4g")


def _measured(points_csv: str, fit) -> dict:
    """label -> (time_s, value, sigma) of a points CSV, its values in the range of the
    fit's model; its conditions, named from the CSV's folder, labelled by their path
    from here like the predicted curves."""
    from taimill.outcome.files import check_values, read_points
    from taimill.outcome.models import MODELS

    pts, out = check_values(read_points(points_csv, key="--points"), MODELS[fit.model]), {}
    for c in dict.fromkeys(pts.condition):
        sel = [i for i, n in enumerate(pts.condition) if n == c]
        label = os.path.normpath(os.path.join(os.path.dirname(points_csv), c))
        out[label] = (pts.time[sel], pts.value[sel], None if pts.sigma is None else pts.sigma[sel])
    return out


def _predict_figure(path, fit, rows, measured: dict, target, predict) -> None:
    """Predicted curves; those of conditions with measured points are drawn as fitted."""
    from taimill.figures.kinetics import outcome_figure

    curves = [{"label": os.path.normpath(r["condition"]), **r["curve"],
               "kind": "fitted" if os.path.normpath(r["condition"]) in measured else "predicted"} for r in rows]
    outcome_figure(path, curves, measured, target, ylabel=predict.model_of(fit).quantity,
                   title=f"{fit.model} on {fit.measure} ({fit.level:.0%} bands)")
