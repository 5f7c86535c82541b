"""Contacts seen in output frames (NumPy): which balls touch the side wall, the floor,
the lid or each other at a stored instant, and their current normal and slip speeds.

Used by the sampled estimator (thesis §3.3) and the regime classifier. Conventions as
in the engine (docs/model.md, docs/outputs.md): positions and velocities in the jar frame, spins absolute
in jar-frame components; the slip speed at a contact point includes spin,
u = v_i - v_j + (s_i - w ẑ) × a_i - (s_j - w ẑ) × a_j, walls at rest in the jar frame.
"""

from __future__ import annotations

import numpy as np

from taimill.analysis.rungeometry import FLOOR, LID, SIDE, RunGeometry

MAX_PAIRWISE = 4000  # balls; beyond, ball–ball contacts are not searched in frames


def _speeds(rel: np.ndarray, n: np.ndarray):
    un = np.einsum("ij,ij->i", rel, n)
    ut = np.linalg.norm(rel - un[:, None] * n, axis=1)
    return un, ut


def frame_contacts(g: RunGeometry, radii, x, v, s, w: float, slack: float = 0.0) -> dict:
    """Contacts in one frame. x, v, s: (N, 3) jar-frame position (m), velocity (m/s),
    absolute spin (rad/s); w: the jar's absolute spin (rad/s) at that instant; slack:
    gap (m) still counted as touching. Returns a dict of arrays over contacts:
    i, j (partner ball or SIDE/FLOOR/LID), un (m/s, > 0 approaching), ut (m/s),
    m_eff (kg)."""
    r = np.asarray(radii, float)
    m = g.ball_mass * (r / g.ball_radius) ** 3
    rel_spin = s - np.array([0.0, 0.0, w])
    out = {k: [] for k in ("i", "j", "un", "ut", "m_eff")}

    def emit(i, j, n, rel, me):
        un, ut = _speeds(rel, n)
        for k, val in (("i", i), ("j", j), ("un", un), ("ut", ut), ("m_eff", me)):
            out[k].append(np.asarray(val))

    phi, grad = g.sdf(x[:, :2])
    side = np.flatnonzero(phi < r + slack)
    if len(side):
        n = np.column_stack([-grad[side], np.zeros(len(side))])  # from the ball towards the wall
        rel = v[side] + np.cross(rel_spin[side], r[side, None] * n)
        emit(side, np.full(len(side), SIDE), n, rel, m[side])
    for code, hit, nz in ((FLOOR, x[:, 2] < r + slack, -1.0), (LID, x[:, 2] > g.height - r - slack, 1.0)):
        k = np.flatnonzero(hit)
        if len(k):
            n = np.tile([0.0, 0.0, nz], (len(k), 1))
            emit(k, np.full(len(k), code), n, v[k] + np.cross(rel_spin[k], r[k, None] * n), m[k])
    if len(r) <= MAX_PAIRWISE:
        d = x[None, :, :] - x[:, None, :]  # d[i, j] = x_j - x_i
        dist = np.linalg.norm(d, axis=2)
        i, j = np.nonzero(np.triu(dist < (r[:, None] + r[None, :] + slack), 1))
        if len(i):
            n = d[i, j] / dist[i, j, None]
            rel = (v[i] + np.cross(rel_spin[i], r[i, None] * n)) - (v[j] + np.cross(rel_spin[j], -r[j, None] * n))
            emit(i, j, n, rel, m[i] * m[j] / (m[i] + m[j]))
    return {k: (np.concatenate(vals) if vals else np.zeros(0)) for k, vals in out.items()}
