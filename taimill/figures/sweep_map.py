"""Maps of a sweep over two numeric axes (plate speed × K, as on a free-gear mill; any
two that vary, taimill.analysis.sweep.sweep_axes): each cell coloured by the replicas'
mean of a metric (impact power, dissipated power: map_<metric>.<fmt>), marked by the
regime class most of its replicas end in (taimill.analysis.regime.MAP_REGIMES), one
panel per combination of the other swept values."""

from __future__ import annotations


import numpy as np

from taimill.analysis.regime import MAP_REGIMES, row_class
from taimill.analysis.sweep import (SweepAxes, axis_label, axis_scale, curves, first_value, mean_band, py_value,
                                    sweep_axes, value_text, x_values)
from taimill.analysis.theory import critical_ratio
from taimill.figures.layout import legend_outside

# maps of a sweep over two numeric axes: (file stem, column, colour bar label, scale)
MAPS = (("map_impact_power", "impact_power", "impact power E_I/τ, one jar (W)", 1.0),
        ("map_dissipated_power", "dissipated_power", "dissipated power, one jar (W)", 1.0))
CLASS_MARKERS = {"cascading": "s", "cataracting": "^", "hopping bed": "v", "pinned ring": "o", "sliding bed": ">",
                 "rolling bed": "D"}  # else "x"


regime_class = row_class  # a sweep row's class (taimill.analysis.regime.row_class)


def map_figure(table: dict, column: str, label: str, scale: float = 1.0, axes: SweepAxes | None = None):
    """The sweep as a map over its two numeric axes (axes.x across, axes.y up): each cell
    coloured by the replicas' mean of `column` (× scale), marked by the regime class
    most of its replicas end in; one panel per combination of the other varying axes."""
    import matplotlib.pyplot as plt

    axes = axes or sweep_axes(table)
    if axes.y is None:
        raise ValueError("a map needs a sweep over two numeric axes")
    groups = curves(table, SweepAxes(axes.x, axes.y, tuple(c for c in axes.curves if c != axes.y), axes.fixed))
    fig, plots = plt.subplots(1, len(groups), figsize=(6.4 * len(groups), 5.0), squeeze=False)
    values = np.asarray(table[column], dtype=float) * scale if column in table else np.full(len(table["point"]), np.nan)
    names = list(table)
    sx, sy = axis_scale(axes.x) or 1, axis_scale(axes.y) or 1
    cells = {}
    for panel, rows in groups.items():  # per panel: x values, y values, mean grid, majority class per cell
        xs, ys = x_values(table, rows, axes.x), x_values(table, rows, axes.y)
        ux, uy = np.unique(xs), np.unique(ys)
        grid = np.full((len(uy), len(ux)), np.nan)
        marks = []
        for i, yv in enumerate(uy):
            for j, xv in enumerate(ux):
                at = rows[(xs == xv) & (ys == yv)]
                if len(at):
                    grid[i, j] = mean_band(values[at])[0]
                    classes = [regime_class({c: py_value(table[c][r]) for c in names}) for r in at]
                    marks.append((xv, yv, max(sorted(set(classes)), key=classes.count)))
        cells[panel] = ux, uy, grid, marks
    finite = np.concatenate([g[np.isfinite(g)] for _, _, g, _ in cells.values()])
    vmin, vmax = (float(finite.min()), float(finite.max())) if len(finite) else (0.0, 1.0)
    shown = set()
    for ax, (panel, (ux, uy, grid, marks)) in zip(plots[0], cells.items()):
        mesh = ax.pcolormesh(_edges(ux) * sx, _edges(uy) * sy, grid, cmap="viridis", vmin=vmin, vmax=vmax,
                             edgecolors="white", linewidth=0.5)
        for xv, yv, cls in marks:
            ax.plot([xv * sx], [yv * sy], CLASS_MARKERS.get(cls, "x"), ms=7, mfc="none", mec="w", mew=1.4)
            shown.add(cls)
        ax.set_xlabel(axis_label(axes.x), fontsize=9)
        ax.set_ylabel(axis_label(axes.y), fontsize=9)
        if np.all(ux <= 0):
            ax.invert_xaxis()
        if axes.x == "ratio":
            mark_critical(ax, table, axes)
        if panel != "all points":
            ax.set_title(panel, fontsize=10)
        fig.colorbar(mesh, ax=ax, label=label)
    handles = [plt.Line2D([], [], ls="none", marker=CLASS_MARKERS.get(c, "x"), mfc="none", mec="k", label=f"regime: {c}")
               for c in (*MAP_REGIMES, "unknown") if c in shown]
    legend_outside(plots[0][-1], below=True, gap=0.5, handles=handles + plots[0][0].get_legend_handles_labels()[0],
                   fontsize=7, ncol=3, frameon=False)
    fixed = ", ".join(value_text(c, first_value(table[c])) for c in axes.fixed if c not in (axes.x, axes.y))
    fig.suptitle(f"{label}; markers: regime class" + (f"\n{fixed}" if fixed else ""), fontsize=10)
    fig.tight_layout()
    return fig


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges halfway between grid values."""
    if len(v) == 1:
        return np.array([v[0] - 0.5 * (abs(v[0]) or 1.0) * 0.1, v[0] + 0.5 * (abs(v[0]) or 1.0) * 0.1])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


CRITICAL_STYLES = ("--", ":", "-.", (0, (6, 2, 1, 2, 1, 2)), (0, (1, 3)))


def mark_critical(ax, table, axes: SweepAxes | None = None):
    """K_c = -√(R_p / (R_jar - r)) for each geometry in the sweep (docs/model.md): one
    line per distinct K_c, each its own legend entry; with several, each names the
    values of the swept axes (axes.curves) that give it ("d = 8 mm"), leaving out an
    axis whose every value shares the line (jars of one radius)."""
    axes = axes or sweep_axes(table)
    geoms = zip(table["plate_radius"], table["jar_radius"], table["ball_radius"])
    kcs = np.array([round(critical_ratio(float(a), float(b), float(c)), 6) for a, b, c in geoms])
    lines = sorted(set(kcs.tolist()))
    for n, kc in enumerate(lines):
        parts = []
        for c in axes.curves if len(lines) > 1 else ():
            column = [py_value(v) for v in table[c]]
            mine = list(dict.fromkeys(v for v, k in zip(column, kcs) if k == kc))
            if len(mine) < len(set(column)):
                parts += [value_text(c, v) for v in mine]
        whose = f" ({', '.join(parts)})" if parts else ""
        ax.axvline(kc, color="0.3", ls=CRITICAL_STYLES[n % len(CRITICAL_STYLES)], lw=1,
                   label=f"K_c = {kc:.2f}, one ball{whose}")
