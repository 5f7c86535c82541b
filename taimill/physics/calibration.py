"""Single-impact experiments run by the real engine: the drop test of thesis §2.1.1
(ball on plate, e = √(h*/h₀), eq 2.5) and its ball-ball counterpart."""

from __future__ import annotations

import math

import numpy as np

from taimill.params import GRAVITY, pair_contact
from taimill.physics import laws_np
from taimill.physics.frame_np import Ramp
from taimill.physics.mill import MillSpec
from taimill.physics.simulation import Runner
from taimill.sinks import MemorySink

STILL = Ramp(0.0, 0.0, 0.0, 1.0)


def impact_spec(ball, jar, bb, bw, friction, positions, velocities, *, gravity, dt, steps, spins=None):
    n = len(positions)
    return MillSpec(
        radius=np.full(n, ball.radius), mass=np.full(n, ball.mass),
        position=np.asarray(positions, float), velocity=np.asarray(velocities, float),
        spin=np.zeros((n, 3)) if spins is None else np.asarray(spins, float),
        profile=jar.profile, height=jar.height, ball_ball=bb, ball_wall=bw, friction=friction,
        plate=STILL, jar=STILL, plate_radius=0.0, gravity=gravity, dt=dt, steps=steps, frame_every=max(1, steps),
    )


def run_spec(spec: MillSpec):
    """Run one mill to its end; returns (final state dict, event table)."""
    runner = Runner([spec])
    sink = MemorySink()
    runner.run([sink])
    return runner.final_state(0), sink.event_table


def drop_test(pair: str, h0: float, *, target="plate", radius=None, law=None, dt=None) -> dict:
    """Drop a ball from height h0 (m, ball bottom above the target) onto the plate or onto
    a free ball of its kind. Returns e, rebound height h* (m), contact duration (s),
    peak force (N), peak penetration (m) and dt (s).

    Plate: gravity on; the ball starts just above the plate at √(2 g h₀); h* is its
    apex after the rebound, e = √(h*/h₀) as measured in the thesis (eq 2.5).
    Ball: two free balls meet head-on at √(2 g h₀) without gravity; e is their
    separation/approach speed ratio and h* = e² h₀ the equivalent rebound height."""
    ball, jar, bb, bw, friction = pair_contact(pair, radius, law)
    v0 = math.sqrt(2.0 * GRAVITY * h0)
    law_used = bw if target == "plate" else bb
    dt = dt or laws_np.auto_dt((law_used,), v0)
    t_c = float(laws_np.simulate_impact(law_used.law_id, law_used.k, law_used.n, law_used.c, law_used.d, law_used.m_eff, v0)["duration"][0])
    steps = int(3 * t_c / dt) + 10
    r, gap = ball.radius, 1e-7
    if target == "plate":
        spec = impact_spec(ball, jar, bb, bw, friction, [[0, 0, r + gap]], [[0, 0, -v0]], gravity=GRAVITY, dt=dt, steps=steps)
    else:
        spec = impact_spec(ball, jar, bb, bw, friction, [[0, 0, 1.0], [0, 0, 1.0 + 2 * r + gap]],
                           [[0, 0, 0.5 * v0], [0, 0, -0.5 * v0]], gravity=0.0, dt=dt, steps=steps)
    state, events = run_spec(spec)
    if len(events["t_start"]) != 1:
        raise RuntimeError(f"drop test expected one impact, got {len(events['t_start'])}")
    v = state["v"]
    if target == "plate":
        h_star = state["x"][0, 2] - r + v[0, 2] ** 2 / (2.0 * GRAVITY)
        e = math.sqrt(max(h_star, 0.0) / h0)
    else:
        e = (v[1, 2] - v[0, 2]) / v0
        h_star = e * e * h0
    return {
        "pair": pair, "target": target, "law": law_used.law, "h0": h0, "impact_speed": v0,
        "e": e, "rebound_height": h_star, "contact_duration": float(events["duration"][0]),
        "peak_force": float(events["peak_force"][0]), "peak_penetration": float(events["peak_penetration"][0]),
        "dt": dt, "ball_radius": r,
    }
