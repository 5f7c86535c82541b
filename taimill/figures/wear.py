"""The wall wear-depth map (docs/wear.md): µm per hour on the side wall (unrolled) and
on the floor and lid, the wear map's cells; cells with fewer than MIN_EVENTS events
are grey (their depth is counting noise), the deepest named with its counting error.
Drawing only: the depths come from taimill.outcome.wear.depth_map."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from taimill.store.output import whole_file

MM = 1e3


def depth_figure(path, wall_map, maps: dict, title: str) -> Path:
    """`maps`: surface -> (µm/h per cell, relative counting error per cell)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    from taimill.analysis.spatial import MIN_EVENTS

    shown = {s: np.where((wall_map.count[s] >= MIN_EVENTS) & (d > 0), d, np.nan) for s, (d, _) in maps.items()}
    vals = np.concatenate([v[np.isfinite(v)] for v in shown.values()])
    norm = LogNorm(vmin=vals.min(), vmax=vals.max()) if len(vals) else None
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), gridspec_kw={"width_ratios": [2.2, 1, 1]}, layout="constrained")
    outline = np.vstack([wall_map.geom.profile.outline, wall_map.geom.profile.outline[:1]]) * MM
    im = None
    for ax, s in zip(axes, ("side", "floor", "lid")):
        xe, ye = (wall_map.s_edges, wall_map.z_edges) if s == "side" else (wall_map.xy_edges, wall_map.xy_edges)
        inside = wall_map.area(s) > 0
        grey = np.ma.masked_where(~(inside & ~np.isfinite(shown[s])).T, np.ones(inside.T.shape))
        ax.pcolormesh(xe * MM, ye * MM, grey, cmap="Greys", vmin=0, vmax=5)
        im = ax.pcolormesh(xe * MM, ye * MM, np.ma.masked_invalid(shown[s].T), norm=norm, cmap="inferno")
        depth, rel = maps[s]
        ok = np.isfinite(shown[s])
        if ok.any():
            i = np.unravel_index(int(np.nanargmax(np.where(ok, depth, np.nan))), depth.shape)
            ax.plot((xe[i[0]] + xe[i[0] + 1]) / 2 * MM, (ye[i[1]] + ye[i[1] + 1]) / 2 * MM, "+", color="c", ms=12,
                    mew=2)
            ax.set_title(f"{s}: deepest {depth[i]:.3g} µm/h ± {100 * rel[i]:.0f} %", fontsize=9)
        else:
            ax.set_title(f"{s}: no cell with {MIN_EVENTS} events", fontsize=9)
        if s == "side":
            ax.set(xlabel="arc length along the wall (mm)", ylabel="z (mm)")
        else:
            ax.plot(outline[:, 0], outline[:, 1], color="0.2", lw=1.2)
            ax.set(xlabel="x (mm)", ylabel="y (mm)", aspect="equal")
    if norm is not None and im is not None:
        fig.colorbar(im, ax=list(axes), label="wear depth (µm/h)", shrink=0.85)
    fig.suptitle(f"{title}; grey: fewer than {MIN_EVENTS} events a cell", fontsize=10)
    path = Path(path)
    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=150)
    finally:
        plt.close(fig)
    return path
