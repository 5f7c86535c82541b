"""The energy spectra of runs or sweep points, overlaid (taimill.model.spectra;
docs/outcome.md): for each energy measure, collisions per second per decade of energy
(mJ), stress events solid and every contact dotted. Axes span the bins that hold
events; events below 1 pJ (those that dissipated nothing, say) are not drawn. A panel
without an event of 1 pJ or more (a charge at rest, or the normal damper's share of a
friction-led charge) says so on linear axes: a log axis has no range without data."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from taimill.analysis.spectra import LOG_HI, LOG_LO, selected  # noqa: E402
from taimill.figures.layout import nothing  # noqa: E402
from taimill.model.spectra import MEASURES, Spectra  # noqa: E402

MJ = 1e3
TITLES = {"dissipated_normal": "dissipated by the normal damper", "dissipated_friction": "dissipated by friction (shear)",
          "se_normal": "kinematic stress energy, normal ½ m_e u̇n²", "se_tangential": "kinematic stress energy, tangential ½ m_e u̇t²"}


def rate_density(sp: Spectra, measure: str, stress_only: bool) -> np.ndarray:
    """Events per second per decade of energy, per bin."""
    count, _ = selected(sp, measure, None, stress_only)
    return count / max(sp.seconds, 1e-300) / (LOG_HI - LOG_LO)


def draw_measure(ax, items: list[tuple[str, Spectra]], measure: str) -> None:
    centres = 10 ** (0.5 * (LOG_LO + LOG_HI)) * MJ
    used = np.zeros(len(centres), dtype=bool)
    for k, (label, sp) in enumerate(items):
        colour = f"C{k % 10}"
        for stress_only, ls in ((True, "-"), (False, ":")):
            y = rate_density(sp, measure, stress_only)
            y[0] = 0.0  # below 1 pJ, zero included (an event without damping or slip): not drawn
            used |= y > 0
            ax.step(centres, np.where(y > 0, y, np.nan), where="mid", color=colour, ls=ls,
                    label=label if stress_only else None)
    ax.set(xlabel="energy per event (mJ)", ylabel="events per second per decade", title=TITLES[measure])
    ax.title.set_fontsize(9)
    if used.any():
        ax.set(xscale="log", yscale="log")
        idx = np.flatnonzero(used)
        ax.set_xlim(10 ** LOG_LO[idx[0]] * MJ, 10 ** LOG_HI[idx[-1]] * MJ)
    else:
        ax.set(xticks=[], yticks=[])
        nothing(ax, "no event of 1 pJ (10⁻⁹ mJ) or more")  # LOG_HI[0]: the lowest bin's upper edge


def drawn(sp: Spectra) -> bool:
    """Whether the spectra hold anything spectra_figure draws: an event of 1 pJ or more."""
    return bool(sp.count[..., 1:].any())


def spectra_figure(items: list[tuple[str, Spectra]], title: str = ""):
    """A 2 × 2 figure, one panel per measure, one colour per run or point."""
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), layout="constrained")
    for ax, measure in zip(axes.flat, MEASURES):
        draw_measure(ax, items, measure)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    handles.append(plt.Line2D([], [], color="grey", ls=":"))
    labels.append("every contact (dotted); solid: stress events")
    fig.legend(handles, labels, loc="outside lower center", ncols=min(4, len(labels)), fontsize=8)
    start = min(sp.start for _, sp in items) if items else math.nan
    fig.suptitle(title or f"Energy spectra of the collision events (from t = {start:g} s)", fontsize=11)
    return fig
