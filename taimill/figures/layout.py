"""Placement rules every taimill figure follows (matplotlib imported on use, as by the
figure modules that import this one): a log axis spans its data (no empty
decades), a legend sits outside the axes (never on the data), a colour bar sits right
beside its map (also beside an equal-aspect map narrower than its layout cell), and
axes with nothing to draw say so in their middle (`nothing`)."""

from __future__ import annotations

import numpy as np

LOG_MARGIN = 10**0.1  # a fitted log axis reaches 0.1 decade beyond its data on each side
LEGEND_GAP = 0.08  # inches between the axes (or what is beside them) and an outside legend
COLORBAR_GAP = 0.06  # inches between a map and its colour bar
COLORBAR_WIDTH = 0.14  # inches


def fit_log(ax, values, axis: str = "x") -> None:
    """Limit a log axis to the positive finite `values` (data units) with LOG_MARGIN;
    unchanged when there are none."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if len(v):
        (ax.set_xlim if axis == "x" else ax.set_ylim)(v.min() / LOG_MARGIN, v.max() * LOG_MARGIN)


def nothing(ax, text: str) -> None:
    """Say on axes that hold no data what is missing (grey, centred), instead of
    drawing zeros or an empty frame that reads as a plotting failure."""
    ax.text(0.5, 0.5, text, ha="center", va="center", color="0.35", transform=ax.transAxes)


VISIBLE = 1e-3  # a density below this share of its curve's peak is indistinguishable from 0 on a linear axis


def occupied(edges: np.ndarray, *hists) -> np.ndarray:
    """The outer edges (lowest, highest) of the bins where any of the histograms `hists`
    (each over `edges`, any leading shape, one curve per row) holds at least VISIBLE of
    its own peak count: the extent of the curves as drawn on equal log bins (a tail of
    a few events in 10⁵, six decades long, is a flat line on the axis); empty if every
    histogram is empty."""
    rows = np.concatenate([np.asarray(h, dtype=float).reshape(-1, len(edges) - 1) for h in hists])
    peak = rows.max(axis=1, keepdims=True)
    full = np.flatnonzero(((rows > 0) & (rows >= VISIBLE * peak)).any(axis=0))
    return np.array([edges[full[0]], edges[full[-1] + 1]]) if len(full) else np.array([])


def legend_outside(ax, *, below: bool = False, gap: float = LEGEND_GAP, **kwargs):
    """The axes' legend outside them: to the right, top-aligned, `gap` inches from the
    axes' right edge (more where a twin axis has its labels there); or, `below`, under
    the axes, centred, `gap` inches under their bottom edge (leave room for the tick
    labels and axis label)."""
    from matplotlib.transforms import ScaledTranslation

    offset = ScaledTranslation(0.0 if below else gap, -gap if below else 0.0, ax.figure.dpi_scale_trans)
    at, loc = ((0.5, 0.0), "upper center") if below else ((1.0, 1.0), "upper left")
    return ax.legend(loc=loc, bbox_to_anchor=at, bbox_transform=ax.transAxes + offset, borderaxespad=0.0, **kwargs)


def colorbar_beside(fig, mappable, ax, label: str, **kwargs):
    """A colour bar as tall as the map `ax` and COLORBAR_GAP inches to its right. It is
    placed in the axes' own coordinates, so it follows the drawn map also where an equal
    aspect leaves the map narrower than its layout cell (a colour bar of the layout
    engine sits at the cell's edge, away from the map)."""
    cax = ax.inset_axes([1.0, 0.0, 1.0, 1.0])
    cax.set_axes_locator(_Beside(ax))
    return fig.colorbar(mappable, cax=cax, label=label, **kwargs)


class _Beside:
    """Axes locator: a strip COLORBAR_WIDTH wide, COLORBAR_GAP right of `ax` as drawn."""

    def __init__(self, ax):
        self.ax = ax

    def __call__(self, cax, renderer):
        from matplotlib.transforms import Bbox

        self.ax.apply_aspect()
        box = self.ax.get_position(original=False)
        w = cax.figure.get_size_inches()[0]
        return Bbox.from_bounds(box.x1 + COLORBAR_GAP / w, box.y0, COLORBAR_WIDTH / w, box.height)
