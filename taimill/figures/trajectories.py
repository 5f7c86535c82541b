"""Trajectory panels of one run (matplotlib): the jar's outline and a few balls' paths in
the jar frame, from above and in section, drawn only where the stored frames resolve them."""

from __future__ import annotations

import numpy as np

from taimill.analysis.run import RunAnalysis
from taimill.figures.layout import legend_outside

MM = 1e3


def outline(ax, a: RunAnalysis):
    o = np.vstack([a.geom.profile.outline, a.geom.profile.outline[:1]]) * MM
    ax.plot(o[:, 0], o[:, 1], color="0.2", lw=1.2)
    ax.set_aspect("equal")


# Trajectory panels: stored frames are 10 ms apart (100/s), in which a cataracting ball
# flies 2-5 cm, so straight lines between them draw a jagged polygon. Between two
# frames the curve is the cubic Hermite interpolant of the stored positions and
# velocities (velocities relative to the jar frame are the time derivatives of the
# jar-frame positions): exact to O(h⁴) in free flight and while rolling along the
# wall. A collision between two frames bends the real path sharply; the curve keeps
# its end points and end tangents there but rounds the corner, so the stored frames
# are marked with dots: the data, the curve only joins them.
#
# The curve joins two frames only where they resolve the motion between them. Where a
# ball moves so far from one frame to the next that its path must turn on the way,
# the turn is the end velocities extrapolated over a step in which the ball may meet
# others unseen: in a PM 100 at 400 rpm (K = −1) the jar turns 48° on the plate
# between two frames 10 ms apart, and a bed sliding on its wall steps 2 cm a frame
# along an arc of 25 mm radius. Criterion: a step is drawn as a curve where the curve
# stays within JOIN_BOW ball radii of the straight line between its two frames, i.e.
# where it claims less beyond the two stored positions than the ball it stands for;
# elsewhere the step is left undrawn and its frames stand as points. A turning step
# bows by (speed × frame interval)² / (8 × radius of the turn) (an arc of radius ρ
# swept by θ: ρ(1 − cos θ/2)), so this bounds the step by the ball's size and the
# turn's, not by either alone: along the wall ≤ 37° a frame for 5 mm balls in the
# 80 ml PM 100 jar, ≤ 55° for the thesis' 12 mm balls in the CY jar. A straight step
# (free flight across the jar, where the curve is exact to O(h⁴)) stays drawn at any
# length, and a collision the curve rounds off within half a ball radius too. Measured
# at the default 100 frames/s: 1 % of the steps left undrawn in the thesis' CY steel
# run (K = −2.6, 200 rpm), 93 % for 25 zirconia balls of 5 mm sliding on the wall of
# the PM 100's 80 ml jar at 400 rpm. (A step whose end velocities both fall short of
# it along a straight line is drawn straight: the curve then claims no more than the
# line between the two dots.)
SUBSTEPS = 8  # curve points per frame interval
JOIN_BOW = 0.5  # ball radii: the most a drawn curve departs from the straight step between its frames


def hermite_path(t: np.ndarray, x: np.ndarray, v: np.ndarray, substeps: int = SUBSTEPS) -> np.ndarray:
    """Points (substeps·(F−1) + 1, D) of the piecewise cubic Hermite curve through
    positions x (F, D) with velocities v (F, D) at times t (F,)."""
    if len(t) < 2:
        return np.asarray(x)
    h = np.diff(t)[:, None, None]
    s = np.linspace(0.0, 1.0, substeps, endpoint=False)[None, :, None]
    s2, s3 = s * s, s * s * s
    p = ((2 * s3 - 3 * s2 + 1) * x[:-1, None] + (s3 - 2 * s2 + s) * h * v[:-1, None]
         + (3 * s2 - 2 * s3) * x[1:, None] + (s3 - s2) * h * v[1:, None])
    return np.vstack([p.reshape(-1, x.shape[1]), x[-1:]])


