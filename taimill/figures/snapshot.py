"""The live mill's current figures as a PNG (the TUI's key g): the jar from above and
in section with the balls, the history of the window figures, and the readouts. Matplotlib's object API
with the Agg canvas, so it can run in a worker thread without a display."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from taimill.store.output import whole_file

MM = 1e3


def save_png(path: Path, *, title: str, outline: np.ndarray, height: float, position: np.ndarray,
             radius: np.ndarray, psi: float | None, history: dict, series: dict, readouts: list[str],
             time: float, window: float) -> Path:
    """Write the figure; lengths in m, times in s; history: readout series with their
    window ends `sim_seconds`, drawn as `series` says (key -> (label, unit, scale));
    readouts: lines of text. Returns path."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    fig = Figure(figsize=(12, 7.5), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 3, width_ratios=[1.2, 1.0, 1.0], height_ratios=[2.2, 1, 1])
    top, side = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[1:, 0])
    closed = np.vstack([outline, outline[:1]]) * MM
    top.plot(closed[:, 0], closed[:, 1], color="0.3", lw=1.2)
    x0, x1 = outline[:, 0].min() * MM, outline[:, 0].max() * MM
    side.plot([x0, x0, x1, x1, x0], [height * MM, 0, 0, height * MM, height * MM], color="0.3", lw=1.2)
    for p, r in zip(position * MM, radius * MM):
        top.add_patch(Circle((p[0], p[1]), r, color="goldenrod", alpha=0.85))
        side.add_patch(Circle((p[0], p[2]), r, color="goldenrod", alpha=0.85))
    if psi is not None:
        R = float(np.hypot(*outline.T).max()) * MM
        top.annotate("", xy=(1.12 * R * math.cos(psi), 1.12 * R * math.sin(psi)), xytext=(0.95 * R * math.cos(psi), 0.95 * R * math.sin(psi)),
                     arrowprops={"arrowstyle": "->", "color": "firebrick"})
    top.set(aspect="equal", xlabel="x (mm)", ylabel="y (mm)", title=f"jar frame from above, t = {time:.3f} s")
    side.set(aspect="equal", xlabel="x (mm)", ylabel="z (mm)", title="section x-z")
    for ax in (top, side):
        ax.autoscale_view()

    cells = [grid[0, 1], grid[0, 2], grid[1, 1], grid[1, 2]]
    for cell, (key, (label, unit, scale)) in zip(cells, series.items()):
        ax = fig.add_subplot(cell)
        ax.plot(history.get("sim_seconds", []), np.asarray(history.get(key, []), float) * scale, ".-", color="C0")
        ax.set(title=f"{label} ({unit}), window {window:g} s", xlabel="simulated time at the window's end (s)")
    text = fig.add_subplot(grid[2, 1:])
    text.axis("off")
    text.text(0.0, 1.0, "\n".join(readouts), family="monospace", va="top", fontsize=9)
    fig.suptitle(title)
    with whole_file(path, "PNG snapshot") as part:
        fig.savefig(part, dpi=100)
    return path
