"""Where things happen: the cylindrical distribution function g(r) and randomness
index (thesis eq 3.9), the ball–jar contact map, and the wear map (new: energy the
walls receive per unit area). NumPy only; accumulators take blocks of the stream."""

from __future__ import annotations

import math

import numpy as np

from taimill.analysis.rungeometry import FLOOR, LID, SIDE, RunGeometry, accessible_area

G_BINS = 20

MAX_CELLS = 256  # wall-map cells across the jar's diameter or height at most

# A wall-map cell with fewer events than MIN_EVENTS is greyed in the wear map and cannot
# be a hot spot: with 10 events its power per area is uncertain by ≥ 1/√10 ≈ 32 % even
# if every event carried the same energy. A hot spot must exceed the rest of its band by
# SPOT_FACTOR and by SPOT_SIGMAS standard errors (WallMap.hot_spot): the factor keeps a
# well-sampled uniform band (CY steel, 24 s: ≈ 56 events a cell in its hottest row, the
# largest cell 1.6× the row's mean) from naming its largest cell; the standard errors
# keep a cell of a few large impacts from it. 4 standard errors: among the ≈ 3000 cells
# of a map, a Gaussian fluctuation that large is expected less than once in ten maps.
# A band without a hot spot is called uniform around the wall only when at least
# UNIFORM_SHARE of its cells hold MIN_EVENTS events: in a short window most cells are too
# sparse for any to stand out, which says nothing about uniformity.
MIN_EVENTS = 10
SPOT_FACTOR = 2.0
SPOT_SIGMAS = 4.0
UNIFORM_SHARE = 0.9


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
        self.squares = {name: {"side": np.zeros((ns, nz)), "floor": np.zeros((nxy, nxy)), "lid": np.zeros((nxy, nxy))}
                        for name in ("impact", "friction", "both")}  # Σ e² per cell (J²): standard errors
        self.count = {"side": np.zeros((ns, nz), np.int64), "floor": np.zeros((nxy, nxy), np.int64),
                      "lid": np.zeros((nxy, nxy), np.int64)}

    def add(self, block: dict) -> None:
        sel = (block["kind"] == 1) & (block["t_start"] >= self.t0) & (block["t_start"] < self.t1)
        j = block["body_j"][sel]
        x, y, z = block["x"][sel], block["y"][sel], block["z"][sel]
        weights = {"impact": block["se_n"][sel], "friction": block["dissipated_friction"][sel]}
        weights["both"] = weights["impact"] + weights["friction"]
        side = j == SIDE
        s = self.geom.arc_length(np.column_stack([x[side], y[side]]))
        zs = np.clip(z[side], self.z_edges[0], self.z_edges[-1])
        self.count["side"] += np.histogram2d(s, zs, bins=(self.s_edges, self.z_edges))[0].astype(np.int64)
        for name, w in weights.items():
            sq = np.histogram2d(s, zs, bins=(self.s_edges, self.z_edges), weights=w[side] ** 2)[0]
            self.squares[name]["side"] += sq
            if name in self.layers:
                self.layers[name]["side"] += np.histogram2d(s, zs, bins=(self.s_edges, self.z_edges), weights=w[side])[0]
        lim = self.xy_edges[-1]
        for surface, code in (("floor", FLOOR), ("lid", LID)):
            on = j == code
            xs, ys = np.clip(x[on], -lim, lim), np.clip(y[on], -lim, lim)
            self.count[surface] += np.histogram2d(xs, ys, bins=(self.xy_edges, self.xy_edges))[0].astype(np.int64)
            for name, w in weights.items():
                bins = (self.xy_edges, self.xy_edges)
                self.squares[name][surface] += np.histogram2d(xs, ys, bins=bins, weights=w[on] ** 2)[0]
                if name in self.layers:
                    self.layers[name][surface] += np.histogram2d(xs, ys, bins=bins, weights=w[on])[0]

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

    def power(self, surface: str, tau: float, layer: str = "both") -> np.ndarray:
        """W/m² per cell of `layer` ("impact", "friction" or "both"); NaN outside the jar."""
        if layer != "both":
            return self.density(layer, surface, tau)
        return self.density("impact", surface, tau) + self.density("friction", surface, tau)

    def sampled(self, surface: str) -> np.ndarray:
        """True where a cell inside the jar holds at least MIN_EVENTS events: the cells
        a wear map colours; the others it greys."""
        return (self.count[surface] >= MIN_EVENTS) & (self.area(surface) > 0)

    def bands(self, surface: str) -> tuple[np.ndarray, np.ndarray]:
        """(band index per cell, band edges in m): the side wall's rows (edges in z) or
        the floor's or lid's rings about the jar axis, one cell wide (edges in r); cells
        outside the jar get -1."""
        if surface == "side":
            rows = np.broadcast_to(np.arange(len(self.z_edges) - 1), self.side_area.shape)
            return np.array(rows), self.z_edges
        mid = 0.5 * (self.xy_edges[1:] + self.xy_edges[:-1])
        h = self.xy_edges[1] - self.xy_edges[0]
        ring = np.floor(np.hypot(*np.meshgrid(mid, mid, indexing="ij")) / h).astype(int)
        return np.where(self.disc_area > 0, ring, -1), h * np.arange(ring.max() + 2)

    def hot_spot(self, tau: float, layer: str = "both") -> dict:
        """Where the walls wear most: a cell that stands out of its band, else the band.

        A band is a row of the side wall (one height, all the way round) or a ring of the
        floor or lid (one distance from the axis). A cell is a hot spot when it holds at
        least MIN_EVENTS events and its power per area P exceeds the rest of its band's,
        P_b, both SPOT_FACTOR times and by SPOT_SIGMAS standard errors:
        P ≥ SPOT_FACTOR · P_b and P − P_b ≥ SPOT_SIGMAS · √(σ² + σ_b²), the errors those
        of sums of random events, σ = √(Σ e²) / (A τ) over the events' energies e
        (compound Poisson). Of such cells the hot spot is the one with the largest P:
        `kind` "spot", `power_per_area` P, `concentration` P over the mean of all walls,
        `over_band` P / P_b, `band_sigmas` the excess in standard errors, and its place
        (`arc_length`, `angle_deg`, `z` on the side wall; `x`, `y`, `angle_deg` on the
        floor or lid). With no such cell the walls wear evenly round each band: `kind`
        "band", and the band with the most power per area (of those with MIN_EVENTS
        events) is named. Either way `band` gives that band: `surface`, its extent
        (`z_range` of a row, `r_range` of a ring, m), `power_per_area`, `concentration`."""
        total_area = self.side_area.sum() + 2 * self.disc_area.sum()
        energy = self.total("impact") + self.total("friction") if layer == "both" else self.total(layer)
        mean = energy / total_area / tau if tau > 0 and total_area > 0 else math.nan
        spot, hottest = None, None
        for surface in ("side", "floor", "lid"):
            e = self._energy(surface, layer)
            sq = self._squares(surface, layer)
            area, count = self.area(surface), self.count[surface]
            band, edges = self.bands(surface)
            for b in range(len(edges) - 1):
                inside = band == b
                a_b, e_b, n_b = area[inside].sum(), e[inside].sum(), count[inside].sum()
                if a_b <= 0 or n_b < MIN_EVENTS:
                    continue
                p_b = e_b / a_b / tau
                share = float(np.mean(count[inside & (area > 0)] >= MIN_EVENTS))
                if hottest is None or p_b > hottest[0]:
                    hottest = (p_b, surface, edges[b:b + 2], share)
                cells = inside & (count >= MIN_EVENTS) & (area > 0) & (area < a_b)
                if not cells.any():
                    continue
                a, e_c, sq_c = area[cells], e[cells], sq[cells]
                a_r = a_b - a
                p, p_r = e_c / a / tau, (e_b - e_c) / a_r / tau
                sigma = np.sqrt(sq_c / a**2 + (sq[inside].sum() - sq_c) / a_r**2) / tau
                out = (p >= SPOT_FACTOR * p_r) & (p - p_r >= SPOT_SIGMAS * sigma)
                if out.any():
                    i = int(np.argmax(np.where(out, p, -np.inf)))
                    if spot is None or p[i] > spot[0]:
                        k = tuple(int(c[i]) for c in np.nonzero(cells))
                        spot = (float(p[i]), surface, k, float(p_r[i]),
                                float((p[i] - p_r[i]) / sigma[i]) if sigma[i] > 0 else math.inf, edges[b:b + 2], p_b,
                                share)
        if hottest is None:
            return {"surface": None, "power_per_area": 0.0, "concentration": math.nan}

        def concentration(p):
            return float(p / mean) if mean > 0 else math.nan

        def band_of(surface, edges, p_b, share):
            extent = "z_range" if surface == "side" else "r_range"
            return {"surface": surface, extent: [float(edges[0]), float(edges[1])], "power_per_area": float(p_b),
                    "concentration": concentration(p_b), "sampled_share": share}

        if spot is None:
            p_b, surface, edges, share = hottest
            return {"kind": "band", "surface": surface, "power_per_area": float(p_b),
                    "concentration": concentration(p_b), "band": band_of(surface, edges, p_b, share)}
        p, surface, (a, b), p_r, sigmas, edges, p_b, share = spot
        out = {"kind": "spot", "surface": surface, "power_per_area": float(p), "concentration": concentration(p),
               "over_band": float(p / p_r) if p_r > 0 else math.inf, "band_sigmas": float(sigmas)}
        if surface == "side":
            s = 0.5 * (self.s_edges[a] + self.s_edges[a + 1])
            out.update(arc_length=float(s), angle_deg=float(self.geom.wall_angle(s)),
                       z=float(0.5 * (self.z_edges[b] + self.z_edges[b + 1])))
        else:
            xc, yc = (0.5 * (self.xy_edges[i] + self.xy_edges[i + 1]) for i in (a, b))
            out.update(x=float(xc), y=float(yc), angle_deg=float(math.degrees(math.atan2(yc, xc))))
        out["band"] = band_of(surface, edges, p_b, share)
        return out

    def _energy(self, surface: str, layer: str) -> np.ndarray:
        if layer == "both":
            return self.layers["impact"][surface] + self.layers["friction"][surface]
        return self.layers[layer][surface]

    def _squares(self, surface: str, layer: str) -> np.ndarray:
        return self.squares[layer][surface]


