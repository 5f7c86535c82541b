"""Allowed ranges of every value a user sets, in the units of the files and the user
interfaces: one table for the preset loader (and so the command line, whose options
are preset overrides) and the live mill of the TUI."""

from __future__ import annotations

import math
from dataclasses import dataclass

from taimill.errors import ConfigError


@dataclass(frozen=True)
class Range:
    lo: float | None  #: None: unbounded
    hi: float | None
    unit: str = ""
    lo_open: bool = False  #: lo itself is not allowed
    live: tuple[float, float] | None = None  #: narrower [lo, hi] for a running mill

    @property
    def live_bounds(self) -> tuple[float, float]:
        """[lo, hi] for a running mill."""
        return self.live or (self.lo, self.hi)

    @property
    def bounds(self) -> dict:
        """Keyword arguments of the preset reader's range check."""
        return {"lo": self.lo, "hi": self.hi, "lo_open": self.lo_open}

    def check_live(self, source: str, key: str, value):
        """value if it is a finite number within the live range, else ConfigError
        naming key, value and range."""
        lo, hi = self.live_bounds
        ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
        if not ok or not lo <= value <= hi:
            unit = f" {self.unit}" if self.unit else ""
            raise ConfigError(source, key, value, f"allowed range [{lo:g}, {hi:g}]{unit}")
        return value


# A negative Ω is the mirror image of a positive one, so a running mill takes Ω ≥ 0;
# its ball count is what a terminal view can draw. plate_rpm is the global sanity cap:
# a mill with known plate speeds replaces it (taimill.model.mills.Mill.plate_range).
RANGES: dict[str, Range] = {
    "plate_rpm": Range(-1000, 1000, "rpm", live=(0.0, 1000.0)),
    "ratio": Range(-10, 10),
    "jar_rpm": Range(-3000, 3000, "rpm"),
    "ramp_time": Range(0, None, "s", lo_open=True, live=(0.01, 60.0)),  # a preset's is also ≤ its duration
    "mu_s": Range(0, 10),
    "mu_d": Range(0, 10),
    "mu_r": Range(0, 10),
    "balls.count": Range(1, 1_000_000, live=(1, 2000)),
    # R_p of a mill file and of a preset (which overrides the mill's for sensitivity
    # studies): up to 2000 mm admits every shipped mill (60.8-150 mm) and the
    # all-but-resting plate of scripts/bench.py (2000 mm). The lower bound that matters
    # is the jar's radius (rules.plate_fits_jar), which also catches a slip of units
    # (0.07 for 70 mm) with its reason.
    "plate_radius_mm": Range(0, 2000, "mm", lo_open=True),
}
