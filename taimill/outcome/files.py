"""The files of outcome work (docs/outcome.md): measured points (CSV) in, a fit (TOML)
out and back. Bad input is a one-line ConfigError naming the file, line, column and
value and what is allowed.

Points CSV: a header line naming the columns `condition`, `time_s`, `value` and
optionally `sigma` (any order; `#` lines and blank lines are skipped), then one line a
point. condition: a run store (RUN.zarr), a sweep point (SWEEP.zarr#INDEX, the plan's
index), or a condition file (NAME.json); a relative path is taken from the CSV's
folder. time_s: milling time (s, ≥ 0). value: the measured quantity. sigma: its
standard uncertainty (> 0), given on every line or on none.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.model.files import read_text, read_toml
from taimill.outcome.fit import Fit, Points
from taimill.store.output import whole_file

COLUMNS = ("condition", "time_s", "value")
OPTIONAL = ("sigma",)
FIT_MARK = "# taimill kinetics fit"  #: how a fit file begins: what tells taimill's own from a user's file
SIGMAS = ("given", "estimated from the residuals")
SYMMETRY = 1e-6  #: |C - Cᵀ| and a negative eigenvalue allowed, relative to C's largest entry (rounding)


def read_points(path, source: str = "command line", key: str = "POINTS") -> Points:
    """The measured points of a CSV (module doc); conditions as written in the file. A
    file that cannot be read is named with `source` and `key` (taimill.model.files)."""
    path = str(path)
    text = read_text(path, source, key, "points CSV")
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1) if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise ConfigError(path, "header", "", f"missing: the first line names the columns {', '.join(COLUMNS)}[, sigma]")
    n0, head = lines[0]
    header = [h.strip() for h in next(csv.reader([head]))]
    for c in COLUMNS:
        if c not in header:
            raise ConfigError(f"{path}:{n0}", "header", head, f"has no column {c!r}: need {', '.join(COLUMNS)} "
                              "and optionally sigma")
    extra = [h for h in header if h not in COLUMNS + OPTIONAL]
    if extra or len(set(header)) != len(header):
        bad = extra[0] if extra else next(h for h in header if header.count(h) > 1)
        raise ConfigError(f"{path}:{n0}", f"column {header.index(bad) + 1}", bad,
                          f"{'unknown' if extra else 'given twice'}: the columns are {', '.join(COLUMNS + OPTIONAL)}")
    if len(lines) < 2:
        raise ConfigError(path, "points", 0, "no measured points below the header")
    cond, t, y, s, where_from = [], [], [], [], []
    for n, line in lines[1:]:
        row = [x.strip() for x in next(csv.reader([line]))]
        if len(row) != len(header):
            raise ConfigError(f"{path}:{n}", "line", line, f"has {len(row)} fields; the header names {len(header)}")
        cell = dict(zip(header, row))
        where = {h: f"{path}:{n}" for h in header}
        key = {h: f"column {header.index(h) + 1} ({h})" for h in header}
        if not cell["condition"]:
            raise ConfigError(where["condition"], key["condition"], "", "empty: name a run store, SWEEP.zarr#INDEX "
                              "or a condition file")
        cond.append(cell["condition"])
        where_from.append(n)
        t.append(_number(cell["time_s"], where["time_s"], key["time_s"], 0.0, "a number of seconds ≥ 0"))
        y.append(_number(cell["value"], where["value"], key["value"], None, "a finite number"))
        if "sigma" in cell:
            s.append(_number(cell["sigma"], where["sigma"], key["sigma"], 0.0, "a number > 0 (or no sigma column)",
                             strict=True) if cell["sigma"] else None)
    if s and any(v is None for v in s) and not all(v is None for v in s):
        n = lines[1 + next(i for i, v in enumerate(s) if (v is None) != (s[0] is None))][0]
        raise ConfigError(f"{path}:{n}", f"column {header.index('sigma') + 1} (sigma)", "",
                          "give sigma on every line or on none (the fit weights all points alike or by their sigma)")
    sigma = np.array(s, dtype=float) if s and s[0] is not None else None
    return Points(cond, np.array(t), np.array(y), sigma, path, where_from, header.index("condition") + 1,
                  header.index("value") + 1)


def check_values(pts: Points, model) -> Points:
    """Refuse a measured value outside what `model` describes (its `values`, e.g. a
    converted fraction in [0, 1]): the first such point, named by its file and line.
    Percent given for a fraction is the usual slip; fitted, it gives a κ that is wrong
    by orders of magnitude with no more than a χ² warning."""
    if model.values is None:
        return pts
    lo, hi = model.values
    bad = np.flatnonzero((pts.value < lo) | (pts.value > hi))
    if bad.size:
        i = int(bad[0])
        where = f"{pts.source}:{pts.lines[i]}" if pts.lines else pts.source
        raise ConfigError(where, f"column {pts.value_column} (value)", float(pts.value[i]),
                          f"allowed range {model.values_text}")
    return pts


def _number(text: str, where: str, key: str, lo, allowed: str, strict: bool = False) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(where, key, text, allowed) from None
    if not math.isfinite(v) or (lo is not None and (v <= lo if strict else v < lo)):
        raise ConfigError(where, key, text, allowed)
    return v


def toml_value(v) -> str:
    """One value as TOML writes it (the fit files of kinetics, sizes and wear)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    v = float(v)
    return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))


