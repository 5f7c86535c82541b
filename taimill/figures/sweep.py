"""Figures of a sweep store (NumPy + matplotlib, from its summary table), like the
thesis' Figs 3.7, 3.8, 4.5, 4.13, 5.1 and 5.5: figures against K = ω/Ω + 1, one curve
per Ω / pair / jar / ball count, the replicas' mean with its 95 % Student-t band, the
single-ball critical ratio K_c (docs/model.md) marked, the refined maximum starred.
Where the replicas at a K end in different motion regimes (bistable, e.g. pinned to
the wall or cataracting near the collapse) the mean is ringed and each replica drawn
with its regime's marker; regimes.<fmt> shows the share of the replicas in each regime
against K.

`--overlay MEASURED.csv` draws a user's measured series against K on a second axis of
the mean-SE figure (the thesis validates so, with 1/√⟨D⟩ and √ρ, Figs 3.9, 4.17).
The CSV format (OVERLAY_FORMAT) is plain comma-separated text:

    # lines starting with '#' are comments
    ratio,inv_sqrt_D [1/sqrt(nm)],inv_sqrt_D_err,sqrt_rho [1e7/m]
    -1.0,0.120,0.004,3.1
    -2.6,0.151,,3.9

The first other line is the header. One column is `ratio` (K, the x values); every
other column is a series, named by its header (a unit in brackets is shown on the
axis); a column `NAME_err` gives ± error bars of series NAME. An empty cell is a
missing value. Anything else is an error naming the file, line and column.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from taimill.analysis.theory import critical_ratio
from taimill.errors import ConfigError
from taimill.model.files import csv_cells, read_text
from taimill.analysis.sweep import CURVE_COLUMNS, REGIMES, mean_band, regime_fractions
from taimill.store.output import whole_file

CURVE_AXES = (("jar", "{}"), ("balls", "{:.0f} balls"), ("pair", "{}"), ("plate_rpm", "Ω = {:g} rpm"))
# file stem, figure title, [(column, panel title)], y label, scale to the plotted unit
FIGURES = (
    ("mean_se", "Average stress energy per event (thesis Figs 5.1, 5.5)", [("mean_se", "total")], "mean SE (mJ)", 1e3),
    ("mean_se_components", "Average stress energy, normal and tangential (thesis Figs 3.7b, 4.5)",
     [("mean_se_normal", "normal"), ("mean_se_tangential", "tangential")], "mean SE (mJ)", 1e3),
    ("impact_power", "Impact power E_I/τ, eq 3.8 (thesis Figs 3.7a, 4.13)", [("impact_power", "total")], "impact power (W)", 1.0),
    ("randomness", "Randomness index 1/σ of g(r), eq 3.9 (thesis Fig 3.8)", [("randomness_index", "1/σ")], "1/σ", 1.0),
    ("normal_fraction", "Normal share of the stress energy", [("normal_fraction", "SE_n / SE")], "normal fraction", 1.0),
)
K_LABEL = "K = ω/Ω + 1 (jar spin / plate spin; |K| grows to the right)"
REGIME_MARKERS = {"cascading": "s", "cataracting": "^", "rolling": "v"}  # any other label: "x"
MIXED_LABEL = "mean over replicas in different regimes"


def report_sweep(path, out_dir, fmt: str = "png", overlay=None) -> list[Path]:
    """Write the sweep figures of the store at `path` into `out_dir` as `fmt` (png,
    svg, pdf); with `overlay` (a CSV path) also overlay.<fmt>. Returns the files."""
    import matplotlib

    matplotlib.use("Agg")
    from taimill.store.sweep import open_sweep

    if fmt not in ("png", "svg", "pdf"):
        raise ConfigError("command line", "--format", fmt, "must be one of png, svg, pdf")
    measured = read_overlay(overlay) if overlay else None
    store = open_sweep(path)
    table = store.table()
    if not len(table.get("point", [])):
        raise ConfigError("command line", "sweep store", str(path), "has no finished point yet")
    peaks = (store.refine or {}).get("peaks", [])
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, title, panels, ylabel, scale in FIGURES:
        fig = _figure(table, title, panels, ylabel, scale, peaks)
        written.append(_save(fig, out_dir / f"{stem}.{fmt}"))
    written.append(_save(_regime_figure(table), out_dir / f"regimes.{fmt}"))
    if measured is not None:
        fig = _figure(table, f"Average stress energy and measured data ({Path(overlay).name})",
                      [("mean_se", "total")], "mean SE (mJ)", 1e3, peaks, measured)
        written.append(_save(fig, out_dir / f"overlay.{fmt}"))
    return written


def curves(table: dict) -> dict[str, np.ndarray]:
    """Label → row indices, one curve per combination of jar, balls, pair and Ω; the
    label names only the axes that vary across the sweep."""
    varying = [(k, f) for k, f in CURVE_AXES if len(set(table[k].tolist())) > 1] or list(CURVE_AXES)
    keys = [tuple(table[k][i] for k, _ in CURVE_AXES) for i in range(len(table["point"]))]
    out: dict = {}
    for i, key in enumerate(keys):
        label = ", ".join(f.format(table[k][i]) for k, f in varying)
        out.setdefault(label, []).append(i)
    return {label: np.array(rows) for label, rows in out.items()}


def band(table: dict, rows: np.ndarray, column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique K (ascending), replicate mean and 95 % half-width (NaN for one replica)."""
    k = np.round(table["ratio"][rows].astype(float), 10)
    y = table[column][rows].astype(float) if column in table else np.full(len(rows), np.nan)
    ks = np.unique(k)
    stats = np.array([mean_band(y[k == v])[:2] for v in ks]).reshape(-1, 2)
    return ks, stats[:, 0], stats[:, 1]


