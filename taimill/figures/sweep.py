"""Figures of a sweep store (NumPy + matplotlib, from its summary table), like the
thesis' Figs 3.7, 3.8, 4.5, 4.13, 5.1 and 5.5: figures against the swept variable
(taimill.analysis.sweep.sweep_axes: K for a K sweep, the plate speed Ω for a sweep over
--plate-rpm at one K, the ball count, μ, …), one curve per value of every other swept
axis (jar, pair, material, mill, Ω …), the replicas' mean with its 95 % Student-t band;
against K the single-ball critical ratio K_c (docs/model.md) is marked and the refined
maximum starred. A sweep over two numeric axes (plate speed × K, as on a free-gear
mill) is also drawn as maps (taimill.figures.sweep_map).
Where the replicas at a value end in different motion regimes (bistable, e.g. pinned to
the wall or cataracting near the collapse) the mean is ringed and each replica drawn
with its regime's marker; regimes.<fmt> shows the share of the replicas in each regime
against the swept variable.

`--overlay MEASURED.csv` draws a user's measured series against K on a second axis of
the mean-SE figure of a K sweep (the thesis validates so, with 1/√⟨D⟩ and √ρ, Figs 3.9,
4.17). The CSV format (OVERLAY_FORMAT) is plain comma-separated text:

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

from taimill.analysis.regime import row_class
from taimill.analysis.sweep import (SweepAxes, axis_label, axis_scale, curves, first_value, mean_band, py_value,
                                    regime_fractions, seen_classes, sweep_axes, value_text, x_values)
from taimill.errors import ConfigError
from taimill.model.files import csv_cells, read_text
from taimill.figures.layout import legend_outside
from taimill.figures.sweep_map import MAPS, map_figure, mark_critical
from taimill.store.output import whole_file

# file stem, figure title, [(column, panel title)], y label, scale to the plotted unit
FIGURES = (
    ("mean_se", "Average stress energy per event (thesis Figs 5.1, 5.5)", [("mean_se", "total")], "mean SE (mJ)", 1e3),
    ("mean_se_components", "Average stress energy, normal and tangential (thesis Figs 3.7b, 4.5)",
     [("mean_se_normal", "normal"), ("mean_se_tangential", "tangential")], "mean SE (mJ)", 1e3),
    ("impact_power", "Impact power E_I/τ (eq 3.8, thesis Figs 3.7a, 4.13) beside the dissipated power, one jar",
     [("impact_power", "impact power E_I/τ (kinematic stress energy)"), ("dissipated_power", "dissipated power (what the charge takes)")],
     "power (W)", 1.0),
    ("randomness", "Randomness index 1/σ of g(r), eq 3.9 (thesis Fig 3.8)", [("randomness_index", "1/σ")], "1/σ", 1.0),
    ("normal_fraction", "Normal share of the stress energy", [("normal_fraction", "SE_n / SE")], "normal fraction", 1.0),
    ("dissipation", "Dissipated power by class: impacts and persistent contacts (normal and friction work), one jar",
     [("dissipated_power_impact", "impacts"), ("dissipated_power_persistent", "persistent contacts")], "dissipated power (W)", 1.0),
    ("specific_power", "Dissipated power per gram of powder, one jar (with --powder-mass)",
     [("specific_power_W_per_g", "all contacts"), ("specific_power_impact_W_per_g", "in impacts")], "power per gram (W/g)", 1.0),
    ("shear", "Gentle / shear view: friction power of persistent contacts per m² of jar wall",
     [("shear_power_persistent_wall_W_per_m2", "persistent friction on the wall")], "power per wall area (W/m²)", 1.0),
)
K_LABEL = "K = ω/Ω + 1 (jar spin / plate spin; |K| grows to the right)"
REGIME_MARKERS = {"cascading": "s", "cataracting": "^", "hopping bed": "v", "pinned ring": "o", "sliding bed": ">",
                  "rolling bed": "D"}  # the regime classes (sweep_map.CLASS_MARKERS); any other label: "x"
MIXED_LABEL = "mean over replicas in different regimes"
LEGEND_WIDTH = 2.5  # inches added to a figure for the legends outside its panels


def figures_of(table: dict) -> list[tuple]:
    """The FIGURES a sweep table has data for: the per-gram one only with a powder mass."""
    return [f for f in FIGURES if f[0] != "specific_power" or "specific_power_W_per_g" in table]


def figure_stems(table: dict, overlay: bool = False) -> list[str]:
    """The file stems report_sweep writes for this sweep table."""
    ax = sweep_axes(table)
    return ([f[0] for f in figures_of(table)] + ["regimes", "energy_spectra"] + ([m[0] for m in MAPS] if ax.y else [])
            + (["overlay"] if overlay else []))


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
    axes = store_axes(store, table)
    if measured is not None and axes.x != "ratio":
        raise ConfigError("command line", "--overlay", str(overlay),
                          f"measured series are drawn against K; this sweep varies {axis_label(axes.x)}")
    peaks = (store.refine or {}).get("peaks", [])
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, title, panels, ylabel, scale in figures_of(table):
        fig = sweep_figure(table, title, panels, ylabel, scale, peaks, axes=axes)
        written.append(_save(fig, out_dir / f"{stem}.{fmt}"))
    written.append(_save(_regime_figure(table, axes), out_dir / f"regimes.{fmt}"))
    written.append(_save(_spectra_figure(store, table), out_dir / f"energy_spectra.{fmt}"))
    if axes.y:
        for stem, column, label, scale in MAPS:
            written.append(_save(map_figure(table, column, label, scale, axes), out_dir / f"{stem}.{fmt}"))
    if measured is not None:
        fig = sweep_figure(table, f"Average stress energy and measured data ({Path(overlay).name})",
                           [("mean_se", "total")], "mean SE (mJ)", 1e3, peaks, measured, axes=axes)
        written.append(_save(fig, out_dir / f"overlay.{fmt}"))
    return written


SPECTRA_LINES = 8  # points overlaid in the energy spectra figure (evenly spread over the plan)


def _spectra_figure(store, table):
    """The energy spectra of up to SPECTRA_LINES points, overlaid, each labelled by its
    swept values (taimill.figures.spectra)."""
    from taimill.figures.spectra import spectra_figure

    points = [int(i) for i in table["point"]]
    if len(points) > SPECTRA_LINES:
        points = [points[round(k * (len(points) - 1) / (SPECTRA_LINES - 1))] for k in range(SPECTRA_LINES)]
    items = []
    for i in points:
        sp = store.spectra(i)
        if sp is not None:
            values = store.plan[i].get("values", {})
            label = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in values.items()
                              if k not in ("replica",)) or f"point {i}"
            items.append((label, sp))
    shown = "" if len(points) == len(table["point"]) else f" ({len(items)} of {len(table['point'])} points)"
    return spectra_figure(items, f"Energy spectra of the collision events{shown}")


def store_axes(store, table) -> SweepAxes:
    """sweep_axes of a store's table, the stored points' value columns as candidates."""
    return sweep_axes(table, [k for p in store.plan[:1] for k in p.get("values", {})])


def band(table: dict, rows: np.ndarray, column: str, x: str = "ratio") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique x values (ascending; K by default), replicate mean and 95 % half-width (NaN for one replica)."""
    k = x_values(table, rows, x)
    y = table[column][rows].astype(float) if column in table else np.full(len(rows), np.nan)
    ks = np.unique(k)
    stats = np.array([mean_band(y[k == v])[:2] for v in ks]).reshape(-1, 2)
    return ks, stats[:, 0], stats[:, 1]


