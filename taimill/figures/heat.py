"""The heat figure (docs/outcome.md, "Heat"): the temperatures of balls, powder and jar
over the mill programme, the powder's limit and measured temperatures. Drawing only:
the curves come from taimill.outcome.thermal."""

from __future__ import annotations

import numpy as np

from taimill.figures.kinetics import _save

COLOURS = {"balls": "C3", "powder": "C1", "jar": "C0", "ball": "C3"}


def heat_figure(path, times_s, temps_c: dict, limit_c=None, measured=None, title: str = ""):
    """`temps_c`: node -> °C at `times_s`; `measured`: (time_s, °C, what) rows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    minutes = np.asarray(times_s) / 60.0
    for name, t in temps_c.items():
        ax.plot(minutes, t, "--" if name == "powder" else "-", color=COLOURS.get(name, "k"), label=name)
    if limit_c is not None:
        ax.axhline(limit_c, color="grey", ls=":", lw=1, label=f"limit {limit_c:g} °C")
    if measured:
        for what in dict.fromkeys(r[2] for r in measured):
            rows = [r for r in measured if r[2] == what]
            ax.plot([r[0] / 60 for r in rows], [r[1] for r in rows], "o", mfc="none",
                    color=COLOURS.get(what, "k"), label=f"{what} (measured)")
    ax.set(xlabel="time (min)", ylabel="temperature (°C)", title=title)
    ax.legend(fontsize=7)
    return _save(fig, path)
