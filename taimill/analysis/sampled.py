"""The thesis' sampled estimator (§3.3, eq 3.8 with C = "points sampling collisions"):
MSC.Adams wrote its output every 1/step s (step = 100 per second); every contact active
at an output instant gave one point with its relative velocity *at that instant*. So
persistent rolling/sliding contacts count once per sample, and short impacts count
only if an output instant happens to fall inside them. Provided for like-for-like
comparison with the thesis' numbers; the event estimator (events.py) is the default.

Needs stored frames at least as often as the sampling rate (the store's trajectory
rate); each sample instant k/rate takes the nearest stored frame.
"""

from __future__ import annotations

import math

import numpy as np

from taimill.analysis.contacts import frame_contacts
from taimill.analysis.events import _split
from taimill.analysis.rungeometry import RunGeometry
from taimill.errors import ConfigError


class SampledStats:
    """Sampled estimator over [t0, t1) at `rate` samples per second (thesis: 100)."""

    def __init__(self, g: RunGeometry, radii, stored_rate: float, rate: float = 100.0,
                 t0: float = 0.0, t1: float = math.inf, source: str = "command line"):
        if not 0 < rate <= stored_rate * 1.01:  # the stored rate, rounded to whole steps (rules.frame_every)
            raise ConfigError(source, "--sampling-rate", rate,
                              f"(0, {stored_rate:g}] per s: the run stored frames at {stored_rate:g} per s")
        self.g, self.radii, self.rate = g, np.asarray(radii, float), rate
        self.t0, self.t1 = t0, t1
        self.tol = 0.5 / stored_rate
        self.last_k = -1
        self.samples = 0
        self.count = np.zeros(2, dtype=np.int64)
        self.se_n = np.zeros(2)
        self.se_t = np.zeros(2)

    def add(self, block: dict) -> None:
        for f, t in enumerate(block["time"]):
            k = int(round(t * self.rate))
            if k <= self.last_k or abs(t - k / self.rate) > self.tol or not self.t0 <= t < self.t1:
                continue
            self.last_k = k
            self.samples += 1
            w = self.g.jar.at(float(t))[0]
            c = frame_contacts(self.g, self.radii, block["position"][f], block["velocity"][f], block["spin"][f], w)
            kind = (c["j"] < 0).astype(np.intp)
            np.add.at(self.count, kind, 1)
            np.add.at(self.se_n, kind, 0.5 * c["m_eff"] * c["un"] ** 2)
            np.add.at(self.se_t, kind, 0.5 * c["m_eff"] * c["ut"] ** 2)

    def result(self, tau: float, volume: float | None = None) -> dict:
        per = (lambda s: s / tau if tau > 0 else math.nan)
        n = int(self.count.sum())
        out = {"estimator": f"sampled at {self.rate:g}/s", "samples": self.samples}
        out.update(_split("", n, float(self.se_n.sum()), float(self.se_t.sum()), per))
        for k, name in enumerate(("ball_ball", "ball_wall")):
            out.update(_split(f"_{name}", int(self.count[k]), float(self.se_n[k]), float(self.se_t[k]), per))
        out["points"] = out.pop("events")
        for name in ("ball_ball", "ball_wall"):
            out[f"points_{name}"] = out.pop(f"events_{name}")
        if volume:
            out["impact_power_density"] = out["impact_power"] / volume
        return out
