#!/usr/bin/env python
"""Write the SYNTHETIC example data of docs/outcome.md into examples/outcome/.

Nothing here was simulated or measured. Three milling conditions are made up as
log-normal spectra of dissipated energy, and "measured" converted fractions are drawn
from the critical-collision model with known parameters plus Gaussian noise, so that
a fit can be checked against the truth. Every number is stated below.

Conditions (SPECTRA): per condition, N_EVENTS events spread over N_EVENTS / rate
seconds, all ball-wall stress events; the dissipated normal energy of the events is
log-normal (median, sd of log10 E), placed at the N_EVENTS quantiles (no random draw);
the friction energy is FRICTION_SHARE of it; the kinematic stress energy is
E_diss / (1 − e²) with e = RESTITUTION (the share of the onset energy a normal damper
with restitution e dissipates), all normal. Powder: POWDER_G per jar.

Points: TRUTH (κ_g, E*) on the dissipated normal energy; α at TIMES_MIN on conditions
a and b, plus noise N(0, SIGMA²) (seed SEED), clipped to [0, 1], with sigma = SIGMA.
points-same-shape.csv: the same on condition a and on a-scaled, a copy of a at a third
of its rate: spectra of the same shape, from which E* cannot be found.

    python scripts/make_outcome_example.py [OUT_DIR]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from taimill.model.spectra import from_rows
from taimill.outcome.condition import Condition, write_file
from taimill.outcome.models import CriticalCollisions

N_EVENTS = 20000
POWDER_G = 5.0
FRICTION_SHARE = 0.2
RESTITUTION = 0.8
STRESS_UN = 0.01  #: m/s, the class threshold the spectra record (every event lies above it)
#: name -> (median dissipated normal energy J, sd of log10 E, events per second)
SPECTRA = {"a": (5e-4, 0.5, 3000.0), "b": (5e-3, 0.4, 800.0), "c": (2e-3, 0.45, 1500.0),
           "a-scaled": (5e-4, 0.5, 1000.0)}
TRUTH = {"kappa_g": 2e-5, "e_star_J": 3e-3}
TIMES_MIN = (5, 10, 20, 40, 60, 90, 120)
SIGMA = 0.03
SEED = 1
NOTE = ("SYNTHETIC example data made by scripts/make_outcome_example.py, not a simulation: "
        "log-normal dissipated normal energy, median {:g} J, sd of log10 E {:g}, {:g} events/s")


def spectra(median: float, sd: float, rate: float):
    e = 10.0 ** (math.log10(median) + sd * stats.norm.ppf((np.arange(N_EVENTS) + 0.5) / N_EVENTS))
    m = np.full(N_EVENTS, 1e-3)  # kg, an effective mass; only the products below matter
    rows = {"t_start": np.zeros(N_EVENTS), "kind": np.ones(N_EVENTS, dtype=np.int64),
            "m_eff": m, "un": np.sqrt(2 * e / (1 - RESTITUTION**2) / m), "ut": np.zeros(N_EVENTS),
            "dissipated_normal": e, "dissipated_friction": FRICTION_SHARE * e}
    return from_rows(rows, 0.0, N_EVENTS / rate, STRESS_UN)


def points(conds: dict, names: tuple[str, ...], seed: int) -> str:
    model, rng = CriticalCollisions("dissipated_normal"), np.random.default_rng(seed)
    lines = ["# SYNTHETIC measurements (scripts/make_outcome_example.py): critical-collision model, "
             f"kappa_g = {TRUTH['kappa_g']:g} g, E* = {TRUTH['e_star_J']:g} J (dissipated normal), "
             f"noise sd {SIGMA:g}, seed {seed}", "condition,time_s,value,sigma"]
    for n in names:
        t = np.array(TIMES_MIN, dtype=float) * 60.0
        y = np.clip(model.value(TRUTH, conds[n], t) + rng.normal(0.0, SIGMA, len(t)), 0.0, 1.0)
        lines += [f"condition-{n}.json,{ti:g},{yi:.4f},{SIGMA:g}" for ti, yi in zip(t, y)]
    return "\n".join(lines) + "\n"


def generate(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    conds = {}
    for name, (median, sd, rate) in SPECTRA.items():
        sp = spectra(median, sd, rate)
        write_file(out / f"condition-{name}.json", sp, POWDER_G, NOTE.format(median, sd, rate))
        conds[name] = Condition(name, sp, POWDER_G)
    (out / "points.csv").write_text(points(conds, ("a", "b"), SEED))
    (out / "points-same-shape.csv").write_text(points(conds, ("a", "a-scaled"), SEED))


if __name__ == "__main__":
    generate(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "examples" / "outcome")
