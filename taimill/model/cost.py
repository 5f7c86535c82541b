"""What a simulation costs in CPU time, from the measured cost per step (docs/performance.md,
the preset table, 2-core AMD EPYC): ≈ 0.1 µs a mill-step plus 25 ns a flying ball, up to
≈ 130 ns a ball in a bed rolling on the wall. Used to tell a user how long a run takes,
to refuse one of hours nobody asked for, and to keep a kernel launch short enough that
Ctrl-C is seen soon."""

from __future__ import annotations

STEP_US = 0.1  #: µs of CPU per mill-step
BALL_US = (0.025, 0.13)  #: µs of CPU per ball-step: (flying balls, a bed on the wall)


def step_seconds(balls: int) -> tuple[float, float]:
    """(low, high) CPU seconds of one step of one mill of `balls` balls."""
    return tuple((STEP_US + b * balls) * 1e-6 for b in BALL_US)


def run_seconds(preset) -> tuple[float, float, float]:
    """(steps, low, high CPU seconds) of a run of `preset` (its duration at its dt)."""
    steps = preset.duration / preset.dt
    lo, hi = step_seconds(preset.balls.count)
    return steps, steps * lo, steps * hi