def _x_axis(ax, table, axes: SweepAxes):
    """Label, ticks and direction of the x axis: K falls to the right (|K| grows), as
    does any axis whose values are all ≤ 0; a text axis gets its values as ticks."""
    ax.set_xlabel(axis_label(axes.x), fontsize=9)
    if axes.text_x:
        names = list(dict.fromkeys(str(c) for c in table[axes.x]))
        ax.set_xticks(range(len(names)), names, fontsize=8)
    elif np.all(np.asarray(table[axes.x], dtype=float) <= 0) and not ax.xaxis_inverted():
        ax.invert_xaxis()


def _shown(table, axes: SweepAxes, values):
    """x values in the shown unit (the ball diameter in mm from its radius in m)."""
    scale = axis_scale(axes.x)
    return values if axes.text_x or scale in (None, 1) else values * scale


def friction_led_text(table, axes) -> str:
    """"; friction-led at Ω 700, 1100 rpm" for a title: where friction takes ≥ 90 % of the
    dissipated power (taimill.analysis.summary.power_lead) the impact power understates it."""
    led = [i for i, v in enumerate(table.get("power_led", [])) if v == "friction-led"]
    if not led:
        return ""
    if len(led) == len(table["point"]):
        return "\nfriction-led at every point: the charge takes its power by friction, read the dissipated power"
    xs = sorted({first_value([table[axes.x][i]]) for i in led}, key=lambda v: (isinstance(v, str), v))
    shown = ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in xs)
    return f"\nfriction-led at {axis_label(axes.x)} {shown}: read the dissipated power there"


