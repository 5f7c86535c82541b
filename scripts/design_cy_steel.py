"""The designer's acceptance study: on the thesis' CY steel set-up (P 4, 12 steel balls
of 12 mm, 200 rpm, presets/p4-cy-steel.toml) search the lifter family with K free in
[-3.4, -1] for the largest normal stress-event power (impact_power_normal), every design
by 3 short runs (4 s, analysis from 1 s), the thesis' jars HM, 1L, 3L, T and CY by the
same protocol at K = -1, -1.1, … -3.4 (each at its best), then 24 s confirmation runs
(analysis from 4 s, the thesis' window) of the winner and the references at their best K.

    nice python scripts/design_cy_steel.py --out design-cy-steel [--trials 100] [--tiny]

The study resumes where it stopped (same command). --tiny is the CI-sized version (a
handful of designs, 1.5 s runs). Prints the summary and the wall time; writes
OUT/wall_seconds.json beside the study's report.png, summary.md and best/*.toml.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from taimill import cli

ROOT = Path(__file__).resolve().parent.parent


def arguments(out: str, trials: int, tiny: bool) -> list[str]:
    common = ["design", str(ROOT / "presets" / "p4-cy-steel.toml"), "--out", out, "--family", "lifters",
              "--objective", "impact_power_normal:max", "--ratio=-3.4:-1", "--seed", "1"]
    if tiny:
        return common + ["--trials", str(min(trials, 4)), "--batch", "2", "--replicas", "2", "--duration", "1.5",
                         "--analysis-start", "1", "--reference-ratios=-2.6", "--confirm", "4.5"]
    return common + ["--trials", str(trials), "--batch", "16", "--replicas", "3", "--duration", "4",
                     "--analysis-start", "1", "--confirm", "24"]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="design-cy-steel", help="study folder")
    p.add_argument("--trials", type=int, default=100, help="designs to evaluate (3 runs each)")
    p.add_argument("--tiny", action="store_true", help="the CI-sized study")
    a = p.parse_args()
    t0 = time.perf_counter()
    code = cli.main(arguments(a.out, a.trials, a.tiny))
    wall = time.perf_counter() - t0
    if code == 0:
        (Path(a.out) / "wall_seconds.json").write_text(json.dumps({"wall_seconds": wall, "trials": a.trials, "tiny": a.tiny}))
    print(f"wall time {wall:.0f} s", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
