"""A milling condition as the outcome models see it: the energy spectra of one jar
(taimill.model.spectra) and the powder charged into it. Read from a run store, a
sweep point or a condition file: a small JSON file holding the same (the shipped
example data are such files, docs/outcome.md).

Condition file (JSON): {"format": "taimill-condition", "version": 1, "note": text,
"powder_g": g, "start": s, "end": s, "stress_un": m/s, "cells": [[kind, class,
measure, bin, count, fixed], …]}: the non-zero cells of Spectra.count and .fixed;
optionally "shear_w_per_g": the friction power per gram of powder of the whole charge.

The spectra count events, contacts that open and close; the friction of contacts that
never close in the window (a bed sliding on the wall: all of a friction-led charge's
power) is in no spectrum. `shear_w_per_g` carries it, from the run summary (its
`specific_power_shear_W_per_g`): the attrition route of the size model needs it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from taimill.analysis.spectra import LOG_HI, LOG_LO, selected
from taimill.errors import ConfigError
from taimill.model.spectra import MEASURES, SHAPE, Spectra

FORMAT, VERSION = "taimill-condition", 1
KNOTS = np.concatenate([[LOG_LO[0]], LOG_HI])  #: log10 J: the bins' edges, the open bins one bin wide


def _log(energy):
    with np.errstate(divide="ignore"):
        return np.log10(np.maximum(energy, 0.0))


def _above(per_bin) -> np.ndarray:
    """Per bin edge (KNOTS), the sum of `per_bin` over the bins at or above it."""
    per_bin = np.asarray(per_bin, dtype=float)
    return np.maximum(np.concatenate([[per_bin.sum()], per_bin.sum() - np.cumsum(per_bin)]), 0.0)


@dataclass(frozen=True)
class Condition:
    """One jar's spectra over its window and its powder (g). `stress_only`: count only
    stress events (onset u̇n ≥ the spectra's threshold) instead of every contact.
    `replicas`: the spectra of runs of the same condition with other seeds (a sweep's
    replicas), for the spread of the rate between seeds."""

    name: str
    spectra: Spectra
    powder_g: float
    shear_w_per_g: float = math.nan  #: W/g, friction power of the whole charge (module doc); nan: unknown
    _curves: dict = field(default_factory=dict, compare=False, repr=False)
    replicas: tuple = field(default=(), compare=False, repr=False)

    def _curve(self, measure: str, stress_only: bool, energy: bool) -> np.ndarray:
        """Per bin edge (KNOTS), the events (or their J) at or above it per second and
        gram. Spread evenly in log E within a bin (taimill.analysis.spectra), the rate
        above E is linear in log E between edges: np.interp on these knots equals
        rate_above / power_above, and costs a fraction of it in a fit's inner loop."""
        key = (measure, stress_only, energy)
        if key not in self._curves:
            count, joules = selected(self.spectra, measure, stress_only=stress_only)
            self._curves[key] = _above(joules if energy else count) / self.spectra.seconds / self.powder_g
        return self._curves[key]

    def rate(self, energy, measure: str, stress_only: bool = False):
        """1/(s g): events per second and gram of powder with `measure` ≥ `energy` J."""
        return np.interp(_log(energy), KNOTS, self._curve(measure, stress_only, False))

    def power(self, energy, measure: str, stress_only: bool = False):
        """W/g: the `measure` energy per second and gram in events with `measure` ≥ `energy` J."""
        return np.interp(_log(energy), KNOTS, self._curve(measure, stress_only, True))

    def counting_error(self, energy, measure: str, stress_only: bool = False, weighted: bool = False) -> float:
        """The relative standard error that counting alone gives the rate (or, weighted,
        the power) above `energy` J: the window holds a finite number of events, a
        Poisson count N (1/√N; the power: √(Σ e²) / Σ e over the events, from each bin's
        count and mean energy). A floor: collisions come in bursts, so the spread
        between seeds is larger. No event above the energy: as if one were there."""
        count, joules = selected(self.spectra, measure, stress_only=stress_only)
        count, joules = np.asarray(count, dtype=float), np.asarray(joules, dtype=float)
        per_bin = np.divide(joules ** 2, count, out=np.zeros_like(joules), where=count > 0) if weighted else count
        total = joules if weighted else count
        x = _log(energy)
        above = np.interp(x, KNOTS, _above(per_bin)), np.interp(x, KNOTS, _above(total))
        if not above[1] > 0:
            return 1.0
        return float(math.sqrt(above[0]) / above[1]) if weighted else float(1.0 / math.sqrt(max(above[0], 1.0)))

    def replica_spread(self, energy, measure: str, stress_only: bool = False, weighted: bool = False) -> float:
        """The relative standard deviation of the rate (weighted: the power) above
        `energy` J between this run and its replicas (NaN: no replicas). Measured, where
        the counting error is a floor; from few replicas, itself uncertain."""
        if not self.replicas:
            return math.nan
        runs = [self] + [Condition(self.name, sp, self.powder_g) for sp in self.replicas]
        x = np.array([float(c.power(energy, measure, stress_only) if weighted else c.rate(energy, measure, stress_only))
                      for c in runs])
        return float(np.std(x, ddof=1) / np.mean(x)) if np.mean(x) > 0 else math.nan

    def energy_range(self, measure: str, stress_only: bool = False) -> tuple[float, float]:
        """J: the lower edge of the lowest and the upper edge of the highest occupied
        bin (NaN, NaN: no events)."""
        count, _ = selected(self.spectra, measure, stress_only=stress_only)
        full = np.flatnonzero(count)
        if not full.size:
            return math.nan, math.nan
        return 10 ** LOG_LO[full[0]], 10 ** LOG_HI[full[-1]]


def check_measure(measure: str, source: str = "command line", key: str = "--measure") -> str:
    if measure not in MEASURES:
        raise ConfigError(source, key, measure, f"allowed: {', '.join(MEASURES)}")
    return measure


def write_file(path, spectra: Spectra, powder_g: float, note: str, shear_w_per_g: float = math.nan) -> None:
    """Write a condition file (module doc)."""
    cells = [[*map(int, idx), int(spectra.count[idx]), int(spectra.fixed[idx])]
             for idx in zip(*np.nonzero(spectra.count | spectra.fixed))]
    doc = {"format": FORMAT, "version": VERSION, "note": note, "powder_g": powder_g, "start": spectra.start,
           "end": spectra.end, "stress_un": spectra.stress_un, "cells": cells}
    if math.isfinite(shear_w_per_g):
        doc["shear_w_per_g"] = shear_w_per_g
    with open(path, "w") as f:
        json.dump(doc, f, indent=None, separators=(",", ":"))
        f.write("\n")


def read_file(path, name: str | None = None, source: str | None = None, key: str = "condition") -> Condition:
    """A condition file; anything else is a one-line ConfigError naming the key (a file
    that cannot be read: named with `source` and `key`, taimill.model.files)."""
    from taimill.model.files import read_text

    try:
        doc = json.loads(read_text(path, source or str(path), key, "condition file (JSON)"))
    except ValueError as err:
        if isinstance(err, ConfigError):
            raise
        raise ConfigError(str(path), "file", None, f"not a condition file: not JSON ({err})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ConfigError(str(path), "format", doc.get("format") if isinstance(doc, dict) else doc,
                          f"must be {FORMAT!r} (a condition file)")
    for key in ("powder_g", "start", "end", "stress_un"):
        v = doc.get(key)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise ConfigError(str(path), key, v, "a finite number is needed")
    if not doc["powder_g"] > 0 or not doc["end"] > doc["start"]:
        bad = "powder_g" if not doc["powder_g"] > 0 else "end"
        raise ConfigError(str(path), bad, doc[bad], "must be positive (powder_g) and after start (end)")
    sp = Spectra(float(doc["start"]), float(doc["end"]), float(doc["stress_un"]))
    try:
        cells = np.asarray(doc.get("cells", []), dtype=np.int64).reshape(-1, 6)
        if (cells < 0).any():
            raise ValueError("negative")
        idx = tuple(cells[:, :4].T)
        sp.count[idx] = cells[:, 4]
        sp.fixed[idx] = cells[:, 5]
    except (ValueError, IndexError, TypeError):
        raise ConfigError(str(path), "cells", "…", f"must be [kind, class, measure, bin, count, fixed] rows "
                          f"within {SHAPE}") from None
    shear = doc.get("shear_w_per_g", math.nan)
    if "shear_w_per_g" in doc and (not isinstance(shear, (int, float)) or isinstance(shear, bool)
                                   or not math.isfinite(shear) or shear < 0):
        raise ConfigError(str(path), "shear_w_per_g", shear, "a number ≥ 0 (W/g), or leave the key out")
    return Condition(name or str(path), sp, float(doc["powder_g"]), float(shear))


def open_condition(text: str, base: str = ".", source: str = "command line", key: str = "condition") -> Condition:
    """The condition `text` names: a condition file (NAME.json), a sweep point
    (SWEEP.zarr#INDEX, the index in the sweep's plan) or a run store (RUN.zarr); a
    relative path is taken from the folder `base`. `source`/`key` name where the
    text came from in a one-line ConfigError."""
    import os

    from taimill.errors import StoreError

    path, _, point = text.partition("#")
    full = path if os.path.isabs(path) else os.path.join(base, path)
    if not os.path.exists(full):
        raise ConfigError(source, key, text, "no such run store, sweep point (SWEEP.zarr#INDEX) or condition file"
                          + (f" (looked in {base})" if base not in ("", ".") else ""))
    if path.endswith(".json") and not point:
        return read_file(full, text, source, key)
    try:
        if point:
            from taimill.store.sweep import open_sweep

            sweep = open_sweep(full)
            if not point.isdigit() or int(point) >= len(sweep.plan):
                raise ConfigError(source, key, text, f"point index: allowed 0 … {len(sweep.plan) - 1}")
            run = sweep.point(int(point))
        else:
            from taimill.store.run import open_run

            run = open_run(full)
    except StoreError as err:
        raise ConfigError(source, key, text, f"cannot be read ({err})") from None
    if not isinstance(run.config, dict) or not run.config:
        raise ConfigError(source, key, text, "cannot be read: not a taimill run store (no config attribute)")
    spectra = run.spectra  # StoreError names what is missing or damaged
    if not spectra.seconds > 0:  # rates over no time: the run stopped before its analysis window
        raise ConfigError(source, key, text, f"its energy spectra cover no time (window {spectra.start:g} to "
                          f"{spectra.end:g} s: the run stopped before its analysis window began); run it longer")
    grams = 1e3 * float(((run.config or {}).get("powder") or {}).get("mass") or math.nan)
    if not grams > 0:
        raise ConfigError(source, key, text, "the run has no powder: give [powder] mass_g or ball_to_powder in its "
                          "preset (or --powder-mass) and run it again")
    summary = getattr(run, "summary", None) or {}
    shear = summary.get("specific_power_shear_W_per_g", math.nan)
    return Condition(text, spectra, grams, float(shear) if isinstance(shear, (int, float)) else math.nan,
                     replicas=tuple(_replicas(sweep, int(point))) if point else ())


def _replicas(sweep, i: int) -> list:
    """The spectra of the sweep's finished points that differ from point i only in
    their seed (its replicas); a damaged one is left out."""
    from taimill.errors import StoreError

    def same(values: dict) -> dict:
        return {k: v for k, v in values.items() if k not in ("seed", "replica")}

    plan, out = sweep.plan, []
    mine = same(plan[i].get("values", {}))
    try:
        done = sorted(sweep.done())
    except StoreError:
        return []
    for j in done:
        if j != i and same(plan[j].get("values", {})) == mine:
            try:
                spectra = sweep.spectra(j)
            except StoreError:
                continue
            if spectra is not None:
                out.append(spectra)
    return out
