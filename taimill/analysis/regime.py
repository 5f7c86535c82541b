"""Motion regime of the balls — cascading, cataracting or rolling — from measurable
criteria, with the criteria, thresholds and a confidence reported.

Criteria (each a fraction or a length ratio, measured in the analysis window):
- `wall_fraction`: share of ball-frames whose centre is within r(1 + 2 %) of the side
  wall (the ball touches it).
- `flight_fraction`: share of ball-frames touching neither the side wall nor another
  ball (in flight; the floor and lid do not count, gravity only sets balls on the floor).
- `flight_chord`: mean distance between successive side-wall impacts (u̇_n ≥ 5 cm/s)
  of the same ball, over the largest chord a centre can fly, 2(R − r).
- `impact_chord`: where the balls' side-wall impacts (u̇_n ≥ 5 cm/s) come from, in the
  plate frame: the distance between a ball's successive impacts, with the jar's turn
  relative to the plate between them taken out (the jar frame's point rotated by
  ψ = φ_plate − φ_jar), over 2(R − r), averaged with weights ½ m_e u̇_n² (the normal
  stress energy of the landing impact). Small for balls that hop in place while the
  wall slides under them; of order 0.3–0.6 for balls thrown across the jar. NaN
  without two impacts of one ball.
- `wall_lag`: for the balls touching the side wall, their mean azimuthal speed in the
  jar frame over the mean speed (Ω − w) ρ at which the plate frame moves relative to
  the jar at their centre radius ρ (Ω: plate speed, w: absolute jar spin, both of the
  frame). 0 for balls carried with the jar, 1 for balls at rest in the plate frame;
  NaN when no ball touches the wall. Not used by `classify`: the regime map
  (`map_regime`) splits a riding charge with it.

Rules, in order:
    rolling      wall_fraction ≥ 0.5 and flight_fraction < 0.35   (balls ride the wall)
    cataracting  flight_fraction ≥ 0.55 and impact_chord ≥ 0.16   (most of the time in
                                                                  flight, landing away
                                                                  from where they left)
    cascading    otherwise                                       (balls roll, tumble or
                                                                  hop over the bed)
Thresholds set from the CY steel preset scanned over K = −0.2 … −3.8 (8 s runs;
windows 1–8 s and 4–8 s agree within 0.03, and 2–3 s runs over three seeds too):
wall_fraction 0.06–0.36 for K ≥ −2.6 vs 0.77–0.91 at K ≤ −3.4;
flight_fraction 0.42 at K = −0.6 and 0.70 at K = −2.2. The cascading/cataracting
change is gradual (every criterion moves monotonically from K = −0.2 to −2.6); the
threshold sits halfway between K = −0.6 and −2.2 and puts the change near K ≈ −1.4
(|K| ≈ 0.65 |K_c|). Checked on HM steel (−0.6 cascading, −2.2 cataracting, −3.8
rolling) and CY fluorite (−0.6 cascading; −2.2 and −3.8 rolling: with μ = 0.2 the
balls slide round the wall as a ring). The flight chord is reported, not used: with
the HM flat wall it stays ≈ 0.07 at K = −2.2 although the balls are mostly in flight.

A flight fraction alone calls a hop a flight. On a standard-gear mill (PM 100, 80 ml
zirconia bowl, 25 zirconia balls of 5 mm, 400 rpm, K = −1, measured zirconia friction;
window 2–4 s) the balls are off the wall and each other 90 % of the time, but they hop
≈ 1 mm in place while the wall slides under them: impact_chord 0.091. Thrown balls land
elsewhere: CY steel (5 s runs, window 2–5 s) 0.28 at K = −1.0, 0.35 (−1.4), 0.39 (−1.8),
0.47 (−2.2), 0.55 (−2.6); HM steel 0.58 at −2.2. CATARACT_CHORD = 0.16 sits at the
geometric mean of the hopping 0.091 and the lowest thrown 0.28; it moves none of these
P 4 runs' regimes. A hopping charge is `cascading` here and a `hopping bed` on the map.

Confidence: the window is cut into 1 s pieces, each classified by the same rules; the
confidence is the share of pieces agreeing with the whole window's label (1.0 = every
second looks the same; low values flag a run at a regime boundary or still settling).
"""

