"""The jar frame's drive in NumPy: start-up / live-change ramps of the plate speed Ω
and the absolute jar spin w (docs/model.md), twin of the Taichi functions in frame.py.

A ramp goes smoothly from `start` to `end` (rad/s) over `duration` s from time `t0`,
with the smoothstep s²(3-2s), so its derivative (the Euler term) is continuous and
real. Its angle is integrated in closed form: ∫ step = T·P(τ/T), P(s) = s³ - s⁴/2.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Ramp:
    t0: float  #: s
    start: float  #: rad/s
    end: float  #: rad/s
    duration: float  #: s
    phase0: float = 0.0  #: rad, angle at t0

    def as_tuple(self):
        return (self.t0, self.start, self.end, self.duration, self.phase0)

    def at(self, t: float) -> tuple[float, float, float]:
        """(speed rad/s, acceleration rad/s², angle rad) at time t ≥ t0."""
        tau = max(t - self.t0, 0.0)
        s = min(tau / self.duration, 1.0)
        delta = self.end - self.start
        speed = self.start + delta * s * s * (3.0 - 2.0 * s)
        accel = delta * 6.0 * s * (1.0 - s) / self.duration if tau < self.duration else 0.0
        integral = s**3 - 0.5 * s**4 if tau < self.duration else tau / self.duration - 0.5
        return speed, accel, self.phase0 + self.start * tau + delta * self.duration * integral
