#!/usr/bin/env python
"""Write the SYNTHETIC size distributions of docs/outcome.md ("Fitting the population
balance") into examples/outcome/sizes.csv.

Nothing here was simulated or measured. The population balance itself
(taimill.outcome.grinding) at the TRUTH parameters grinds a log-normal feed (x50
FEED_X50_UM µm, σ of ln x FEED_SPREAD) at the example conditions a and b (made by
make_outcome_example.py); their cumulative distributions at the √2 class edges from
TOP_UM down to FINEST_UM are written at time 0 (the feed, exact) and after HOURS, each
share above 0.5 % and below 99.5 % times (1 + NOISE · N(0, 1)) (seed SEED), then made
cumulative as an instrument reports it (never falling, at most 100 %). The truth is
known, so a fit can be checked.

    python scripts/make_sizes_example.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from taimill.outcome import sizes_fit as sf
from taimill.outcome.condition import read_file
from taimill.outcome.grinding import SizeClasses, evolve, feed, passing

TRUTH = {"f_mat": 0.02, "xw_min": 0.05, "phi": 0.4, "gamma": 0.9}  #: capture_g 1 mg and beta 3.5: sizes_fit.HELD
FEED_X50_UM, FEED_SPREAD = 200.0, 0.5
TOP_UM, FINEST_UM = 800.0, 2.0
HOURS = (0.25, 1.0, 4.0)
NOISE, SEED = 0.02, 1
CONDITIONS = ("condition-a.json", "condition-b.json")


def generate(out: Path, conditions: Path | None = None) -> None:
    conditions = conditions or Path(__file__).resolve().parent.parent / "examples" / "outcome"
    classes = SizeClasses.spanning(FINEST_UM * 1e-6, TOP_UM * 1e-6)
    m0 = feed(classes, FEED_X50_UM * 1e-6, FEED_SPREAD)
    g = sf.grinding(TRUTH, "dissipated_normal", True)
    rng = np.random.default_rng(SEED)
    x = classes.edges[::-1]
    lines = ["# SYNTHETIC: the population balance at f_mat 0.02 kg/(J m), xw_min 0.05 J m/kg, phi 0.4, gamma 0.9",
             "# (capture_g 1 mg, beta 3.5), 2 % noise; made by scripts/make_sizes_example.py, not measured",
             "condition,time_h,size_um,passing_pct"]
    for name in CONDITIONS:
        a = sf.rates(g, classes, read_file(conditions / name))
        q0 = passing(classes, m0)[0][::-1]
        keep = q0 > 0.0005
        lines += [f"{name},0,{xi * 1e6:.6g},{qi * 100:.6g}" for xi, qi in zip(x[keep], q0[keep])]
        for h, row in zip(HOURS, passing(classes, evolve(a, m0, [h * 3600 for h in HOURS]))):
            row = row[::-1]
            keep = (row > 0.005) & (row < 0.995)
            noisy = np.minimum(np.maximum.accumulate(row[keep] * (1 + NOISE * rng.standard_normal(keep.sum()))), 1.0)
            lines += [f"{name},{h:g},{xi * 1e6:.6g},{qi * 100:.6g}" for xi, qi in zip(x[keep], noisy)]
    out.mkdir(parents=True, exist_ok=True)
    (out / "sizes.csv").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    generate(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "examples" / "outcome")