def starts_with(path, mark: str) -> bool:
    """True if the file `path` begins with `mark`: how taimill tells its own fit files
    (kinetics, sizes, wear) from a user's, the one kind each `--out … --overwrite` replaces."""
    try:
        with open(path, "rb") as f:
            return f.read(len(mark.encode())) == mark.encode()
    except OSError:
        return False


def is_fit_file(path) -> bool:
    """True if `path` is a kinetics fit file taimill wrote (its first line is FIT_MARK)."""
    return starts_with(path, FIT_MARK)


def write_fit(path, fit: Fit, header: str) -> None:
    """The fit as a small TOML file, `header` (# comments) first, FIT_MARK its first line."""
    top = {"model": fit.model, "measure": fit.measure, "stress_only": fit.stress_only, "level": fit.level,
           "interval_method": fit.interval_method, "sigma": fit.sigma, "conditions": fit.conditions,
           "warnings": fit.warnings, "open_ends": fit.open_ends, "covariance_names": fit.covariance_names,
           "covariance": fit.covariance, "flat_directions": fit.flat_directions}
    tables = {"parameters": fit.params, "intervals": {k: list(v) for k, v in fit.intervals.items()},
              "fixed": fit.fixed, "goodness": fit.goodness, "correlation": fit.correlation, "profiles": fit.profiles}
    lines = [f"# {h}" for h in header.splitlines()]
    if not lines or not lines[0].startswith(FIT_MARK):
        lines.insert(0, FIT_MARK)
    lines.append("# covariance and [profiles]: of the fitted coordinates (log10 of the log parameters), for "
                 "prediction bands")
    lines += [f"{k} = {toml_value(v)}" for k, v in top.items()]
    for name, table in tables.items():
        lines += ["", f"[{name}]"] + [f"{json.dumps(k)} = {toml_value(v)}" for k, v in table.items()]
    with whole_file(Path(path), "fit") as part:
        Path(part).write_text("\n".join(lines) + "\n")


