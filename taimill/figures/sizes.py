"""The particle size figure (docs/outcome.md, "Particle sizes"): per condition its
cumulative distributions over milling time (measured points on them), then x50 and
x90 against time with their bands, and the selection rate against size of the impact
and attrition routes. Drawing only: the numbers come from taimill.outcome.sizes_fit.
Matplotlib is imported inside with the headless Agg backend."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from taimill.figures.kinetics import _save

PANELS = ("cumulative distribution", "x50 and x90 against milling time", "selection rate against size")


def sizes_figure(path, rows: list[dict], measured: dict | None = None, target_m: float | None = None,
                 title: str = "") -> list[str]:
    """`rows`: {"label", "edges_m", "times_s", "passing" (a row per time, a column per
    edge), "curve": {"time_s", "x50": (value, lower, upper), "x90": (…)}, "impact",
    "attrition" (1/s per class), "sizes_m" (each class's size)} each; `measured`: label
    -> [(time_s, sizes_m, passing)], drawn on that condition's panel and as x50, x90
    points; `target_m`: a target x90. Returns the panels' titles, in drawing order."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measured = measured or {}
    n = len(rows)
    cols = max(n, 2)
    fig = plt.figure(figsize=(3.6 * cols, 7.5))
    grid = fig.add_gridspec(2, 2 * cols)
    titles = []
    for i, r in enumerate(rows):
        ax = fig.add_subplot(grid[0, 2 * i:2 * i + 2])
        times = np.asarray(r["times_s"], dtype=float)
        cmap = plt.get_cmap("viridis")
        for k, (t, q) in enumerate(zip(times, r["passing"])):
            col = cmap(k / max(len(times) - 1, 1))
            ax.plot(np.asarray(r["edges_m"]) * 1e6, 100 * np.asarray(q), "-", color=col, label=f"{t / 3600:.3g} h")
            for tm, x, qm in measured.get(r["label"], []):
                if abs(tm - t) <= 1e-9 * max(t, 1.0):
                    ax.plot(np.asarray(x) * 1e6, 100 * np.asarray(qm), "o", ms=3, color=col)
        titles.append(f"{r['label']}: {PANELS[0]}")
        ax.set(xscale="log", xlabel="size (µm)", ylabel="passing (%)", ylim=(0, 100),
               title="\n".join(textwrap.wrap(titles[-1], 45)))
        ax.title.set_fontsize(8)
        ax.legend(fontsize=6, title="time (lines: model, dots: measured)" if measured else "time", title_fontsize=6)
    ax = fig.add_subplot(grid[1, :cols])
    for i, r in enumerate(rows):
        c = r["curve"]
        hours = np.asarray(c["time_s"], dtype=float) / 3600
        for name, style in (("x50", "--"), ("x90", "-")):
            v, lo, hi = (np.asarray(a, dtype=float) * 1e6 for a in c[name])
            ax.plot(hours, v, style, color=f"C{i % 10}", label=f"{r['label']} {name}")
            ax.fill_between(hours, lo, hi, color=f"C{i % 10}", alpha=0.15, lw=0)
        for tm, x, qm in measured.get(r["label"], []):
            for share, marker in ((0.5, "s"), (0.9, "o")):
                if qm[0] <= share <= qm[-1]:
                    ax.plot(tm / 3600, np.exp(np.interp(share, qm, np.log(x))) * 1e6, marker, ms=4, color=f"C{i % 10}",
                            mfc="none")
    if target_m is not None:
        ax.axhline(target_m * 1e6, color="grey", lw=0.8, ls=":", label=f"target x90 {target_m * 1e6:g} µm")
    titles.append(PANELS[1])
    ax.set(yscale="log", xlabel="milling time (h)", ylabel="size (µm)", title=titles[-1])
    ax.legend(fontsize=6)
    ax = fig.add_subplot(grid[1, cols:])
    for i, r in enumerate(rows):
        x = np.asarray(r["sizes_m"])[:-1] * 1e6  # the sink does not break
        for route, style in (("impact", "-"), ("attrition", "--")):
            s = np.asarray(r[route])[:-1] * 3600
            if np.any(s > 0):
                ax.plot(x, np.where(s > 0, s, np.nan), style, color=f"C{i % 10}", label=f"{r['label']} {route}")
    titles.append(PANELS[2])
    ax.set(xscale="log", yscale="log", xlabel="size (µm)", ylabel="selection rate S (1/h)", title=titles[-1])
    if ax.lines:
        ax.legend(fontsize=6)
    if title:
        fig.suptitle(title, fontsize=9)
    _save(fig, Path(path))
    return titles
