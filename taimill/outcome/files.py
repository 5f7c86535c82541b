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
    return Points(cond, np.array(t), np.array(y), sigma, path, where_from, header.index("condition") + 1)


def _number(text: str, where: str, key: str, lo, allowed: str, strict: bool = False) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(where, key, text, allowed) from None
    if not math.isfinite(v) or (lo is not None and (v <= lo if strict else v < lo)):
        raise ConfigError(where, key, text, allowed)
    return v


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    v = float(v)
    return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))


def write_fit(path, fit: Fit, header: str) -> None:
    """The fit as a small TOML file, `header` (# comments) first."""
    top = {"model": fit.model, "measure": fit.measure, "stress_only": fit.stress_only, "level": fit.level,
           "interval_method": fit.interval_method, "sigma": fit.sigma, "conditions": fit.conditions,
           "warnings": fit.warnings, "open_ends": fit.open_ends, "covariance_names": fit.covariance_names,
           "covariance": fit.covariance}
    tables = {"parameters": fit.params, "intervals": {k: list(v) for k, v in fit.intervals.items()},
              "fixed": fit.fixed, "goodness": fit.goodness, "correlation": fit.correlation}
    lines = [f"# {h}" for h in header.splitlines()]
    lines.append("# covariance: of the fitted coordinates (log10 of the log parameters), for prediction bands")
    lines += [f"{k} = {_toml_value(v)}" for k, v in top.items()]
    for name, table in tables.items():
        lines += ["", f"[{name}]"] + [f"{json.dumps(k)} = {_toml_value(v)}" for k, v in table.items()]
    with whole_file(Path(path), "fit") as part:
        Path(part).write_text("\n".join(lines) + "\n")


def read_fit(path, source: str = "command line", key: str = "FIT") -> Fit:
    """A fit file written by write_fit; a file that is not one is a one-line ConfigError."""
    path = str(path)
    doc = read_toml(path, source, key, "fit file (TOML)")
    from taimill.outcome.models import MODELS

    if doc.get("model") not in MODELS:
        raise ConfigError(path, "model", doc.get("model"), f"allowed: {', '.join(MODELS)} (a file of taimill kinetics fit)")
    names = {p.name for p in MODELS[doc["model"]].params}
    given = {**doc.get("parameters", {}), **doc.get("fixed", {})}
    if set(given) != names or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in given.values()):
        raise ConfigError(path, "parameters", given, f"need a number for each of {', '.join(sorted(names))}")
    try:
        return Fit(doc["model"], doc["measure"], bool(doc.get("stress_only", False)), doc["parameters"],
                   {k: tuple(v) for k, v in doc.get("intervals", {}).items()}, doc.get("fixed", {}),
                   list(doc.get("conditions", [])), doc.get("goodness", {}), doc.get("sigma", ""),
                   float(doc.get("level", 0.95)), list(doc.get("covariance_names", [])),
                   doc.get("covariance", []), doc.get("correlation", {}), list(doc.get("warnings", [])),
                   list(doc.get("open_ends", [])), doc.get("interval_method", ""))
    except KeyError as err:
        raise ConfigError(path, err.args[0], None, "missing (a file of taimill kinetics fit)") from None
