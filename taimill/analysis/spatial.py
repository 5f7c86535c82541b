"""Where things happen: the cylindrical distribution function g(r) and randomness
index (thesis eq 3.9), the ball–jar contact map, and the wear map (new: energy the
walls receive per unit area). NumPy only; accumulators take blocks of the stream."""

from __future__ import annotations

import math

import numpy as np

from taimill.analysis.rungeometry import FLOOR, LID, SIDE, RunGeometry, accessible_area

G_BINS = 20

MAX_CELLS = 256  # wall-map cells across the jar's diameter or height at most


class RadialDensity:
    """g(r), eq 3.9: the time-averaged density of ball centres in cylindrical shells
    about the jar axis, normalised so that a uniform density over the region a centre
    can reach gives g ≡ 1. In a non-circular jar each shell's area is only its part
    inside that region (the thesis' 2π h r Δr is the circular case). The randomness
    index is 1/σ with σ the variance of the g histogram (thesis §3.2.3): larger = more
    uniform, more random motion. A centre pressed into the side wall lies beyond R − r
    by its contact overlap (µm); it counts in the last shell."""

    def __init__(self, g: RunGeometry, t0: float = 0.0, bins: int = G_BINS):
        self.t0 = t0
        self.edges = np.linspace(0.0, g.jar_radius - g.ball_radius, bins + 1)
        self.area = accessible_area(g, self.edges)
        self.hist = np.zeros(bins)

    def add(self, block: dict) -> None:
        x = block["position"][block["time"] >= self.t0]
        rho = np.minimum(np.hypot(x[..., 0], x[..., 1]).ravel(), self.edges[-1])
        self.hist += np.histogram(rho, bins=self.edges)[0]

    @property
    def g(self) -> np.ndarray:
        total = self.hist.sum()
        ok = self.area > 0
        out = np.full(len(self.hist), np.nan)
        if total:
            out[ok] = (self.hist[ok] / total) / (self.area[ok] / self.area[ok].sum())
        return out

    @property
    def randomness_index(self) -> float:
        g = self.g
        g = g[np.isfinite(g)]
        if len(g) == 0:
            return math.nan
        var = float(np.var(g))
        return 1.0 / var if var > 0 else math.inf


class WallMap:
    """Energy the jar walls receive, per unit area, over the window t0 ≤ t_start < t1 (s): the
    side wall unrolled (arc length × height) and the floor and lid (x × y).

    Two layers: `impact` (normal stress energy ½ m u̇_n² of ball–wall events, J) and
    `friction` (friction work of those events, J — an Archard-type wear indicator:
    abrasive wear volume ∝ sliding work). Divided by cell area and window length they
    are W/m². Every wall event lands in exactly one cell, so Σ map · area = energy."""

    def __init__(self, g: RunGeometry, t0: float = 0.0, cell: float | None = None, t1: float = math.inf):
        self.geom, self.t0, self.t1 = g, t0, t1
        # a third of a ball radius, but at most MAX_CELLS across the jar (small beads in a
        # large jar: a finer map is unreadable and its set-up grows with the cell count)
        cell = cell or max(g.ball_radius / 3.0, 1e-4, 2.0 * g.jar_radius / MAX_CELLS, g.height / MAX_CELLS)
        ns = max(8, int(round(g.perimeter / cell)))
        nz = max(2, int(round(g.height / cell)))
        self.s_edges = np.linspace(0.0, g.perimeter, ns + 1)
        self.z_edges = np.linspace(0.0, g.height, nz + 1)
        R = g.jar_radius
        nxy = max(4, int(round(2 * R / cell)))
        self.xy_edges = np.linspace(-R, R, nxy + 1)
        self.side_area = np.outer(np.diff(self.s_edges), np.diff(self.z_edges))
        self.disc_area = _inside_area(g, self.xy_edges)
        self.layers = {name: {"side": np.zeros((ns, nz)), "floor": np.zeros((nxy, nxy)), "lid": np.zeros((nxy, nxy))}
                       for name in ("impact", "friction")}
        self.count = {"side": np.zeros((ns, nz), np.int64), "floor": np.zeros((nxy, nxy), np.int64),
                      "lid": np.zeros((nxy, nxy), np.int64)}

    def add(self, block: dict) -> None:
        sel = (block["kind"] == 1) & (block["t_start"] >= self.t0) & (block["t_start"] < self.t1)
        j = block["body_j"][sel]
        x, y, z = block["x"][sel], block["y"][sel], block["z"][sel]
        weights = {"impact": block["se_n"][sel], "friction": block["dissipated_friction"][sel]}
        side = j == SIDE
        s = self.geom.arc_length(np.column_stack([x[side], y[side]]))
        zs = np.clip(z[side], self.z_edges[0], self.z_edges[-1])
        self.count["side"] += np.histogram2d(s, zs, bins=(self.s_edges, self.z_edges))[0].astype(np.int64)
        for name, w in weights.items():
            self.layers[name]["side"] += np.histogram2d(s, zs, bins=(self.s_edges, self.z_edges), weights=w[side])[0]
        lim = self.xy_edges[-1]
        for surface, code in (("floor", FLOOR), ("lid", LID)):
            on = j == code
            xs, ys = np.clip(x[on], -lim, lim), np.clip(y[on], -lim, lim)
            self.count[surface] += np.histogram2d(xs, ys, bins=(self.xy_edges, self.xy_edges))[0].astype(np.int64)
            for name, w in weights.items():
                self.layers[name][surface] += np.histogram2d(xs, ys, bins=(self.xy_edges, self.xy_edges), weights=w[on])[0]

    def area(self, surface: str) -> np.ndarray:
        return self.side_area if surface == "side" else self.disc_area

    def density(self, layer: str, surface: str, tau: float) -> np.ndarray:
        """W/m² per cell (energy / area / window length); NaN outside the jar."""
        a = self.area(surface)
        with np.errstate(invalid="ignore", divide="ignore"):
            d = self.layers[layer][surface] / a / tau
        return np.where(a > 0, d, np.nan)

    def total(self, layer: str) -> float:
        return float(sum(v.sum() for v in self.layers[layer].values()))

    def hot_spot(self, tau: float, layer: str = "both") -> dict:
        """The cell receiving most power per area (W/m²), where it is, and how many
        times the wall's mean it is (the concentration)."""
        best, where = -1.0, None
        for surface in ("side", "floor", "lid"):
            if layer == "both":
                d = self.density("impact", surface, tau) + self.density("friction", surface, tau)
            else:
                d = self.density(layer, surface, tau)
            if np.all(~np.isfinite(d)):
                continue
            k = np.unravel_index(np.nanargmax(d), d.shape)
            if d[k] > best:
                best, where = float(d[k]), (surface, k)
        total_area = self.side_area.sum() + 2 * self.disc_area.sum()
        energy = self.total("impact") + self.total("friction") if layer == "both" else self.total(layer)
        mean = energy / total_area / tau if tau > 0 else math.nan
        if where is None or best <= 0:
            return {"surface": None, "power_per_area": 0.0, "concentration": math.nan}
        surface, (a, b) = where
        out = {"surface": surface, "power_per_area": best, "concentration": best / mean if mean > 0 else math.nan}
        if surface == "side":
            s = 0.5 * (self.s_edges[a] + self.s_edges[a + 1])
            out.update(arc_length=float(s), angle_deg=float(self.geom.wall_angle(s)),
                       z=float(0.5 * (self.z_edges[b] + self.z_edges[b + 1])))
        else:
            xc, yc = (0.5 * (self.xy_edges[i] + self.xy_edges[i + 1]) for i in (a, b))
            out.update(x=float(xc), y=float(yc), angle_deg=float(math.degrees(math.atan2(yc, xc))))
        return out