def _figure(table, title, panels, ylabel, scale, peaks, measured=None):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(6.4 * len(panels), 4.6), squeeze=False)
    groups = curves(table)
    for ax, (column, panel) in zip(axes[0], panels):
        drawn: set[str] = set()
        for n, (label, rows) in enumerate(groups.items()):
            ks, mean, half = band(table, rows, column)
            color = f"C{n % 10}"
            ax.plot(ks, mean * scale, "o-", ms=3.5, color=color, label=label)
            if np.isfinite(half).any():
                ax.fill_between(ks, (mean - half) * scale, (mean + half) * scale, color=color, alpha=0.2, lw=0)
            drawn |= mark_mixed(ax, table, rows, column, scale, color)
        _mixed_legend(ax, drawn)
        _mark_peaks(ax, peaks, column, scale)
        _mark_critical(ax, table)
        ax.set_title(panel, fontsize=10)
        ax.set_xlabel(K_LABEL, fontsize=9)
        ax.set_ylabel(ylabel)
        if not ax.xaxis_inverted():
            ax.invert_xaxis()
        ax.grid(alpha=0.3)
        if measured is not None:
            _overlay(ax, measured)
        ax.legend(fontsize=8, loc="upper left")
    if any(np.isfinite(band(table, r, panels[0][0])[2]).any() for r in groups.values()):
        title += " — mean of replicas, 95 % band"
    if any(g["bistable"] for rows in groups.values() for g in regime_groups(table, rows)):
        title += "; ringed: replicas in different regimes"
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def regime_groups(table: dict, rows: np.ndarray) -> list[dict]:
    """taimill.analysis.sweep.regime_fractions of the table's `rows` (one curve)."""
    return regime_fractions({c: np.asarray(table[c])[rows] for c in (*CURVE_COLUMNS, "ratio", "regime")})


def mark_mixed(ax, table, rows, column, scale, color) -> set[str]:
    """At each K of the curve `rows` whose replicas end in different regimes: a ring
    round the plotted mean and every replica's own value, marked by its regime.
    Returns the regimes drawn."""
    k = np.round(table["ratio"][rows].astype(float), 10)
    y = table[column][rows].astype(float) * scale if column in table else np.full(len(rows), np.nan)
    labels = np.array([str(v) or "unknown" for v in table["regime"][rows]])
    ks, mean, _ = band(table, rows, column)
    drawn = set()
    for g in regime_groups(table, rows):
        if not g["bistable"]:
            continue
        ax.plot([g["ratio"]], mean[ks == g["ratio"]] * scale, "o", ms=12, mfc="none", mec="k", mew=1.2, zorder=4)
        for regime in sorted(set(labels[k == g["ratio"]])):
            at = (k == g["ratio"]) & (labels == regime)
            ax.plot(k[at], y[at], REGIME_MARKERS.get(regime, "x"), ms=5, mfc="none", mec=color, ls="none", zorder=4)
            drawn.add(regime)
    return drawn


def _mixed_legend(ax, drawn: set[str]):
    """Legend entries (grey proxies) for what mark_mixed drew on `ax`."""
    if drawn:
        ax.plot([], [], "o", ms=12, mfc="none", mec="k", mew=1.2, label=MIXED_LABEL)
    for regime in sorted(drawn):
        ax.plot([], [], REGIME_MARKERS.get(regime, "x"), ms=5, mfc="none", mec="0.4", ls="none",
                label=f"replica ending {regime}")


