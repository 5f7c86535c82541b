"""`taimill advise`: which plate speed for a mill, bowl and charge, and what that answer
hinges on. One sweep (taimill.runs.sweep, the same points as `taimill sweep`) over the
plate speeds × the friction μ of the pair where nobody measured it × replicas; the
table, the flag and the recommendation are taimill.analysis.advise.

The friction levels (mu_levels). A pair whose μ_s and μ_d were measured (a built-in pair
with no estimate among them: the thesis' pairs) runs as it is, one level, its μ_d. Any
other friction — an estimate such as `dry-ceramic-powder`, a pair file (it names no
source), coefficients set by hand in a preset — runs at three Coulomb levels μ = μ_s =
μ_d (as `taimill sweep --mu` sets them): LOW_MU, the run's own μ_d, HIGH_MU. The span is
the one results/standard_gear_evidence.md found no source to narrow for powder-coated
media: from the thesis' steel-graphite pair (μ_s 0.1) to bare media (steel-steel μ_d
0.8, zirconia-zirconia μ_s 0.8). A span set by the estimate (×0.5 … ×2 of it: 0.1 … 0.4
for dry-ceramic-powder) was not taken: it stops below μ 0.45, where the PM 100 charge of
that evidence (80 ml zirconia bowl, 25 × 5 mm zirconia balls, 400 rpm) is already a
hopping crescent instead of the impact-free bed it is at μ 0.2, so it could miss the one
switch known to matter. `--mu` replaces the levels.
"""

from __future__ import annotations

import math
from pathlib import Path

from taimill.errors import ConfigError

LOW_MU = 0.1  #: the thesis' steel-graphite μ_s: the most slippery coated media the project holds
HIGH_MU = 0.8  #: bare media: steel-steel μ_d (thesis Table 3.3), zirconia-zirconia μ_s
DEFAULT_SPEEDS = 5  #: plate speeds spread over the mill's range when none are given
SPEED_STEP = 10.0  #: rpm: the spread speeds are rounded to it (inside the range)


def mu_levels(preset) -> tuple[list[float] | None, str]:
    """(the friction levels to sweep, or None to run the pair as it is; a line saying
    which and why) for a loaded preset (taimill.model.preset.Preset)."""
    from taimill.model.materials import load_friction, pair_friction_measured

    bb = preset.frictions[0]
    own = load_friction(preset.pair, "advise")[0]
    same = (bb.mu_s, bb.mu_d, bb.mu_r) == (own.mu_s, own.mu_d, own.mu_r)
    name = Path(preset.pair).name
    if same and pair_friction_measured(preset.pair):
        return None, (f"friction: the pair {name} as measured (μ_s {bb.mu_s:g}, μ_d {bb.mu_d:g}), not varied; "
                      "--mu varies it")
    why = ("coefficients set by hand in the preset, no source" if not same
           else "a pair file, which names no source" if preset.pair.endswith(".toml")
           else "an estimate, not a measurement")
    levels = sorted({LOW_MU, round(bb.mu_d, 10), HIGH_MU})
    return levels, (f"friction μ = μ_s = μ_d at {', '.join(f'{m:g}' for m in levels)}: the friction of {name} is {why}; "
                    f"its μ_d {bb.mu_d:g} and the span of coated to bare media, {LOW_MU:g} (graphite-like) to "
                    f"{HIGH_MU:g} (bare steel or zirconia) (docs/advise.md)")


def default_speeds(mill, n: int = DEFAULT_SPEEDS) -> list[float]:
    """`n` plate speeds (rpm) spread evenly over the mill's range, rounded to SPEED_STEP
    but never outside it. A mill file without a highest speed refuses: the speeds must
    be given."""
    hi = mill.plate_rpm_max
    if hi is None:
        raise ConfigError("command line", "--plate-rpm", None,
                          f"the mill {mill.name} states no plate speed range: give the speeds, e.g. --plate-rpm 100:400:100")
    lo = mill.plate_rpm_min or hi / n  # a range known only at its top: start at a fifth of it
    speeds = [lo + (hi - lo) * i / (n - 1) for i in range(n)]
    rounded = [min(hi, max(lo, SPEED_STEP * math.floor(s / SPEED_STEP + 0.5))) for s in speeds]  # halves up
    rounded[0], rounded[-1] = lo, hi  # the range's own ends
    return list(dict.fromkeys(round(s, 9) for s in rounded))


def request(preset: str, overrides: dict, speeds: list[float], mus: list[float] | None, replicas: int):
    """The sweep (taimill.runs.sweep.Request): plate speed × μ (when there are levels) ×
    replicas."""
    # zarr and the executors: loaded when a sweep is made, not for `taimill --help`
    from taimill.runs.sweep import Request

    axes = {"plate_rpm": list(speeds)}
    if mus is not None:
        axes["friction.mu"] = list(mus)
    return Request(preset, overrides, axes, replicas)

