"""Measured particle size distributions (CSV) for the population balance
(taimill.outcome.grinding, docs/outcome.md "Particle sizes"). Bad input is a one-line
ConfigError naming the file, line, column and value and what is allowed.

A header line names the columns, each quantity with its unit (any order; `#` lines and
blank lines are skipped):

    condition, time_h | time_min | time_s, size_um | size_mm | size_m, passing_pct | passing_fraction
    [, sigma_pct | sigma_fraction]

then one line per point of a cumulative distribution: the share of the mass finer than
`size` (laser diffraction's Q3) at milling time `time` under `condition` (a run store,
SWEEP.zarr#INDEX or a condition file, as in the kinetics points; a relative path from
the CSV's folder). The optional sigma column is the passing share's standard
uncertainty (one standard deviation, in percentage points or as a fraction), on every
line; `taimill sizes fit` weights by it (without it, by 2 % of each share). The lines
of one distribution (one condition and time) come together, sizes increasing, the
passing share never falling. A column without a unit, a share above 100 % (or a
fraction above 1: percent under a fraction's name) or a size no powder has (below 1 nm
or above 0.1 m: metres under µm's name, or µm under metres') is refused with the line
and column.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass

import numpy as np

from taimill.errors import ConfigError
from taimill.model.files import read_text

TIME_UNITS = {"time_s": 1.0, "time_min": 60.0, "time_h": 3600.0}  #: to s
SIZE_UNITS = {"size_m": 1.0, "size_mm": 1e-3, "size_um": 1e-6}  #: to m
PASSING_UNITS = {"passing_fraction": 1.0, "passing_pct": 0.01}  #: to a fraction
SIZE_RANGE = (1e-9, 0.1)  #: m: what a milled powder's particles can measure
SIGMA_UNITS = {"sigma_fraction": 1.0, "sigma_pct": 0.01}  #: to a fraction (of the whole charge, like passing)
QUANTITIES = (("condition", {"condition": None}), ("time", TIME_UNITS), ("size", SIZE_UNITS),
              ("passing", PASSING_UNITS))
OPTIONAL = (("sigma", SIGMA_UNITS),)  #: columns a file may give: the passing share's standard uncertainty


@dataclass(frozen=True)
class Distribution:
    """One measured cumulative distribution: `passing` (fraction, 0 … 1) finer than each
    of `sizes` (m, increasing), after `time` s under `condition`; `line` where it begins."""

    condition: str
    time: float
    sizes: np.ndarray
    passing: np.ndarray
    line: int
    sigma: np.ndarray | None = None  #: fraction, one standard uncertainty of each passing share (None: not given)


def _header(path: str, n: int, head: str) -> dict[str, tuple[str, float | None]]:
    """{quantity: (column name, its unit's factor)} from the header line."""
    names = [h.strip() for h in next(csv.reader([head]))]
    found = {}
    for quantity, units in QUANTITIES:
        given = [h for h in names if h in units]
        if len(given) != 1:
            bare = quantity in names and quantity != "condition"
            allowed = " | ".join(units)
            why = (f"{quantity!r} has no unit: name it {allowed}" if bare else
                   f"has {'no column' if not given else 'two columns'} for the {quantity}: one of {allowed}")
            raise ConfigError(f"{path}: line {n}", "header", head, why)
        found[quantity] = (given[0], units[given[0]])
    for quantity, units in OPTIONAL:
        given = [h for h in names if h in units]
        if len(given) > 1 or quantity in names:
            why = (f"{quantity!r} has no unit: name it {' | '.join(units)}" if quantity in names else
                   f"has two columns for the {quantity}: one of {' | '.join(units)}")
            raise ConfigError(f"{path}: line {n}", "header", head, why)
        if given:
            found[quantity] = (given[0], units[given[0]])
    known = {c for _, (c, _) in found.items()}
    extra = [h for h in names if h not in known]
    if extra:
        raise ConfigError(f"{path}: line {n}", f"column {names.index(extra[0]) + 1}", extra[0],
                          "unknown: the columns are condition, time_h|time_min|time_s, size_um|size_mm|size_m, "
                          "passing_pct|passing_fraction[, sigma_pct|sigma_fraction]")
    return {q: (c, f) for q, (c, f) in found.items()} | {"_order": names}


def _value(text: str, where: str, column: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(where, column, text, "not a number") from None
    if not math.isfinite(v):
        raise ConfigError(where, column, text, "not a finite number")
    return v


def read_distributions(path, source: str = "command line", key: str = "SIZES") -> list[Distribution]:
    """The measured distributions of a CSV (module doc), in file order."""
    path = str(path)
    text = read_text(path, source, key, "size distribution CSV")
    lines = [(n, ln) for n, ln in enumerate(text.splitlines(), 1) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ConfigError(path, "header", "", "missing: the first line names the columns condition, time_h, size_um, "
                          "passing_pct (each with its unit)")
    cols = _header(path, *lines[0])
    order = cols.pop("_order")
    if len(lines) < 2:
        raise ConfigError(path, "points", 0, "no measured points below the header")
    groups: dict[tuple, dict] = {}
    last = None
    for n, line in lines[1:]:
        row = [x.strip() for x in next(csv.reader([line]))]
        if len(row) != len(order):
            raise ConfigError(f"{path}: line {n}", "line", line, f"has {len(row)} fields; the header names {len(order)}")
        cell = dict(zip(order, row))
        where = f"{path}: line {n}"

        def col(q):
            c = cols[q][0]
            return f"column {order.index(c) + 1} ({c})"

        cond = cell[cols["condition"][0]]
        if not cond:
            raise ConfigError(where, col("condition"), "", "empty: name a run store, SWEEP.zarr#INDEX or a condition file")
        t_col, t_f = cols["time"]
        t = _value(cell[t_col], where, col("time"))
        if t < 0:
            raise ConfigError(where, col("time"), cell[t_col], "a milling time ≥ 0")
        x_col, x_f = cols["size"]
        x = _value(cell[x_col], where, col("size")) * x_f
        lo, hi = SIZE_RANGE
        if not lo <= x <= hi:
            hint = ("; metres under µm's or mm's name? name the column size_m" if x < lo and x_f < 1 else
                    "; µm under metres' name? name the column size_um" if x > hi and x_f >= 1e-3 else "")
            raise ConfigError(where, col("size"), cell[x_col], f"a particle size lies in [1 nm, 100 mm]{hint}")
        q_col, q_f = cols["passing"]
        q = _value(cell[q_col], where, col("passing"))
        top = 1.0 / q_f
        if not 0 <= q <= top:
            hint = "; percent under a fraction's name? name the column passing_pct" if q_f == 1.0 and 1 < q <= 100 else ""
            raise ConfigError(where, col("passing"), cell[q_col], f"a cumulative share lies in [0, {top:g}]{hint}")
        k = (cond, t * t_f)
        if k in groups and last != k:
            raise ConfigError(where, col("time"), cell[t_col], f"this distribution ({cond} at {cell[t_col]}) began at "
                              f"line {groups[k]['line']} and was interrupted: give its lines together")
        if "sigma" in cols:
            s_col, s_f = cols["sigma"]
            sd = _value(cell[s_col], where, col("sigma"))
            if not 0 < sd * s_f <= 1:
                raise ConfigError(where, col("sigma"), cell[s_col], f"an uncertainty in (0, {1 / s_f:g}] (one standard "
                                  "deviation of the passing share, in the column's unit)")
        g = groups.setdefault(k, {"line": n, "x": [], "q": [], "n": [], "s": []})
        if g["x"] and x <= g["x"][-1]:
            raise ConfigError(where, col("size"), cell[x_col], f"sizes of a distribution must increase (line "
                              f"{g['n'][-1]} had {g['x'][-1] / x_f:g})")
        if g["q"] and q * q_f < g["q"][-1] - 1e-12:
            raise ConfigError(where, col("passing"), cell[q_col], f"a cumulative share cannot fall with size (line "
                              f"{g['n'][-1]} had {g['q'][-1] / q_f:g})")
        g["x"].append(x)
        g["q"].append(q * q_f)
        g["n"].append(n)
        if "sigma" in cols:
            g["s"].append(sd * s_f)
        last = k
    return [Distribution(c, t, np.array(g["x"]), np.array(g["q"]), g["line"], np.array(g["s"]) if g["s"] else None)
            for (c, t), g in groups.items()]
