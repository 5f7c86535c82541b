"""The drive of a planetary mill, the one place where its speeds are converted.

The plate turns at Ω about its axis; the jar's axis is carried at R_p from it and the
jar turns at ω *relative to the plate* (the thesis drives the hinge between jar and
plate). The speed ratio is K = ω/Ω + 1, the jar's absolute spin over Ω: K < 0 is
counter-rotation, K = 0 a jar that translates without turning, K = 1 a jar fixed to
the plate. Inside taimill the drive is (Ω, w = KΩ = ω + Ω) in rad/s; files and the
user interfaces speak rpm and K or ω.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from taimill.model.frame import Ramp

RPM = 2.0 * math.pi / 60.0  #: rad/s per rpm


@dataclass(frozen=True)
class Drive:
    """Target speeds of a run, reached from rest (or from the current speeds after a
    live change) by smoothstep ramps of `ramp_time`."""

    plate_omega: float  #: Ω, rad/s
    jar_spin: float  #: w = KΩ = ω + Ω, absolute spin of the jar, rad/s
    ramp_time: float = 1.0  #: s

    @classmethod
    def from_rpm(cls, plate_rpm: float, *, ratio: float | None = None, jar_rpm: float | None = None,
                 ramp_time: float = 1.0) -> "Drive":
        """Ω in rpm and the jar speed as K or as ω (rpm, relative to the plate)."""
        if (ratio is None) == (jar_rpm is None):
            raise ValueError("give exactly one of ratio and jar_rpm")
        om = plate_rpm * RPM
        w = ratio * om if ratio is not None else jar_rpm * RPM + om
        return cls(om, w, ramp_time)

    @classmethod
    def from_config(cls, config: dict) -> "Drive":
        """The drive of a stored run's resolved configuration."""
        return cls(float(config["plate_omega"]), float(config["jar_spin"]), float(config.get("ramp_time", 1.0)))

    @property
    def ratio(self) -> float:
        """K = w/Ω (nan for Ω = 0)."""
        return self.jar_spin / self.plate_omega if self.plate_omega else math.nan

    @property
    def plate_rpm(self) -> float:
        """Ω, rpm."""
        return self.plate_omega / RPM

    @property
    def jar_rpm(self) -> float:
        """ω = w − Ω, the jar's speed relative to the plate, rpm."""
        return (self.jar_spin - self.plate_omega) / RPM

    @property
    def relative_spin(self) -> float:
        """ω = w − Ω, rad/s (the speed of the jar wall past the charge is |ω|·r)."""
        return self.jar_spin - self.plate_omega

    def retarget(self, plate_rpm: float | None = None, *, ratio: float | None = None, jar_rpm: float | None = None,
                 ramp_time: float | None = None) -> "Drive":
        """New targets: Ω (rpm) and the jar speed as K or ω; with neither, K is kept
        (ω when Ω is 0, where K is undefined)."""
        om = plate_rpm * RPM if plate_rpm is not None else self.plate_omega
        if ratio is not None:
            w = ratio * om
        elif jar_rpm is not None:
            w = jar_rpm * RPM + om
        elif self.plate_omega:
            w = self.jar_spin / self.plate_omega * om
        else:
            w = self.jar_spin - self.plate_omega + om
        return Drive(om, w, self.ramp_time if ramp_time is None else ramp_time)

    def start_up(self) -> tuple[Ramp, Ramp]:
        """(Ω(t), w(t)) ramps from rest at t = 0."""
        return Ramp(0.0, 0.0, self.plate_omega, self.ramp_time), Ramp(0.0, 0.0, self.jar_spin, self.ramp_time)

    def as_dict(self) -> dict:
        """Plain data with every form of the speeds (for stores and summaries)."""
        return {"plate_omega": self.plate_omega, "jar_spin": self.jar_spin, "ramp_time": self.ramp_time,
                "ratio": self.ratio, "plate_rpm": self.plate_rpm, "jar_rpm": self.jar_rpm}