from __future__ import annotations

import math

import numpy as np

from taimill.analysis.contacts import MAX_PAIRWISE
from taimill.analysis.rungeometry import SIDE, RunGeometry
from taimill.schema import REGIME_CLASSES

ROLLING_WALL, ROLLING_FLIGHT = 0.5, 0.35
CATARACT_FLIGHT = 0.55
CATARACT_CHORD = 0.16  # impact_chord at and above which balls in flight are thrown, not hopping
TOUCH_SLACK = 0.02  # of a ball radius
IMPACT_UN = 0.05  # m/s, side-wall impacts counted for the flight chord
FEATURE_RATE = 25.0  # frames per second examined
PAIR_ELEMENTS = 1 << 20  # ball pairs compared at once across frames (× 8 B × 3 for the differences)
PIECE = 1.0  # s, sub-window for the confidence

THRESHOLDS = {"rolling": {"wall_fraction >=": ROLLING_WALL, "flight_fraction <": ROLLING_FLIGHT},
              "cataracting": {"flight_fraction >=": CATARACT_FLIGHT, "impact_chord >=": CATARACT_CHORD}}


def hopping(flight_fraction: float, impact_chord: float) -> bool:
    """Balls mostly off the wall and each other that land where they left, in the plate
    frame: they hop in place (a NaN chord, no repeated impacts, is not taken as hopping)."""
    return flight_fraction >= CATARACT_FLIGHT and impact_chord < CATARACT_CHORD


def classify(wall_fraction: float, flight_fraction: float, flight_chord: float = math.nan,
             impact_chord: float = math.nan) -> str:
    """The rules above; NaN criteria (e.g. too many balls to search pairs) fall back on
    the wall fraction alone."""
    if not math.isfinite(wall_fraction):
        return "unknown"
    if not math.isfinite(flight_fraction):
        return "rolling" if wall_fraction >= ROLLING_WALL else "cascading/cataracting"
    if wall_fraction >= ROLLING_WALL and flight_fraction < ROLLING_FLIGHT:
        return "rolling"
    if flight_fraction >= CATARACT_FLIGHT and not hopping(flight_fraction, impact_chord):
        return "cataracting"
    return "cascading"


