"""The files of wear work (docs/wear.md): measured contamination (CSV) in, a wear fit
(TOML) out and back, and a run store read as a WearCondition. Bad input is a one-line
ConfigError naming the file, line, column, value and what is allowed.

Contamination CSV: a header naming `condition`, one time column (`time_h`,
`time_min` or `time_s`) and one value column (`contamination_pct` or
`contamination_fraction`), any order (`#` lines and blank lines skipped), then one
line a measurement. condition: a run store (RUN.zarr), relative paths taken from the
CSV's folder; time ≥ 0; contamination the mass of worn ball and jar material over the
mass of the (contaminated) powder, in [0, 100) % or [0, 1).
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.model.files import read_text, read_toml
from taimill.outcome.files import starts_with, toml_value
from taimill.outcome.fit import Fit, Points
from taimill.outcome.wear import KINDS, Body, WearCondition
from taimill.store.output import whole_file

TIMES = {"time_h": 3600.0, "time_min": 60.0, "time_s": 1.0}  #: column -> seconds per unit
VALUES = {"contamination_pct": 100.0, "contamination_fraction": 1.0}  #: column -> units per fraction
FIT_MARK = "# taimill wear fit"  #: how a wear fit file begins
MODEL = "archard-wear"
SIGMAS = ("given", "estimated from the residuals")


def read_measured(path, source: str = "command line", key: str = "MEASURED") -> Points:
    """The measured contamination of a CSV (module doc) as fit Points: time in s, the
    value a mass fraction."""
    path = str(path)
    text = read_text(path, source, key, "contamination CSV")
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    need = "condition, one of time_h|time_min|time_s and one of contamination_pct|contamination_fraction"
    if not lines:
        raise ConfigError(path, "header", "", f"missing: the first line names the columns {need}")
    n0, head = lines[0]
    header = [h.strip() for h in next(csv.reader([head]))]
    for i, h in enumerate(header):
        if h not in ("condition", *TIMES, *VALUES) or header.count(h) > 1:
            raise ConfigError(f"{path}:{n0}", f"column {i + 1}", h,
                              f"{'given twice' if h in header[:i] else 'unknown'}: the columns are {need}")
    times, values = [h for h in header if h in TIMES], [h for h in header if h in VALUES]
    if "condition" not in header or len(times) != 1 or len(values) != 1:
        raise ConfigError(f"{path}:{n0}", "header", head, f"need exactly the columns {need}")
    tcol, vcol = times[0], values[0]
    if len(lines) < 2:
        raise ConfigError(path, "points", 0, "no measurements below the header")
    cond, t, y, where_from = [], [], [], []
    scale = VALUES[vcol]
    for n, line in lines[1:]:
        row = [x.strip() for x in next(csv.reader([line]))]
        if len(row) != len(header):
            raise ConfigError(f"{path}:{n}", "line", line, f"has {len(row)} fields; the header names {len(header)}")
        cell = dict(zip(header, row))
        col = {h: f"column {header.index(h) + 1} ({h})" for h in header}
        if not cell["condition"]:
            raise ConfigError(f"{path}:{n}", col["condition"], "", "empty: name a run store RUN.zarr")
        cond.append(cell["condition"])
        where_from.append(n)
        t.append(_number(cell[tcol], f"{path}:{n}", col[tcol], 0.0, math.inf, False, "a time ≥ 0") * TIMES[tcol])
        allowed = "allowed range [0, 100) %" if scale == 100.0 else \
            "allowed range [0, 1) (a fraction; percent? use contamination_pct)"
        y.append(_number(cell[vcol], f"{path}:{n}", col[vcol], 0.0, scale, True, allowed) / scale)
    return Points(cond, np.array(t), np.array(y), None, path, where_from, header.index("condition") + 1,
                  header.index(vcol) + 1)


def _number(text, where, key, lo, hi, hi_open, allowed) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(where, key, text, allowed) from None
    if not math.isfinite(v) or v < lo or (v >= hi if hi_open else v > hi):
        raise ConfigError(where, key, text, allowed)
    return v


def open_wear_condition(name: str, base: str, where: str, key: str, threshold_j: float = 0.0) -> WearCondition:
    """A run store read as a WearCondition: its summary's friction power by contact
    kind, its event rows' impact energies ≥ threshold_j and wall map, its balls, jar
    wall and powder. `where`, `key`: how a bad one is named (the CSV line, or the
    command line)."""
    from taimill.analysis.run import geometry
    from taimill.analysis.rungeometry import FLOOR, LID, SIDE
    from taimill.analysis.spatial import WallMap
    from taimill.errors import StoreError
    from taimill.model.materials import material_data
    from taimill.store.run import open_run

    path = name if os.path.isabs(name) else os.path.join(base, name)
    if not os.path.exists(path):
        looked = f" (looked in {base})" if base not in ("", ".") else ""
        raise ConfigError(where, key, name, f"no such run store{looked}")
    try:
        store = open_run(path)
    except StoreError as err:
        raise ConfigError(where, key, name, f"cannot be read ({err})") from None
    summary, config = store.summary, store.config or {}
    if not summary or "dissipation_by_mechanism" not in summary:
        raise ConfigError(where, key, name, "a finished run store (this one has no final summary with "
                          "dissipation_by_mechanism: killed, still running, or older)")
    mech = summary["dissipation_by_mechanism"]
    friction = {k: float(mech[k]["impact"]["friction"] + mech[k]["persistent"]["friction"]) for k in KINDS}
    powder = summary.get("powder_mass_g") or 1e3 * ((config.get("powder") or {}).get("mass") or 0.0)
    if not powder or not powder > 0:
        raise ConfigError(where, key, name, "a run with powder (taimill run --powder-mass G): contamination is "
                          "a fraction of the powder")
    worn = []
    for role, mat in (("ball", config["balls"]["material"]["name"]), ("wall", config["jar"]["wall_material"])):
        data = material_data(mat, where, key)
        if not data.hardness_hv > 0:
            raise ConfigError(where, key, name, f"{role} material {mat} has no hardness_hv in the material table: "
                              "its wear cannot be computed")
        worn.append(Body(mat, data.material.density, data.hardness_hv))
    t0, t1 = (float(x) for x in summary["analysis_window"])
    impact, wall_map = None, None
    if config.get("events_output", "rows") == "rows":
        ev = store.events
        win = (ev["t_start"] >= t0) & (ev["t_start"] < t1)
        big = win & (ev["se_n"] >= threshold_j)
        on = {"ball_ball": ev["kind"] == 0, "side": (ev["kind"] == 1) & (ev["body_j"] == SIDE),
              "floor": (ev["kind"] == 1) & (ev["body_j"] == FLOOR), "lid": (ev["kind"] == 1) & (ev["body_j"] == LID)}
        impact = {k: float(ev["se_n"][big & sel].sum() / (t1 - t0)) for k, sel in on.items()}
        wall_map = WallMap(geometry(store), t0, t1=t1)
        wall_map.add(ev)
    return WearCondition(name, friction, impact, threshold_j, worn[0], worn[1], float(powder), wall_map)


def bodies(config: dict) -> tuple[Body | None, Body | None]:
    """The balls and jar wall of a run's config as wear Bodies; None where the material
    is not in the table or states no hardness."""
    from taimill.model.materials import material_data

    out = []
    for name in (((config.get("balls") or {}).get("material") or {}).get("name"),
                 (config.get("jar") or {}).get("wall_material")):
        try:
            data = material_data(name)
        except ConfigError:
            out.append(None)
            continue
        out.append(Body(name, data.material.density, data.hardness_hv) if data.hardness_hv > 0 else None)
    return out[0], out[1]


def is_fit_file(path) -> bool:
    """True if `path` is a wear fit taimill wrote (its first line is FIT_MARK)."""
    return starts_with(path, FIT_MARK)


def write_fit(path, fit: Fit, threshold_j: float, header: str) -> None:
    """The wear fit as a small TOML file, FIT_MARK its first line."""
    top = {"model": MODEL, "impact_threshold_J": threshold_j, "level": fit.level, "sigma": fit.sigma,
           "interval_method": fit.interval_method, "conditions": fit.conditions, "warnings": fit.warnings,
           "open_ends": fit.open_ends}
    tables = {"parameters": fit.params, "fixed": fit.fixed, "intervals": {k: list(v) for k, v in fit.intervals.items()},
              "goodness": fit.goodness}
    lines = [FIT_MARK] + [f"# {h}" for h in header.splitlines()] + [f"{k} = {toml_value(v)}" for k, v in top.items()]
    for name, table in tables.items():
        lines += ["", f"[{name}]"] + [f"{json.dumps(k)} = {toml_value(v)}" for k, v in table.items()]
    with whole_file(Path(path), "fit") as part:
        Path(part).write_text("\n".join(lines) + "\n")


def read_fit(path, source: str = "command line", key: str = "--fit") -> dict:
    """A wear fit: {"k": {name: value}, "intervals": {name: (lo, hi)}, "threshold_j",
    "level", "conditions"}; anything else a one-line ConfigError naming the key."""
    path = str(path)
    doc = read_toml(path, source, key, "wear fit file (TOML)")
    if doc.get("model") != MODEL:
        raise ConfigError(path, "model", doc.get("model"), f"must be {MODEL!r} (a file of taimill wear fit)")
    names = ("k_friction", "k_impact")
    params, fixed = doc.get("parameters", {}), doc.get("fixed", {})
    if not isinstance(params, dict) or not isinstance(fixed, dict) or set(params) | set(fixed) != set(names) \
            or set(params) & set(fixed):
        raise ConfigError(path, "parameters", params,
                          f"one value for each of {', '.join(names)} in [parameters] or [fixed]")
    k = {}
    for table, values in (("parameters", params), ("fixed", fixed)):
        for n, v in values.items():
            lo_open = table == "parameters"
            if not _positive(v, lo_open):
                raise ConfigError(path, f"{table}.{n}", v, f"allowed range {'(0' if lo_open else '[0'}, ∞), finite")
            k[n] = float(v)
    intervals = doc.get("intervals", {})
    if not isinstance(intervals, dict) or set(intervals) != set(params):
        raise ConfigError(path, "intervals", intervals, f"one [lower, upper] for each of {', '.join(params) or 'none'}")
    iv = {}
    for n, v in intervals.items():
        if not (isinstance(v, list) and len(v) == 2 and all(_positive(x, False) for x in v) and v[0] <= k[n] <= v[1]):
            raise ConfigError(path, f"intervals.{n}", v, f"[lower, upper]: two numbers ≥ 0 around {k[n]!r}")
        iv[n] = (float(v[0]), float(v[1]))
    thr = doc.get("impact_threshold_J", 0.0)
    if not _positive(thr, False):
        raise ConfigError(path, "impact_threshold_J", thr, "allowed range [0, ∞) J")
    level = doc.get("level", 0.95)
    if not (isinstance(level, float) and 0.5 <= level < 1):
        raise ConfigError(path, "level", level, "allowed range [0.5, 1)")
    conditions = doc.get("conditions", [])
    return {"k": k, "intervals": iv, "threshold_j": float(thr), "level": level,
            "conditions": [str(c) for c in conditions] if isinstance(conditions, list) else []}


def _positive(v, lo_open: bool) -> bool:
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    return ok and (v > 0 if lo_open else v >= 0)
