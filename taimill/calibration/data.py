"""Measured drop tests: a CSV of drop heights and rebounds (format in
`taimill/data/zirconia_drop_table2_1.csv`, thesis Table 2.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.model.files import csv_cells, read_text

DATA_DIR = Path(__file__).resolve().parent.parent / "data"
TABLE_2_1 = DATA_DIR / "zirconia_drop_table2_1.csv"
MAX_HEIGHT_MM = 10_000.0


@dataclass(frozen=True)
class DropData:
    source: str
    h0: np.ndarray  #: m, drop heights
    e: np.ndarray  #: measured restitution, eq 2.5
    sigma: np.ndarray  #: 1 s.d. of e per row (nan: not given, the fit's --scatter applies)
    measured_rebound: np.ndarray | None = None  #: m, the file's rebound_mm per row (nan: not given)

    @property
    def rebound(self) -> np.ndarray:
        """Rebound heights h* = e² h₀ (m), eq 2.5."""
        return self.e**2 * self.h0

    @property
    def rebound_shown(self) -> np.ndarray:
        """The measured rebound heights (m): the file's rebound_mm where it gives one, else
        e² h₀. (With both columns the file's e is fitted, and the rows of Table 2.1 show
        that e² h₀ is not the measured rebound: a mean of e is not √(mean h*/h₀).)"""
        given = np.full_like(self.h0, np.nan) if self.measured_rebound is None else self.measured_rebound
        return np.where(np.isfinite(given), given, self.rebound)


def _number(path, line, col, text, lo, hi, unit=""):
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise ConfigError(path, f"{col} (line {line})", text, "must be a number") from None
    if not (math.isfinite(v) and lo < v <= hi):
        raise ConfigError(path, f"{col} (line {line})", v, f"allowed range ({lo:g}, {hi:g}]{unit}")
    return v


def load_drop_data(path) -> DropData:
    """Read a drop-test CSV: h0_mm and rebound_mm or e per row (e wins when both are
    given: see the file format), optional sigma_e or sigma_mm; other columns ignored."""
    text = read_text(path, "command line", "--data", "CSV file")
    path = Path(path)
    lines = [(i + 1, s) for i, s in enumerate(text.splitlines()) if s.strip() and not s.lstrip().startswith("#")]
    if not lines:
        raise ConfigError(path, "columns", None, "empty file; need a header with h0_mm and rebound_mm or e")
    header = [c.strip() for c in csv_cells(lines[0][1], path, f"line {lines[0][0]}")]
    if "h0_mm" not in header or not {"rebound_mm", "e"} & set(header):
        raise ConfigError(path, "columns", ",".join(header), "need h0_mm and rebound_mm or e (optional sigma_e or sigma_mm)")
    h0, e, sigma, rebound = [], [], [], []
    for line, row in lines[1:]:
        values = [c.strip() for c in csv_cells(row, path, f"line {line}")]
        if len(values) > len(header):  # a shifted row would silently fit the wrong numbers
            raise ConfigError(path, f"line {line}", row, f"{len(values)} cells; the header has {len(header)} columns "
                              f"({','.join(header)})")
        cells = dict(zip(header, values))
        h = _number(path, line, "h0_mm", cells.get("h0_mm"), 0, MAX_HEIGHT_MM, " mm")
        hr = math.nan
        if "rebound_mm" in header and (cells.get("rebound_mm") or "e" not in header):
            hr = _number(path, line, "rebound_mm", cells.get("rebound_mm"), 0, h, " mm (h* <= h0)")
        if "e" in header:
            ei = _number(path, line, "e", cells.get("e"), 0, 1)
        else:
            ei = math.sqrt(hr / h)
        s = math.nan
        if "sigma_e" in header:
            s = _number(path, line, "sigma_e", cells.get("sigma_e"), 0, 1)
        elif "sigma_mm" in header:
            s = _number(path, line, "sigma_mm", cells.get("sigma_mm"), 0, h, " mm") / (2 * ei * h)  # dh* = 2 e h0 de
        h0.append(h * 1e-3)
        e.append(ei)
        sigma.append(s)
        rebound.append(hr * 1e-3)
    if not h0:
        raise ConfigError(path, "rows", 0, "no data rows after the header")
    return DropData(str(path), np.array(h0), np.array(e), np.array(sigma), np.array(rebound))