class RegimeFeatures:
    """Accumulates the criteria over the window t ≥ t0, per 1 s piece."""

    def __init__(self, g: RunGeometry, radii, t0: float = 0.0):
        self.g, self.radii, self.t0 = g, np.asarray(radii, float), t0
        self.pairwise = len(self.radii) <= MAX_PAIRWISE
        self.next_t = t0
        # piece -> [ball-frames, on wall, in flight, chord sum, chords,
        #           Σ azimuthal jar-frame speed on the wall, Σ (Ω − w) ρ on the wall,
        #           Σ SE_n × plate-frame chord, Σ SE_n]
        self.pieces: dict[int, np.ndarray] = {}
        self.last_impact: dict[int, tuple] = {}  # ball -> its last impact point, jar and plate frame
        self.chord_scale = 2.0 * (g.jar_radius - g.ball_radius)

    def _piece(self, t: float) -> np.ndarray:
        return self.pieces.setdefault(int((t - self.t0) // PIECE), np.zeros(9))

    def _sampled(self, time: np.ndarray):
        """(index, time) of the frames sampled at FEATURE_RATE: the first frame at or
        after next_t, then the first at or after its time + 1 / FEATURE_RATE, ... In
        time order the next one is found by bisection: a dense trajectory (10⁵ frames/s)
        is not walked frame by frame in Python."""
        time = np.asarray(time)
        ordered = len(time) < 2 or bool(np.all(time[1:] >= time[:-1]))
        f = 0
        while f < len(time):
            if ordered:
                f += int(np.searchsorted(time[f:], self.next_t - 1e-12, side="left"))
                if f == len(time):
                    return
            t = time[f]
            if not t < self.next_t - 1e-12:
                self.next_t = t + 1.0 / FEATURE_RATE
                yield f, t
            f += 1

    def frames(self, block: dict) -> None:
        """Add the block's sampled frames. Who touches the side wall and who touches
        another ball is found for all of them at once (NumPy over frames, a few frames
        at a time for large mills); the per-frame sums then run in the order the frames
        come, as one frame at a time would. (One frame_contacts call per frame, with the
        contact speeds this does not need, made the Python share of a 12-ball run 7.6 %
        instead of 4.5 %.)"""
        picks = list(self._sampled(block["time"]))
        if not picks:
            return
        n, r = len(self.radii), self.radii
        slack = TOUCH_SLACK * self.g.ball_radius
        rows = np.array([f for f, _ in picks])
        x_all, v_all = np.asarray(block["position"])[rows], np.asarray(block["velocity"])[rows]
        phi, _ = self.g.sdf(x_all[:, :, :2].reshape(-1, 2))
        wall = phi.reshape(len(rows), n) < r + slack
        touching = wall.copy()
        if self.pairwise:
            reach = r[:, None] + r[None, :] + slack
            step = max(1, PAIR_ELEMENTS // max(1, n * n))
            for a in range(0, len(rows), step):
                x = x_all[a:a + step]
                close = np.triu(np.linalg.norm(x[:, None, :, :] - x[:, :, None, :], axis=3) < reach, 1)
                touching[a:a + step] |= close.any(axis=2) | close.any(axis=1)
        for k, (f, t) in enumerate(picks):
            # the frame's own drive (a TUI run changes it live), else the config's ramps
            w = float(block["jar_spin"][f]) if "jar_spin" in block else self.g.jar.at(float(t))[0]
            om = float(block["plate_speed"][f]) if "plate_speed" in block else self.g.plate.at(float(t))[0]
            on_wall = np.flatnonzero(wall[k])
            p = self._piece(float(t))
            p[0] += n
            p[1] += len(on_wall)
            p[2] += (n - int(np.count_nonzero(touching[k]))) if self.pairwise else math.nan
            if len(on_wall):  # wall_lag: azimuthal jar-frame speed vs the plate frame's (Ω − w) ρ
                x, v = x_all[k][on_wall], v_all[k][on_wall]
                rho = np.hypot(x[:, 0], x[:, 1])
                p[5] += float(np.sum((x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]) / np.maximum(rho, 1e-12)))
                p[6] += (om - w) * float(np.sum(rho))

    def events(self, block: dict) -> None:
        sel = (block["kind"] == 1) & (block["body_j"] == SIDE) & (block["un"] >= IMPACT_UN) & (block["t_start"] >= self.t0)
        order = np.argsort(block["t_start"][sel], kind="stable")
        t, b, x, y, m, un = (block[k][sel][order] for k in ("t_start", "body_i", "x", "y", "m_eff", "un"))
        se = 0.5 * m * un * un
        # the impact point in the plate frame: the jar frame's turned back by ψ = φ_plate − φ_jar
        # (the configured drive's angles; a live-tuned recording's differ after a change)
        psi = np.array([self.g.plate.at(float(tk))[2] - self.g.jar.at(float(tk))[2] for tk in t])
        xp, yp = np.cos(psi) * x + np.sin(psi) * y, np.cos(psi) * y - np.sin(psi) * x
        for k in range(len(t)):
            prev = self.last_impact.get(int(b[k]))
            self.last_impact[int(b[k])] = (x[k], y[k], xp[k], yp[k])
            if prev is not None:
                p = self._piece(float(t[k]))
                p[3] += math.hypot(x[k] - prev[0], y[k] - prev[1]) / self.chord_scale
                p[4] += 1
                p[7] += se[k] * math.hypot(xp[k] - prev[2], yp[k] - prev[3]) / self.chord_scale
                p[8] += se[k]

    @staticmethod
    def _criteria(a: np.ndarray) -> dict:
        return {"wall_fraction": a[1] / a[0] if a[0] else math.nan,
                "flight_fraction": a[2] / a[0] if a[0] else math.nan,
                "flight_chord": a[3] / a[4] if a[4] else 0.0,
                "wall_lag": a[5] / a[6] if a[6] else math.nan,
                "impact_chord": a[7] / a[8] if a[8] > 0 else math.nan}

    @staticmethod
    def _label(crit: dict) -> str:
        return classify(crit["wall_fraction"], crit["flight_fraction"], crit["flight_chord"], crit["impact_chord"])

    def result(self) -> dict:
        """{'regime', 'regime_confidence', 'regime_criteria': {...}, 'regime_thresholds'}"""
        full = [p for p in self.pieces.values() if p[0] > 0]
        if not full:
            return {"regime": "unknown", "regime_confidence": math.nan, "regime_criteria": {}, "regime_thresholds": THRESHOLDS}
        crit = self._criteria(np.sum(full, axis=0))
        label = self._label(crit)
        votes = [self._label(self._criteria(p)) for p in full]
        return {"regime": label, "regime_confidence": votes.count(label) / len(votes),
                "regime_criteria": crit, "regime_thresholds": THRESHOLDS}


# ---------------------------------------------------------------- regime maps
# The (K, μ) map tells three ways a charge can ride the wall apart (docs/regimes.md):
# a *pinned ring* turns with the jar (wall_lag near 0); a charge near rest in the plate
# frame (wall_lag near 1) is a *sliding bed* when the wall slides under it (slip ratio
# ≥ SLIDING_SLIP) and a *rolling bed* when its balls roll in place, their contact
# points moving with the wall (no slip, so by the slip ratio alone it looked pinned).
MAP_REGIMES = REGIME_CLASSES  # taimill.schema: the summary's regime_class takes these values
# slip_ratio at and above which a riding charge is a sliding bed: its wall slides under
# it, in part or fully. Beds rolling in place read 0.0011 (CY map, μ 0.5, K = 0) and
# 0.012–0.015 (CY graphite-6, K = −2.2, seed 6); beds whose wall slides 0.074 (CY map,
# μ 0.25, K = −1), 0.096, 0.22, 0.59 and 0.62 (PM 100, 80 ml zirconia, 25 × 5 mm zirconia,
# dry-ceramic-powder, 400 rpm, seeds 4, 3, 1, 2: 6 s runs, window 2–6 s), 0.43–0.49
# (graphite-6's other state) and 0.72 (CY fluorite, K = −3.0). 0.1, the threshold before,
# split the PM 100 bed's seeds; 0.03 lies in the gap 0.015 … 0.074.
SLIDING_SLIP = 0.03
# wall_lag below which a riding charge turns with the jar (pinned ring). Measured (CY,
# 8 s runs, window 4–8 s): steel pinned rings −0.020 (K = −3.6) and −0.028 (−4.0);
# fluorite's sliding bed at −3.0 1.000 (slip 0.72); graphite-6 at −2.2 0.9999, slip
# 0.015: a bed rolling in place, which the slip ratio alone called pinned. Re-running
# the seven "pinned ring" cells of results/regime_map_cy.png (12 s, window 4–12 s):
# five rings −0.041 … −0.012, two beds 0.96 (K = −1, μ 0.25, slip 0.074) and 0.80
# (K = 0, μ 0.5, confidence 0.5); non-riding cells of those runs read 0.75–0.87.
# results/powder_models.md's rings re-run: graphite-6 at −2.2 … −3.8 all 1.000 (rolling
# beds), fluorite at −3.8 (μ_r 0.02, 0.1, ball-wall only) 0.017, 0.042, −0.016. The
# threshold sits in the middle of the gap between rings (≤ 0.05) and beds (≥ 0.8).
PINNED_LAG = 0.5
# A criterion this close to the threshold that decided a class is called borderline: a
# replica, another seed or a longer window may give the other class. Factors: the slip
# ratio spans decades (beds 10⁻³ … 1), the chord a factor 6 (0.09 … 0.58), the flight
# fraction 0.4 … 0.9 (docs/regimes.md's runs).
BORDERLINE = {"slip ratio": 1.5, "impact chord": 1.25, "flight fraction": 1.1}


def class_note(label: str, criteria: dict, slip: float) -> str | None:
    """A line when the class rests on a criterion near its threshold (within the
    criterion's BORDERLINE factor of it), naming the criterion, its value, the threshold
    and the other class; None when the class is clear. criteria: the regime's
    (wall_fraction, flight_fraction, impact_chord, …); slip: the slip ratio."""
    def near(name, value, threshold):
        return math.isfinite(value) and threshold / BORDERLINE[name] <= value <= threshold * BORDERLINE[name]

    def line(name, value, threshold, other):
        return (f"borderline: {name} {value:.3g} is near the {threshold:g} that splits {label} from {other}; "
                "replicas (other seeds) tell which it is")

    chord, flight = criteria.get("impact_chord", math.nan), criteria.get("flight_fraction", math.nan)
    if label in ("sliding bed", "rolling bed") and near("slip ratio", slip, SLIDING_SLIP):
        return line("slip ratio", slip, SLIDING_SLIP, "rolling bed" if label == "sliding bed" else "sliding bed")
    if label in ("hopping bed", "cataracting") and flight >= CATARACT_FLIGHT and near("impact chord", chord, CATARACT_CHORD):
        return line("impact chord", chord, CATARACT_CHORD, "cataracting" if label == "hopping bed" else "hopping bed")
    if label in ("cascading", "cataracting", "hopping bed") and near("flight fraction", flight, CATARACT_FLIGHT):
        return line("flight fraction", flight, CATARACT_FLIGHT, "cascading" if label != "cascading" else "cataracting")
    return None


def slip_ratio(row: dict) -> float:
    """Friction power of the persistent side-wall contacts over what the wall would
    dissipate sliding at its full speed |K − 1| Ω R (relative to the plate) under every
    ball pressed by the plate's pull m Ω² R_p: P / (μ_d n m Ω³ R_p R |K − 1|), μ_d the
    ball-wall dynamic friction. ≈ 0 for a pinned ring, of order 1 for a sliding bed.
    `row` is a sweep-table row (taimill.runs.sweep.point_values and the flattened
    summary). inf without wall friction (nothing can pin the charge)."""
    om = row["plate_rpm"] * math.pi / 30.0
    mu_d = row.get("mu_d_wall", math.nan)
    ref = mu_d * row["balls"] * row["ball_mass"] * abs(om) ** 3 * row["plate_radius"] * row["jar_radius"] * abs(row["ratio"] - 1.0)
    power = row.get("dissipated_power_side_persistent_friction", math.nan)
    if mu_d == 0.0:
        return math.inf
    return power / ref if ref > 0 else math.nan


def map_regime(regime: str, slip: float, wall_lag: float = math.nan, flight_fraction: float = math.nan,
               impact_chord: float = math.nan) -> str:
    """One of MAP_REGIMES: the run's regime, its `rolling` split by the wall lag and the
    slip ratio: wall_lag < PINNED_LAG pinned ring; otherwise sliding bed when slip ≥
    SLIDING_SLIP, else rolling bed. Without a finite wall_lag (rows of sweep stores
    written before it was measured, which lack the column) the old two-way rule holds:
    slip ≥ SLIDING_SLIP sliding bed, else pinned ring — so such a "pinned ring" may be
    a rolling bed. A charge whose balls hop in place in the plate frame (`hopping`:
    mostly in flight, impact_chord < CATARACT_CHORD) is a hopping bed; rows without an
    impact_chord (older stores) keep their regime."""
    if regime != "rolling":
        if hopping(flight_fraction, impact_chord):
            return "hopping bed"
        return regime if regime in MAP_REGIMES else "unknown"
    if not math.isfinite(slip) and not math.isinf(slip):
        return "unknown"
    if wall_lag is None or not math.isfinite(wall_lag):  # an old store: no wall_lag column
        return "sliding bed" if slip >= SLIDING_SLIP else "pinned ring"
    if wall_lag < PINNED_LAG:
        return "pinned ring"
    return "sliding bed" if slip >= SLIDING_SLIP else "rolling bed"


def row_class(row: dict) -> str:
    """A run's or sweep row's regime class (MAP_REGIMES), the one vocabulary of tables
    and figures: its stored `regime_class`, else (rows of stores written before it)
    from its regime, slip ratio and wall lag; "unknown" where neither is there."""
    if row.get("regime_class"):
        return str(row["regime_class"])
    regime = str(row.get("regime") or "unknown")
    try:  # the slip ratio splits only a charge riding the wall
        slip = slip_ratio(row) if regime == "rolling" else math.nan
        return map_regime(regime, slip, row.get("wall_lag", math.nan), row.get("flight_fraction", math.nan),
                          row.get("impact_chord", math.nan))
    except (KeyError, TypeError, ValueError):
        return "unknown"