def _inside_area(g: RunGeometry, edges: np.ndarray, sub: int = 6) -> np.ndarray:
    """Area (m²) of each square cell of the floor/lid grid inside the jar profile: the
    share of sub × sub sample points with φ ≥ 0. φ is a distance (1-Lipschitz), so a
    cell whose centre lies farther from the wall than its half-diagonal (with a margin
    far above rounding) has every sample on the centre's side: only the cells the wall
    crosses are sampled (the same counts; 256² cells: 2.4 M SDF points → ≈ 0.1 M)."""
    n, h = len(edges) - 1, edges[1] - edges[0]
    u = (np.arange(n * sub) + 0.5) * h / sub + edges[0]
    mid = 0.5 * (edges[:-1] + edges[1:])
    cx, cy = np.meshgrid(mid, mid, indexing="ij")
    phi_c, _ = g.sdf(np.column_stack([cx.ravel(), cy.ravel()]))
    reach = h * math.sqrt(0.5) * (1.0 + 1e-6) + 1e-12 * (abs(edges[0]) + abs(edges[-1]))
    counts = np.where(phi_c > reach, float(sub * sub), 0.0)
    cross = np.flatnonzero(np.abs(phi_c) <= reach)
    rows = max(1, (1 << 16) // (sub * sub))  # cells per SDF call: bounded memory
    for a in range(0, len(cross), rows):
        ia, ib = np.divmod(cross[a:a + rows], n)
        k = np.arange(sub)
        xs = u[(ia * sub)[:, None, None] + k[None, :, None]]  # (cells, sub, 1)
        ys = u[(ib * sub)[:, None, None] + k[None, None, :]]  # (cells, 1, sub)
        xs, ys = np.broadcast_arrays(xs, ys)
        phi, _ = g.sdf(np.column_stack([xs.ravel(), ys.ravel()]))
        counts[cross[a:a + rows]] = (phi >= 0).reshape(-1, sub * sub).sum(axis=1)
    return counts.reshape(n, n) * (h / sub) ** 2


def contact_map(g: RunGeometry, events: dict, t0: float = 0.0) -> dict:
    """Ball–jar impact points (Figs 4.10/4.16): for side-wall events the unrolled
    position (arc length, z; m) and polar angle (deg), for floor/lid events x, y (m),
    each with its onset normal speed u̇_n (m/s) and normal stress energy (J)."""
    sel = (events["kind"] == 1) & (events["t_start"] >= t0)
    out = {}
    for surface, code in (("side", SIDE), ("floor", FLOOR), ("lid", LID)):
        on = sel & (events["body_j"] == code)
        x, y = events["x"][on], events["y"][on]
        d = {"x": x, "y": y, "z": events["z"][on], "un": events["un"][on], "se_n": events["se_n"][on]}
        if surface == "side":
            d["arc_length"] = g.arc_length(np.column_stack([x, y]))
            d["angle_deg"] = np.degrees(np.arctan2(y, x))
        out[surface] = d
    return out
