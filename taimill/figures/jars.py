"""Drawings of jar cross-sections (`taimill jars show`): the filleted outline piece by
piece, and the signed-distance field φ the wall contacts use. Matplotlib is imported
inside `draw_jar` with the headless Agg backend, so importing this module is cheap."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from taimill.model import geometry
from taimill.store.output import whole_file

MM = 1e3  # m → mm
GRID = 301  # SDF samples per side


def jar_row(jar, cy_volume: float | None = None) -> dict:
    """One jar's numbers for the `jars` table / JSON (mm², ml, mm)."""
    return {
        "name": jar.name,
        "area_mm2": jar.area * 1e6,
        "volume_ml": jar.volume * 1e6,
        "ratio_to_CY": jar.volume / cy_volume if cy_volume else None,
        "pieces": len(jar.profile.pieces),
        "fillet_mm": jar.fillet * MM,
        "height_mm": round(jar.height * MM, 9),
        "description": jar.description,
    }


def _piece_points(row, n=200):
    """(n, 2) points along one boundary piece (m)."""
    if row[0] == geometry.LINE:
        return np.linspace(row[1:3], row[3:5], n)
    c, rho, m, cos_h = row[1:3], row[3], row[5:7], row[7]
    mid, half = math.atan2(m[1], m[0]), math.acos(np.clip(cos_h, -1.0, 1.0))
    t = np.linspace(mid - half, mid + half, n)
    return np.column_stack([c[0] + rho * np.cos(t), c[1] + rho * np.sin(t)])


def _is_fillet(row, jar) -> bool:
    return row[0] == geometry.ARC and jar.fillet > 0 and abs(row[3] - jar.fillet) < 1e-9 and row[4] > 0


def draw_jar(jar, path) -> Path:
    """Two panels (outline; φ field) of `jar`'s cross-section, saved to `path` (.png/.svg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    path = Path(path)
    prof = jar.profile
    R = prof.bounding_radius * MM
    lim = 1.15 * R
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 5.6), constrained_layout=True)
    fig.suptitle(f"{jar.name} — {jar.description}\narea {jar.area * 1e6:.1f} mm², "
                 f"volume {jar.volume * 1e6:.1f} ml (height {jar.height * MM:g} mm), "
                 f"{len(prof.pieces)} boundary piece(s), fillet {jar.fillet * MM:g} mm")

    # ---- left: the boundary, piece by piece
    out = np.vstack([prof.outline, prof.outline[:1]]) * MM
    ax0.fill(out[:, 0], out[:, 1], color="0.93", zorder=0)
    styles = {"wall arc": dict(color="tab:blue", lw=2.2), "flat wall": dict(color="tab:green", lw=2.2),
              "lifter": dict(color="tab:purple", lw=2.2), "fillet": dict(color="tab:red", lw=3.0)}
    seen = set()
    for row in prof.pieces:
        if _is_fillet(row, jar):
            kind = "fillet"
        elif row[0] == geometry.LINE:
            kind = "flat wall"
        else:
            kind = "wall arc" if row[4] > 0 else "lifter"
        xy = _piece_points(row) * MM
        ax0.plot(xy[:, 0], xy[:, 1], **styles[kind], label=None if kind in seen else kind, zorder=2)
        seen.add(kind)
        if kind == "fillet":
            ax0.plot(row[1] * MM, row[2] * MM, "+", color="tab:red", ms=6, zorder=3)
    if len(prof.pieces) > 1:  # tangent points where pieces meet
        ends = np.array([_piece_points(r, 2)[[0, -1]] for r in prof.pieces]).reshape(-1, 2) * MM
        ax0.plot(ends[:, 0], ends[:, 1], "o", color="k", ms=3, zorder=4, label="tangent points")
    ax0.axhline(0, color="0.6", lw=0.6, ls="--", zorder=1)
    ax0.axvline(0, color="0.6", lw=0.6, ls="--", zorder=1)
    ax0.plot(0, 0, marker="x", color="k", ms=9, mew=2, zorder=5, label="jar axis")
    ax0.set(xlim=(-lim, lim), ylim=(-lim, lim), xlabel="x (mm)", ylabel="y (mm)",
            title="cross-section (fillet centres +)")
    ax0.set_aspect("equal")
    ax0.grid(alpha=0.3)
    ax0.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=5, fontsize=8, frameon=False)

    # ---- right: the signed distance field
    g = np.linspace(-lim, lim, GRID)
    X, Y = np.meshgrid(g, g)
    phi, _ = geometry.profile_sdf(prof, np.column_stack([X.ravel(), Y.ravel()]) / MM)
    Z = phi.reshape(X.shape) * MM
    norm = TwoSlopeNorm(vcenter=0.0, vmin=min(Z.min(), -1e-3), vmax=max(Z.max(), 1e-3))
    cf = ax1.contourf(X, Y, Z, levels=40, cmap="RdBu_r", norm=norm)
    cf.set_rasterized(True)  # keeps an .svg small; outlines stay vector
    ax1.contour(X, Y, Z, levels=np.arange(5, Z.max(), 5), colors="k", linewidths=0.4, alpha=0.4)
    ax1.contour(X, Y, Z, levels=[0.0], colors="k", linewidths=2.0)
    ax1.plot(0, 0, marker="x", color="k", ms=9, mew=2)
    ax1.set(xlim=(-lim, lim), ylim=(-lim, lim), xlabel="x (mm)", ylabel="y (mm)",
            title="signed distance φ (zero contour = wall, lines every 5 mm)")
    ax1.set_aspect("equal")
    fig.colorbar(cf, ax=ax1, label="φ (mm), positive inside", shrink=0.9)

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=110)
    finally:
        plt.close(fig)
    return path