def sweep_figure(table, title, panels, ylabel, scale, peaks=(), measured=None, axes: SweepAxes | None = None):
    """One figure of the sweep table against axes.x (default sweep_axes(table)): a panel
    per (column, panel title), a curve per combination of the other varying axes."""
    import matplotlib.pyplot as plt

    axes = axes or sweep_axes(table)
    fig, plots = plt.subplots(1, len(panels), figsize=(6.4 * len(panels) + LEGEND_WIDTH, 4.6), squeeze=False)
    groups = curves(table, axes)
    for ax, (column, panel) in zip(plots[0], panels):
        drawn: set[str] = set()
        for n, (label, rows) in enumerate(groups.items()):
            ks, mean, half = band(table, rows, column, axes.x)
            xs = _shown(table, axes, ks)
            color = f"C{n % 10}"
            ax.plot(xs, mean * scale, "o-", ms=3.5, color=color, label=label)
            if np.isfinite(half).any():
                ax.fill_between(xs, (mean - half) * scale, (mean + half) * scale, color=color, alpha=0.2, lw=0)
            drawn |= mark_mixed(ax, table, rows, column, scale, color, axes)
        _mixed_legend(ax, drawn)
        if axes.x == "ratio":  # landmarks of K
            _mark_peaks(ax, peaks, column, scale)
            mark_critical(ax, table, axes)
        ax.set_title(panel, fontsize=10)
        _x_axis(ax, table, axes)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        if measured is not None:
            _overlay(ax, measured)
        else:
            legend_outside(ax, fontsize=8)
    if any(np.isfinite(band(table, r, panels[0][0], axes.x)[2]).any() for r in groups.values()):
        title += " — mean of replicas, 95 % band"
    if any(g["bistable"] for rows in groups.values() for g in regime_groups(table, rows, axes)):
        title += "; ringed: replicas in different regimes"
    title += friction_led_text(table, axes)
    fixed = ", ".join(value_text(c, first_value(table[c])) for c in axes.fixed if c != axes.x)
    fig.suptitle(title + (f"\n{fixed}" if fixed else ""), fontsize=11)
    fig.tight_layout()
    return fig


def regime_groups(table: dict, rows: np.ndarray, axes: SweepAxes | None = None) -> list[dict]:
    """taimill.analysis.sweep.regime_fractions of the table's `rows` (one curve) along
    axes.x (K by default), each with its x coordinate as `x` (x_values)."""
    x = axes.x if axes else "ratio"
    sub = {c: np.asarray(table[c])[rows] for c in table} | {"x": x_values(table, rows, x)}
    return [g | {x: g["x"]} if x != "x" else g for g in regime_fractions(sub, ("x",))]