def frame_path(t: np.ndarray, x: np.ndarray, v: np.ndarray, radius: float,
               substeps: int = SUBSTEPS) -> tuple[np.ndarray, np.ndarray]:
    """(curve, joined): the Hermite curve of hermite_path (same points) with the inner
    points of each step it does not join NaN, so that a plot leaves that step undrawn;
    joined (F−1,) bool: the steps whose curve stays within JOIN_BOW · radius (m, the
    ball's) of the straight line between their frames (comment above)."""
    substeps = max(int(substeps), 2)  # a step needs an inner point to be left out
    curve = np.array(hermite_path(t, x, v, substeps), dtype=float)
    if len(t) < 2:
        return curve, np.zeros(0, dtype=bool)
    inner = curve[:-1].reshape(len(t) - 1, substeps, -1)
    a, d = x[:-1, None], (x[1:] - x[:-1])[:, None]
    along = np.einsum("fsd,fsd->fs", inner - a, d) / np.maximum(np.einsum("fsd,fsd->fs", d, d), 1e-300)
    bow = np.linalg.norm(inner - (a + np.clip(along, 0.0, 1.0)[..., None] * d), axis=-1).max(axis=1)
    joined = bow <= JOIN_BOW * radius
    inner[~joined, 1:] = np.nan
    return curve, joined


def _paths(a: RunAnalysis, balls: int, seconds: float):
    """(curve, stored frames, joined steps) per drawn ball; mm, jar frame."""
    fr = a.store.frames
    sel = (fr["time"] >= a.t0) & (fr["time"] < a.t0 + seconds)
    t = fr["time"][sel]
    radii = np.broadcast_to(np.asarray(a.store.radii, dtype=float), (a.geom.n_balls,))
    for b in range(min(balls, a.geom.n_balls)):
        x, v = fr["position"][sel, b], fr["velocity"][sel, b]
        curve, joined = frame_path(t, x, v, radii[b])
        yield curve * MM, x * MM, joined


def _interval_ms(a: RunAnalysis, seconds: float) -> float:
    t = a.store.frames["time"]
    t = t[(t >= a.t0) & (t < a.t0 + seconds)]
    return float(np.median(np.diff(t))) * 1e3 if len(t) > 1 else float("nan")


def draw_trajectories_top(ax, a: RunAnalysis, balls: int = 3, seconds: float = 0.5):
    outline(ax, a)
    steps = []
    for b, (curve, stored, joined) in enumerate(_paths(a, balls, seconds)):
        line, = ax.plot(curve[:, 0], curve[:, 1], lw=0.7, label=f"ball {b}")
        ax.plot(stored[:, 0], stored[:, 1], ".", ms=2.5, color=line.get_color())
        steps.append(joined)
    steps = np.concatenate(steps) if steps else np.zeros(0, dtype=bool)
    title = f"Trajectories, top view ({seconds:g} s; dots: stored frames)"
    if (~steps).any():  # what the dots alone stand for, and how often
        title += (f"\nframes {_interval_ms(a, seconds):.3g} ms apart: {(~steps).mean():.0%} of the steps "
                  "too long to draw as paths, points only")
    ax.set(xlabel="x (mm, jar frame)", ylabel="y (mm)", title=title)
    legend_outside(ax)


def draw_trajectories_section(ax, a: RunAnalysis, balls: int = 3, seconds: float = 0.5):
    x0, x1 = a.geom.profile.outline[:, 0].min() * MM, a.geom.profile.outline[:, 0].max() * MM
    H = a.geom.height * MM
    ax.plot([x0, x1, x1, x0, x0], [0, 0, H, H, 0], color="0.2", lw=1.2)
    for curve, stored, _ in _paths(a, balls, seconds):
        line, = ax.plot(curve[:, 0], curve[:, 2], lw=0.7)
        ax.plot(stored[:, 0], stored[:, 2], ".", ms=2.5, color=line.get_color())
    ax.set(xlabel="x (mm, jar frame)", ylabel="z (mm)", title="Trajectories, section")
    ax.set_aspect("equal")
