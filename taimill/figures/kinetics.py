"""The outcome figure (docs/outcome.md): measured points, fitted curves and predicted
curves against milling time, each curve with its band, one colour per condition (PNG
or SVG by the file's suffix). Drawing only: the curves come from
taimill.outcome.predict. Matplotlib is imported inside with the headless Agg backend."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from taimill.store.output import whole_file


def outcome_figure(path, curves: list[dict], points: dict | None = None, target: float | None = None,
                   ylabel: str = "value", title: str = "") -> Path:
    """`curves`: {"label", "kind" ("fitted" or "predicted"), "time_s", "value",
    "lower", "upper"} each; `points`: label -> (time_s, value, sigma or None), drawn
    in the colour of the curve of the same label; `target`: a horizontal line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    colour = {}
    for i, c in enumerate(curves):
        col = colour.setdefault(c["label"], f"C{len(colour) % 10}")
        minutes = np.asarray(c["time_s"]) / 60.0
        style = "-" if c["kind"] == "fitted" else "--"
        ax.plot(minutes, c["value"], style, color=col, label=f"{c['label']} ({c['kind']})")
        ax.fill_between(minutes, c["lower"], c["upper"], color=col, alpha=0.15, lw=0)
    for label, (t, y, s) in (points or {}).items():
        col = colour.setdefault(label, f"C{len(colour) % 10}")
        ax.errorbar(np.asarray(t) / 60.0, y, yerr=None if s is None else 2 * np.asarray(s), fmt="o", color=col,
                    capsize=3, label=f"{label} (measured{', ±2σ' if s is not None else ''})")
    if target is not None:
        ax.axhline(target, color="grey", lw=0.8, ls=":", label=f"target {target:g}")
    ax.set(xlabel="milling time (min)", ylabel=ylabel, title=title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = Path(path)
    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=150)
    finally:
        plt.close(fig)
    return path


def stress_model_figure(path, rows: list[dict], ylabel: str = "value", title: str = "") -> Path:
    """The stress-model plot (Kwade): the measured quantity against the stress number
    (events at or above the threshold per gram), one marker colour per condition, its
    mean stress energy in the legend. `rows`: taimill.outcome.models.stress_model_points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for i, c in enumerate(dict.fromkeys(r["condition"] for r in rows)):
        mine = [r for r in rows if r["condition"] == c]
        se = mine[0]["stress_energy_J"]
        ax.plot([r["stress_number_per_g"] for r in mine], [r["value"] for r in mine], "o", color=f"C{i % 10}",
                label=f"{c}: mean SE {se * 1e3:.3g} mJ")
    ax.set(xscale="log", xlabel="stress number SN (events ≥ threshold per g)", ylabel=ylabel, title=title)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = Path(path)
    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=150)
    finally:
        plt.close(fig)
    return path