def hot_spot_text(h: dict) -> str:
    """One line naming what WallMap.hot_spot found ("" if nothing): the spot and how far
    it stands out of its band, or the band, uniform round the wall."""
    if not h.get("surface"):
        return ""
    wall = f"{h['power_per_area']:.4g} W/m², {h['concentration']:.3g}× the wall mean"
    if h.get("kind", "spot") == "spot":
        where = (f"side wall at {h['angle_deg']:.0f}°, z = {h['z'] * 1e3:.1f} mm" if h["surface"] == "side"
                 else f"{h['surface']} at x = {h['x'] * 1e3:.1f}, y = {h['y'] * 1e3:.1f} mm")
        band = (f"; {h['over_band']:.3g}× the rest of its {_band_name(h['band'])}, {h['band_sigmas']:.3g} standard errors"
                if "band" in h else "")
        return f"wear hot spot: {where}, {wall}{band}"
    around = "the wall" if h["surface"] == "side" else "the axis"
    where = f"most in the {h['surface'].replace('side', 'side wall')}'s {_band_name(h['band'])}"
    if uniform(h):
        return (f"wear: no hot spot; {where}, uniform around {around} (no cell exceeds the rest of its band "
                f"{SPOT_FACTOR:g}× and by {SPOT_SIGMAS:g} standard errors), {wall}")
    share = h["band"].get("sampled_share", math.nan)
    return (f"wear: no hot spot found; {where}, {wall}; only {share:.0%} of its cells have {MIN_EVENTS} events or "
            f"more, too few to tell whether it is uniform around {around} (a longer window would)")


def uniform(h: dict) -> bool:
    """True if WallMap.hot_spot found no spot and its band has enough sampled cells
    (UNIFORM_SHARE) to be called uniform around the wall."""
    return h.get("kind") == "band" and h["band"].get("sampled_share", 0.0) >= UNIFORM_SHARE


def _band_name(band: dict) -> str:
    if "z_range" in band:
        lo, hi = band["z_range"]
        return f"band z = {lo * 1e3:.1f}–{hi * 1e3:.1f} mm"
    lo, hi = band["r_range"]
    return f"ring r = {lo * 1e3:.1f}–{hi * 1e3:.1f} mm"


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
