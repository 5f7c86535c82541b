"""The (K, μ) regime map of a sweep (docs/regimes.md): each point of the plane coloured
by the charge's motion — cascading, cataracting, hopping bed, pinned ring, sliding bed, rolling bed
(taimill.analysis.regime.map_regime) — with the analytic boundaries drawn over it: the
pinning friction μ_pin(K) of one ball that cannot roll (solid), its large-|K| form
R_p/(K²(R − r)) (dotted), and the single-ball critical ratio K_c (vertical). Contours:
the stress-event power (impact power, W) and the friction power of persistent contacts
(W). One panel per rolling resistance μ_r (and per ball-wall friction where a coated
jar was swept). Replicas are averaged; a cell's regime is its replicas' majority."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from taimill.figures.layout import legend_outside
from taimill.analysis.regime import MAP_REGIMES, map_regime, slip_ratio
from taimill.analysis.theory import critical_ratio, pinning_friction
from taimill.store.output import whole_file

COLOURS = {"cascading": "#9ecae1", "cataracting": "#fdae6b", "hopping bed": "#fee08b", "pinned ring": "#74c476",
           "sliding bed": "#bcbddc", "rolling bed": "#fa9fb5", "unknown": "#ffffff"}
MIN_POWER = 1e-3  #: W, contours start a decade above it
PERSISTENT_FRICTION = tuple(f"dissipated_power_{k}_persistent_friction" for k in ("ball_ball", "side", "floor", "lid"))


def map_cells(rows: list[dict]) -> dict:
    """{(mu_r, K, μ): {regime, impact_power, persistent_friction_power, slip_ratio,
    wall_lag}}, μ being the ball-wall μ_s; replicas averaged, the regime their majority.
    Rows without a wall_lag column (sweep stores written before it) are split by the
    slip ratio alone (map_regime)."""
    groups: dict = {}
    for r in rows:
        key = (round(r.get("mu_r", 0.0), 10), round(r["ratio"], 10), round(r.get("mu_wall", r.get("mu", math.nan)), 10))
        groups.setdefault(key, []).append(r)
    out = {}
    for key, rs in groups.items():
        labels = [map_regime(r.get("regime", ""), slip_ratio(r), _num(r.get("wall_lag")), _num(r.get("flight_fraction")),
                             _num(r.get("impact_chord"))) for r in rs]
        out[key] = {"regime": max(set(labels), key=labels.count),
                    "impact_power": float(np.mean([r.get("impact_power", math.nan) for r in rs])),
                    "persistent_friction_power": float(np.mean([sum(r.get(c, 0.0) for c in PERSISTENT_FRICTION) for r in rs])),
                    "slip_ratio": float(np.mean([slip_ratio(r) for r in rs])),
                    "wall_lag": float(np.mean([_num(r.get("wall_lag")) for r in rs]))}
    return out


def _num(v) -> float:
    return math.nan if v is None else float(v)


def _edges(v: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges halfway between grid values (geometric halfway on a log axis)."""
    x = np.log(v) if log else v
    mid = 0.5 * (x[1:] + x[:-1])
    first = x[0] - (mid[0] - x[0]) if len(x) > 1 else x[0] - 0.5
    last = x[-1] + (x[-1] - mid[-1]) if len(x) > 1 else x[-1] + 0.5
    e = np.concatenate([[first], mid, [last]])
    return np.exp(e) if log else e


def friction_axis_label(rows: list[dict]) -> str:
    """The μ axis is the ball-wall μ_s: named for every contact when each row's
    ball-ball friction equals it (`taimill sweep --mu` sets both), else for the wall."""
    def same(a, b):
        return a is None or b is None or math.isclose(a, b)

    both = all(same(r.get("mu"), r.get("mu_wall")) and same(r.get("mu_d"), r.get("mu_d_wall")) for r in rows)
    return "friction μ of every contact (μ_s = μ_d)" if both else "ball-wall friction μ (μ_s = μ_d)"