def mark_mixed(ax, table, rows, column, scale, color, axes: SweepAxes | None = None) -> set[str]:
    """At each x (K by default) of the curve `rows` whose replicas end in different
    regimes: a ring round the plotted mean and every replica's own value, marked by its
    regime. Returns the regimes drawn."""
    x = axes.x if axes else "ratio"
    k = x_values(table, rows, x)
    y = table[column][rows].astype(float) * scale if column in table else np.full(len(rows), np.nan)
    names = list(table)
    labels = np.array([row_class({c: py_value(table[c][r]) for c in names}) for r in rows])
    ks, mean, _ = band(table, rows, column, x)
    shown = (lambda v: v) if axes is None else (lambda v: _shown(table, axes, v))
    drawn = set()
    for g in regime_groups(table, rows, axes):
        if not g["bistable"]:
            continue
        ax.plot(shown(np.array([g["x"]])), mean[ks == g["x"]] * scale, "o", ms=12, mfc="none", mec="k", mew=1.2, zorder=4)
        for regime in sorted(set(labels[k == g["x"]])):
            at = (k == g["x"]) & (labels == regime)
            ax.plot(shown(k[at]), y[at], REGIME_MARKERS.get(regime, "x"), ms=5, mfc="none", mec=color, ls="none", zorder=4)
            drawn.add(regime)
    return drawn


def _mixed_legend(ax, drawn: set[str]):
    """Legend entries (grey proxies) for what mark_mixed drew on `ax`."""
    if drawn:
        ax.plot([], [], "o", ms=12, mfc="none", mec="k", mew=1.2, label=MIXED_LABEL)
    for regime in sorted(drawn):
        ax.plot([], [], REGIME_MARKERS.get(regime, "x"), ms=5, mfc="none", mec="0.4", ls="none",
                label=f"replica ending {regime}")


def _regime_figure(table, axes: SweepAxes | None = None):
    """Share of the replicas in each regime class against axes.x: one panel per class
    some replica ends in (the classes of the summary and the sweep table), one line per
    curve, ringed where the replicas at a value disagree."""
    import matplotlib.pyplot as plt

    axes = axes or sweep_axes(table)
    per_curve = {label: regime_groups(table, rows, axes) for label, rows in curves(table, axes).items()}
    shown = seen_classes([g for groups in per_curve.values() for g in groups]) or ["unknown"]
    fig, plots = plt.subplots(1, len(shown), figsize=(4.4 * len(shown) + LEGEND_WIDTH, 4.2), squeeze=False,
                              sharey=True)
    any_mixed = any(g["bistable"] for groups in per_curve.values() for g in groups)
    for ax, regime in zip(plots[0], shown):
        for n, (label, groups) in enumerate(per_curve.items()):
            share = np.array([g["regime_fractions"].get(regime, 0.0) for g in groups])
            ks = _shown(table, axes, np.array([g["x"] for g in groups]))
            mixed = np.array([g["bistable"] for g in groups])
            ax.plot(ks, share, "o-", ms=3.5, color=f"C{n % 10}", label=label)
            ax.plot(ks[mixed], share[mixed], "o", ms=12, mfc="none", mec="k", mew=1.2, zorder=4)
        if any_mixed:
            ax.plot([], [], "o", ms=12, mfc="none", mec="k", mew=1.2, label="replicas in different regimes")
        if axes.x == "ratio":
            mark_critical(ax, table, axes)
        ax.set_title(regime, fontsize=10)
        _x_axis(ax, table, axes)
        ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3)
    legend_outside(plots[0][-1], handles=plots[0][0].get_legend_handles_labels()[0], fontsize=8)
    plots[0][0].set_ylabel("share of the replicas")
    fig.suptitle(f"Regime class of the replicas at each {axis_label(axes.x).split(' (')[0]} (taimill.analysis.regime)",
                 fontsize=11)
    fig.tight_layout()
    return fig


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
    handles = [h for a in (ax, twin) for h in a.get_legend_handles_labels()[0]]
    legend_outside(twin, handles=handles, fontsize=8, gap=0.7)  # right of the twin axis' labels


def _bare(name: str) -> str:
    """A series name without its "[unit]"."""
    return re.sub(r"\s*\[.*\]", "", name)


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=120, bbox_inches="tight")  # the legends outside the panels too
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
