"""The figure of `taimill advise --figure FILE.png`: the chosen measure against the plate
speed, one curve per friction level μ (the replicas' mean), the replicas' range as a
band, each point marked by its regime class (the replicas' most frequent; colours of
the regime map, taimill.figures.regime_map), the best speed at each μ ringed. Input:
the speed rows of taimill.analysis.advise (with_best)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from taimill.analysis.advise import MEASURES
from taimill.figures.layout import legend_outside
from taimill.figures.regime_map import COLOURS
from taimill.store.output import whole_file

CLASS_MARKERS = {"cascading": "s", "cataracting": "^", "hopping bed": "D", "pinned ring": "o", "sliding bed": ">",
                 "rolling bed": "v", "unknown": "X"}
LEGEND_WIDTH = 2.5  # inches added for the legend outside the panel


def advise_figure(rows: list[dict], subtitle: str = ""):
    """The figure (matplotlib) of the advise speed rows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measure = rows[0]["measure"]
    what, unit, scale = MEASURES[measure]
    mus = sorted({m["mu"] for r in rows for m in r["by_mu"]})
    fig, ax = plt.subplots(figsize=(6.4 + LEGEND_WIDTH, 4.6))
    seen: set[str] = set()
    for n, mu in enumerate(mus):
        pts = [(r["plate_rpm"], m, mu in r["best_at_mu"]) for r in rows for m in r["by_mu"] if m["mu"] == mu]
        x = np.array([p[0] for p in pts], dtype=float)
        mean, lo, hi = (np.array([p[1][f"measure_{k}"] for p in pts], dtype=float) * scale for k in ("mean", "min", "max"))
        color = f"C{n % 10}"
        ax.plot(x, mean, "-", lw=1.5, color=color, label=f"μ {mu:g}")
        if np.any(hi > lo):
            ax.fill_between(x, lo, hi, color=color, alpha=0.2, lw=0)
        for xi, yi, (_, m, best) in zip(x, mean, pts):
            label = m["regime_classes"][0] if m["regime_classes"] else "unknown"
            seen.add(label)
            ax.plot([xi], [yi], CLASS_MARKERS.get(label, "X"), ms=7, mfc=COLOURS.get(label, "#ffffff"), mec=color,
                    mew=1.3, zorder=4)
            if best:  # a ring round the class marker
                ax.plot([xi], [yi], "o", ms=15, mfc="none", mec="k", mew=1.2, zorder=5)
    for label in [c for c in CLASS_MARKERS if c in seen]:
        ax.plot([], [], CLASS_MARKERS[label], ms=7, mfc=COLOURS.get(label, "#ffffff"), mec="0.3", ls="none", label=label)
    ax.plot([], [], "o", ms=12, mfc="none", mec="k", mew=1.2, ls="none", label="best speed at that μ")
    ax.set_xlabel("plate speed Ω (rpm)")
    ax.set_ylabel(f"{what} ({unit})")
    ax.grid(alpha=0.3)
    legend_outside(ax, fontsize=8)
    reps = sorted({m["replicas"] for r in rows for m in r["by_mu"]})
    band = "; band: the replicas' range" if max(reps) > 1 else ""
    title = f"{what[0].upper()}{what[1:]} against plate speed, one curve per friction μ (replicas' mean{band})"
    fig.suptitle(title + (f"\n{subtitle}" if subtitle else ""), fontsize=10)
    fig.tight_layout()
    return fig


def save_advise_figure(rows: list[dict], path, subtitle: str = "") -> Path:
    """Draw advise_figure into `path` (png, svg or pdf), whole or not at all."""
    import matplotlib.pyplot as plt

    fig = advise_figure(rows, subtitle)
    path = Path(path)
    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=120, bbox_inches="tight")
    finally:
        plt.close(fig)
    return path