def read_fit(path, source: str = "command line", key: str = "FIT") -> Fit:
    """A fit file written by write_fit; a file that is not one, or one whose numbers a
    fit cannot have (edited, damaged), is a one-line ConfigError naming the file, the
    key, the value and what is allowed: every number is used for a prediction, and a
    wrong one (a negative variance, a NaN parameter) would give a wrong band or
    "never" rather than an error."""
    path = str(path)
    doc = read_toml(path, source, key, "fit file (TOML)")
    from taimill.model.spectra import MEASURES
    from taimill.outcome.models import MODELS

    if doc.get("model") not in MODELS:
        raise ConfigError(path, "model", doc.get("model"), f"allowed: {', '.join(MODELS)} (a file of taimill kinetics fit)")
    model = MODELS[doc["model"]]
    names = {p.name for p in model.params}
    fitted, held = _table(doc, path, "parameters"), _table(doc, path, "fixed")
    given = {**fitted, **held}
    if set(given) != names or set(fitted) & set(held) or not all(_is_number(v) for v in given.values()):
        raise ConfigError(path, "parameters", given, f"need a number for each of {', '.join(sorted(names))}")
    for k in ("model", "measure", "sigma", "covariance_names", "covariance"):
        if k not in doc:
            raise ConfigError(path, k, None, "missing (a file of taimill kinetics fit)")
    _choice(path, "measure", doc["measure"], MEASURES)
    _choice(path, "sigma", doc["sigma"], SIGMAS)
    if not isinstance(doc.get("stress_only", False), bool):
        raise ConfigError(path, "stress_only", doc["stress_only"], "true or false")
    level = _checked(path, "level", doc.get("level", 0.95), 0.5, 1.0, "[0.5, 1)", hi_open=True)
    for k in ("conditions", "warnings", "open_ends"):
        if not isinstance(doc.get(k, []), list) or not all(isinstance(x, str) for x in doc.get(k, [])):
            raise ConfigError(path, k, doc.get(k), "a list of strings")
    if not isinstance(doc.get("interval_method", ""), str):
        raise ConfigError(path, "interval_method", doc["interval_method"], "a string")
    for table in ("parameters", "fixed"):
        for name, v in doc.get(table, {}).items():
            _parameter(path, f"{table}.{name}", v, next(p for p in model.params if p.name == name))
    intervals = _intervals(path, _table(doc, path, "intervals"), doc.get("parameters", {}))
    cov = _covariance(path, doc["covariance_names"], doc["covariance"], doc.get("parameters", {}))
    correlation = _table(doc, path, "correlation")
    for name, r in correlation.items():
        _checked(path, f"correlation.{name}", r, -1.0 - SYMMETRY, 1.0 + SYMMETRY, "[-1, 1]")
    goodness = _goodness(path, _table(doc, path, "goodness"), doc["sigma"])
    profiles = _profiles(path, _table(doc, path, "profiles"), doc["covariance_names"])
    flat = _vectors(path, "flat_directions", doc.get("flat_directions", []), doc["covariance_names"])
    return Fit(doc["model"], doc["measure"], bool(doc.get("stress_only", False)), doc["parameters"], intervals,
               doc.get("fixed", {}), list(doc.get("conditions", [])), goodness, doc["sigma"], float(level),
               list(doc["covariance_names"]), cov, correlation, list(doc.get("warnings", [])),
               list(doc.get("open_ends", [])), doc.get("interval_method", ""), profiles, flat)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _table(doc: dict, path: str, name: str) -> dict:
    t = doc.get(name, {})
    if not isinstance(t, dict):
        raise ConfigError(path, name, t, "a table (a file of taimill kinetics fit)")
    return t


def _choice(path: str, key: str, v, allowed) -> None:
    if v not in allowed:
        raise ConfigError(path, key, v, f"allowed: {', '.join(map(repr, allowed))}")


def _checked(path: str, key: str, v, lo: float, hi: float, text: str, lo_open: bool = False,
             hi_open: bool = False) -> float:
    """v if it is a finite number within [lo, hi] (an end open where said), else a
    ConfigError saying the range `text`."""
    ok = _is_number(v) and math.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        raise ConfigError(path, key, v, f"allowed range {text}")
    return float(v)


def _parameter(path: str, key: str, v, p) -> None:
    """A parameter's value: finite; > 0 if fitted in log10 (an energy threshold may be
    held at 0: every event counts)."""
    if p.threshold:
        _checked(path, key, v, 0.0, math.inf, "[0, ∞) J, finite")
    elif p.log:
        _checked(path, key, v, 0.0, math.inf, "(0, ∞), finite", lo_open=True)
    else:
        _checked(path, key, v, -math.inf, math.inf, "a finite number")


def _intervals(path: str, table: dict, params: dict) -> dict:
    if set(table) != set(params):
        raise ConfigError(path, "intervals", sorted(table), f"one [lower, upper] for each of {', '.join(params)}")
    out = {}
    for name, v in table.items():
        ok = isinstance(v, list) and len(v) == 2 and all(_is_number(x) and not math.isnan(x) for x in v) and v[0] <= v[1]
        if not ok:
            raise ConfigError(path, f"intervals.{name}", v, "[lower, upper]: two numbers, lower ≤ upper")
        out[name] = (float(v[0]), float(v[1]))
    return out


