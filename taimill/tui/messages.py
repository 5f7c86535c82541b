"""Messages between the simulation worker, the widgets and the app (small dataclasses;
the frequent ones replace an unhandled predecessor, so a slow screen skips frames
instead of queueing them)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from textual.message import Message


# ---- worker -> app
@dataclass
class FrameReady(Message):
    """The mill's state for the views."""

    sim_time: float  #: s, simulated (Message.time is the posting time)
    position: np.ndarray  #: (N, 3) m, jar frame
    psi: float  #: rad, direction away from the plate axis in the jar frame
    plate: float  #: Ω now, rad/s
    jar: float  #: w now, rad/s (absolute jar spin)
    realtime: float  #: simulated s per wall s, recent (nan while paused)

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, FrameReady)


@dataclass
class ReadoutsReady(Message):
    """Sliding-window figures (summary keys, docs/outputs.md) and their recent history."""

    values: dict
    history: dict  #: name -> list of recent values

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, ReadoutsReady)


@dataclass
class SimFault(Message):
    """The simulation stopped: unstable (docs/model.md, faults); the text says why."""

    text: str


@dataclass
class Notice(Message):
    """A line for the message bar (file written, value refused, …)."""

    text: str
    error: bool = False


@dataclass
class WriteFailed(Message):
    """A file the app writes (a recording, a PNG) could not be written: the app says so,
    ends the recording of `kind` if one is open, goes on, and exits non-zero at the end."""

    error: BaseException  #: the refusal (StoreWriteError, OSError)
    kind: str | None = None  #: "rrd" or "zarr" for a recording


# ---- controls -> app
@dataclass
class SpeedsRequested(Message):
    """New targets: Ω (rpm) and the jar speed as K or ω (rpm), ramp time (s)."""

    plate_rpm: float
    ratio: float | None = None
    jar_rpm: float | None = None
    ramp_time: float | None = None


@dataclass
class FrictionRequested(Message):
    """Friction of both contact kinds (kind None) or of "ball_ball" or "ball_wall" alone."""

    mu_s: float | None = None
    mu_d: float | None = None
    pair: str | None = None
    mu_r: float | None = None
    kind: str | None = None


@dataclass
class RebuildRequested(Message):
    """A new jar (name in jars/) and/or ball count: the mill restarts at t = 0."""

    jar: str | None = None
    balls: int | None = None