def regime_map(rows: list[dict], title: str = ""):
    """The figure (matplotlib) of the sweep rows (taimill sweep table rows)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    cells = map_cells(rows)
    r0 = rows[0]
    Rp, R, r = r0["plate_radius"], r0["jar_radius"], r0["ball_radius"]
    mu_rs = sorted({k[0] for k in cells})
    ylabel = friction_axis_label(rows)
    fig, axes = plt.subplots(1, len(mu_rs), figsize=(6.4 * len(mu_rs), 5.2), squeeze=False)
    names = list(COLOURS)
    cmap = ListedColormap([COLOURS[n] for n in names])
    for ax, mu_r in zip(axes[0], mu_rs):
        ks = np.array(sorted({k[1] for k in cells if k[0] == mu_r}))
        mus = np.array(sorted({k[2] for k in cells if k[0] == mu_r}))
        grid = np.full((len(mus), len(ks)), names.index("unknown"), dtype=float)
        pi = np.full_like(grid, np.nan)
        pf = np.full_like(grid, np.nan)
        for (m_r, k, mu), c in cells.items():
            if m_r != mu_r:
                continue
            i, j = int(np.searchsorted(mus, mu)), int(np.searchsorted(ks, k))
            grid[i, j] = names.index(c["regime"] if c["regime"] in names else "unknown")
            pi[i, j], pf[i, j] = c["impact_power"], c["persistent_friction_power"]
        ax.pcolormesh(_edges(ks, False), _edges(mus, True), grid, cmap=cmap, vmin=-0.5, vmax=len(names) - 0.5,
                      edgecolors="white", linewidth=0.5)
        if len(ks) > 1 and len(mus) > 1:
            kk, mm = np.meshgrid(ks, mus)
            for z, style, colour, label in ((pi, "-", "k", "stress-event power"), (pf, "--", "#7f2704", "persistent friction power")):
                ok = np.isfinite(z) & (z > 0)
                if ok.sum() >= 4 and z[ok].max() / z[ok].min() > 1.5:
                    # decades from 10 mW up, contoured in log10: below 10 mW (creeping contacts,
                    # no contact at all) the power is lumped, so noise there draws no lines
                    lz = np.log10(np.maximum(np.where(ok, z, 0.0), MIN_POWER))
                    levels = [v for v in np.arange(math.log10(MIN_POWER) + 1, np.ceil(lz.max()) + 1) if lz.min() < v < lz.max()]
                    if levels:
                        cs = ax.contour(kk, mm, lz, levels=levels, colors=colour, linestyles=style, linewidths=1)
                        ax.clabel(cs, fmt=lambda v: f"{10 ** v:.2g} W", fontsize=7)
        kc = critical_ratio(Rp, R, r)
        kline = np.linspace(min(ks.min(), kc) - 0.05, kc - 1e-3, 200)
        ax.plot(kline, [pinning_friction(k, Rp, R, r) for k in kline], "k-", lw=2, label="μ_pin(K): one ball held (cannot roll)")
        kfar = np.linspace(ks.min() - 0.05, -0.5, 200)
        ax.plot(kfar, Rp / (kfar**2 * (R - r)), "k:", lw=1.2, label="R_p / (K²(R − r)), large-|K| form")
        ax.axvline(kc, color="r", lw=1.2, label=f"K_c = {kc:.2f}: frictionless ball stays on the wall")
        ax.set_yscale("log")
        ax.set_ylim(_edges(mus, True)[0], _edges(mus, True)[-1])
        ax.set_xlim(_edges(ks, False)[-1], _edges(ks, False)[0])  # K falling to the right, as the thesis draws it
        ax.set_xlabel("K = ω/Ω + 1")
        ax.set_ylabel(ylabel)
        ax.set_title(f"μ_r = {mu_r:g}" if len(mu_rs) > 1 or mu_r else "no rolling resistance", fontsize=10)
        handles = [Patch(color=COLOURS[n], label=n) for n in MAP_REGIMES]
        handles += [plt.Line2D([], [], color="k", ls="-", label="contours: stress-event power"),
                    plt.Line2D([], [], color="#7f2704", ls="--", label="contours: persistent friction power")]
        legend_outside(ax, below=True, gap=0.45, handles=ax.get_legend_handles_labels()[0] + handles, fontsize=7, ncol=2,
                       frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def save_regime_map(rows: list[dict], path, title: str = "") -> Path:
    path = Path(path)
    fig = regime_map(rows, title)
    import matplotlib.pyplot as plt

    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=130, bbox_inches="tight")  # the legends under the maps too
    finally:
        plt.close(fig)
    return path