def _covariance(path: str, names, cov, params: dict) -> list:
    """The covariance of the fitted coordinates: one row and column a fitted parameter,
    finite, symmetric and positive semi-definite (variances ≥ 0), up to rounding."""
    if not isinstance(names, list) or names != list(params):
        raise ConfigError(path, "covariance_names", names, f"the fitted parameters in order: {list(params)}")
    n = len(names)
    if (not isinstance(cov, list) or len(cov) != n
            or not all(isinstance(r, list) and len(r) == n and all(_is_number(x) for x in r) for r in cov)):
        raise ConfigError(path, "covariance", cov, f"a {n} × {n} table of numbers (rows and columns {', '.join(names)})")
    c = np.array(cov, dtype=float).reshape(n, n)
    for i in range(n):
        for j in range(n):
            if not math.isfinite(c[i, j]):
                raise ConfigError(path, f"covariance[{i}][{j}]", cov[i][j], "a finite number")
    for i in range(n):
        if c[i, i] < 0:
            raise ConfigError(path, f"covariance[{i}][{i}]", cov[i][i], f"allowed range [0, ∞): the variance of {names[i]}")
    scale = float(np.abs(c).max()) if n else 0.0
    for i in range(n):
        for j in range(i + 1, n):
            if abs(c[i, j] - c[j, i]) > SYMMETRY * scale:
                raise ConfigError(path, f"covariance[{i}][{j}]", cov[i][j],
                                  f"must equal covariance[{j}][{i}] = {cov[j][i]!r} (a symmetric matrix)")
    if n and float(np.linalg.eigvalsh((c + c.T) / 2).min()) < -SYMMETRY * scale:
        raise ConfigError(path, "covariance", cov, "a positive semi-definite matrix (|correlation| ≤ 1)")
    return c.tolist()


def _profiles(path: str, table: dict, names: list) -> dict:
    """[profiles]: for a fitted parameter, the best fits along its profile, each a
    point of the fitted coordinates (one finite number per fitted parameter). Absent in
    a fit file of an older taimill: predict then falls back to linearised bands."""
    out = {}
    for name, points in table.items():
        if name not in names:
            raise ConfigError(path, f"profiles.{name}", points, f"a profile of a fitted parameter: {', '.join(names)}")
        if not points:
            raise ConfigError(path, f"profiles.{name}", points, "a list of points along the profile, not empty")
        out[name] = _vectors(path, f"profiles.{name}", points, names)
    return out


def _vectors(path: str, key: str, vectors, names: list) -> list:
    """A list of points (or directions) of the fitted coordinates: each one finite
    number per fitted parameter."""
    ok = isinstance(vectors, list) and all(isinstance(z, list) and len(z) == len(names)
                                           and all(_is_number(x) and math.isfinite(x) for x in z) for z in vectors)
    if not ok:
        raise ConfigError(path, key, "…", f"a list of points, each {len(names)} finite numbers ({', '.join(names)})")
    return [[float(x) for x in z] for z in vectors]


GOODNESS = {  # key -> (lo, hi, lo open, text)
    "n_points": (1, math.inf, False, "[1, ∞), a whole number"), "dof": (1, math.inf, False, "[1, ∞), a whole number"),
    "rmse": (0.0, math.inf, False, "[0, ∞)"), "chi2": (0.0, math.inf, False, "[0, ∞)"),
    "reduced_chi2": (0.0, math.inf, False, "[0, ∞)"), "p_value": (0.0, 1.0, False, "[0, 1]"),
    "residual_sd": (0.0, math.inf, False, "[0, ∞)"), "r2": (-math.inf, 1.0, False, "(-∞, 1] or nan"),
}


def _goodness(path: str, table: dict, sigma: str) -> dict:
    """[goodness]: each number in its range; `dof` is needed where the band's quantile
    is Student's t (the scatter estimated)."""
    for k, v in table.items():
        if k not in GOODNESS:
            raise ConfigError(path, f"goodness.{k}", v, f"allowed keys: {', '.join(GOODNESS)}")
        lo, hi, lo_open, text = GOODNESS[k]
        if k == "r2" and _is_number(v) and math.isnan(v):  # all values alike: R² undefined
            continue
        if k in ("n_points", "dof") and not isinstance(v, int):
            raise ConfigError(path, f"goodness.{k}", v, f"allowed range {text}")
        _checked(path, f"goodness.{k}", v, lo, hi, text, lo_open=lo_open)
    if sigma != "given" and "dof" not in table:
        raise ConfigError(path, "goodness.dof", None, "missing: the bands of a fit with estimated scatter need it")
    return table