def _regime_figure(table):
    """Share of the replicas in each regime against K: one panel per regime, one line
    per curve, ringed where the replicas of a K disagree."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(REGIMES), figsize=(5.2 * len(REGIMES), 4.2), squeeze=False, sharey=True)
    per_curve = {label: regime_groups(table, rows) for label, rows in curves(table).items()}
    any_mixed = any(g["bistable"] for groups in per_curve.values() for g in groups)
    for ax, regime in zip(axes[0], REGIMES):
        for n, (label, groups) in enumerate(per_curve.items()):
            share = np.array([g["regime_fractions"][regime] for g in groups])
            ks = np.array([g["ratio"] for g in groups])
            mixed = np.array([g["bistable"] for g in groups])
            ax.plot(ks, share, "o-", ms=3.5, color=f"C{n % 10}", label=label)
            ax.plot(ks[mixed], share[mixed], "o", ms=12, mfc="none", mec="k", mew=1.2, zorder=4)
        if any_mixed:
            ax.plot([], [], "o", ms=12, mfc="none", mec="k", mew=1.2, label="replicas in different regimes")
        _mark_critical(ax, table)
        ax.set_title(regime, fontsize=10)
        ax.set_xlabel(K_LABEL, fontsize=9)
        ax.set_ylim(-0.05, 1.05)
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8, loc="best")
    axes[0][0].set_ylabel("share of the replicas")
    fig.suptitle("Motion regime of the replicas at each K (taimill.analysis.regime)", fontsize=11)
    fig.tight_layout()
    return fig


def _mark_critical(ax, table):
    """K_c = -√(R_p / (R_jar - r)) for each geometry in the sweep (docs/model.md)."""
    geoms = {(float(a), float(b), float(c)) for a, b, c in zip(table["plate_radius"], table["jar_radius"], table["ball_radius"])}
    for n, g in enumerate(sorted(geoms)):
        kc = critical_ratio(*g)
        ax.axvline(kc, color="0.3", ls="--", lw=1, label="K_c, one ball" if n == 0 else None)


def _mark_peaks(ax, peaks, column, scale):
    for p in peaks:
        if p.get("metric") == column and math.isfinite(p.get("ratio", math.nan)):
            ax.plot([p["ratio"]], [p["value"] * scale], "*", ms=12, color="k", zorder=5,
                    label=f"refined max K = {p['ratio']:.2f} ({p['method']})")


def _overlay(ax, measured):
    twin = ax.twinx()
    for n, (name, (x, y, err)) in enumerate(measured.items()):
        unit = re.search(r"\[(.*)\]", name)
        twin.errorbar(x, y, yerr=err, fmt="s--", ms=4, color=f"C{(n + 5) % 10}", capsize=2,
                      label=f"measured: {_bare(name)}")
        if unit:
            twin.set_ylabel(f"measured ({unit.group(1)})")
    if not twin.get_ylabel():
        twin.set_ylabel("measured")
    twin.legend(fontsize=8, loc="upper right")


def _bare(name: str) -> str:
    """A series name without its "[unit]"."""
    return re.sub(r"\s*\[.*\]", "", name)


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=120)
    finally:
        plt.close(fig)
    return path


def read_overlay(path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """Series name → (K, values, ± errors or None) from a CSV in the format of the
    module docstring; ConfigError naming file, line and column for anything else."""
    text = read_text(path, "command line", "--overlay", "CSV file")
    path = Path(path)
    lines = [(n, ln) for n, ln in enumerate(text.splitlines(), 1) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ConfigError(path, "header", None, "the file has no header line: expected 'ratio,SERIES[,SERIES_err]…'")
    header = [h.strip() for h in csv_cells(lines[0][1], path, f"line {lines[0][0]}")]
    if "ratio" not in header:
        raise ConfigError(path, f"line {lines[0][0]}", lines[0][1], "the header needs a column named 'ratio' (K = ω/Ω + 1)")
    if len(header) < 2 or len(set(header)) != len(header) or not all(header):
        raise ConfigError(path, f"line {lines[0][0]}", lines[0][1], "the header needs 'ratio' and at least one series, all named and distinct")
    if len(lines) < 2:
        raise ConfigError(path, "data", None, "no data line after the header")
    data = np.full((len(lines) - 1, len(header)), np.nan)
    for r, (n, ln) in enumerate(lines[1:]):
        cells = csv_cells(ln, path, f"line {n}")
        if len(cells) != len(header):
            raise ConfigError(path, f"line {n}", ln, f"{len(cells)} cells; the header has {len(header)} columns")
        for c, cell in enumerate(cells):
            if not cell.strip():
                continue
            try:
                data[r, c] = float(cell)
            except ValueError:
                raise ConfigError(path, f"line {n}, column {header[c]}", cell, "must be a number (or empty)") from None
            if not math.isfinite(data[r, c]):
                raise ConfigError(path, f"line {n}, column {header[c]}", cell, "must be finite")
            if header[c].endswith("_err") and data[r, c] < 0:  # a ± error bar; matplotlib refuses one below 0
                raise ConfigError(path, f"line {n}, column {header[c]}", cell, "allowed range [0, ∞): an error is ≥ 0")
    k = data[:, header.index("ratio")]
    if np.isnan(k).any():
        n = lines[1 + int(np.flatnonzero(np.isnan(k))[0])][0]
        raise ConfigError(path, f"line {n}, column ratio", "", "every data line needs a ratio")
    series = {}
    for c, name in enumerate(header):
        if name == "ratio" or name.endswith("_err"):
            continue
        err_col = f"{_bare(name)}_err"
        err = data[:, header.index(err_col)] if err_col in header else None
        series[name] = (k, data[:, c], err)
    orphans = [h for h in header if h.endswith("_err") and not any(_bare(s) + "_err" == h for s in series)]
    if orphans:
        raise ConfigError(path, "header", orphans[0], "an error column needs its series column (NAME and NAME_err)")
    return series
