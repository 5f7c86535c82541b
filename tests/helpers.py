"""Hand-built mills for validation tests: one or two balls, no drive, chosen laws."""

from __future__ import annotations

import numpy as np

from taimill.params import Friction, NormalLaw, pair_contact
from taimill.physics import laws_np
from taimill.physics.calibration import impact_spec, run_spec

FRICTIONLESS = Friction("frictionless", 0.0, 0.0, 1e-3, 1e-2)


def steel(law=None):
    """(ball, jar, ball-ball law, ball-wall law, friction) of the thesis' steel set."""
    return pair_contact("steel-steel", law=law)


def elastic(law: NormalLaw) -> NormalLaw:
    """The same law without damping (pure Hertz)."""
    return NormalLaw("adams-impact", law.k, 1.5, 0.0, law.d, law.m_eff, 1.0, law.u_ref)


def dt_for(law: NormalLaw, v: float, steps_per_contact: int) -> float:
    t_c = laws_np.simulate_impact(law.law_id, law.k, law.n, law.c, law.d, law.m_eff, v)["duration"][0]
    return float(t_c / steps_per_contact)


def two_ball_impact(bb: NormalLaw, friction, v_rel, offset, *, dt):
    """Two 6 mm steel balls: ball 0 at rest, ball 1 approaching along -x at v_rel (m/s)
    with its centre `offset` (m) off the line in y; no gravity. Returns (final state,
    events)."""
    ball, jar, _, bw, _ = steel()
    r = ball.radius
    gap = 1e-6
    x1 = np.sqrt(max((2 * r + gap) ** 2 - offset**2, 0.0))
    pos = [[0.0, 0.0, 0.5], [x1, offset, 0.5]]
    vel = [[0.0, 0.0, 0.0], [-v_rel, 0.0, 0.0]]
    t_c = 3.0 * laws_np.simulate_impact(bb.law_id, bb.k, bb.n, bb.c, bb.d, bb.m_eff, v_rel)["duration"][0]
    steps = int((t_c + 2 * gap / v_rel) / dt) + 20
    spec = impact_spec(ball, jar, bb, bw, friction, pos, vel, gravity=0.0, dt=dt, steps=steps)
    return run_spec(spec)
