"""How the headline outputs move when the contacts are softened (docs/softening.md).

    .venv/bin/python scripts/softening_validation.py [--factors 1,2,3,5,10] [--seeds 1,2,3]
        [--duration 8] [--beads-seconds 0.002] [--json out.json]

For each factor: CY steel (12 steel balls, K = −2.6, 200 rpm; window 4 s … duration)
over the seeds, its stress-event rate, median and P90 of the energy dissipated per
stress event, the kinematic stress energy, the dissipated power by class, the regime;
each as the seeds' mean and its change against factor 1. Then the bead presets' cost:
simulated seconds per CPU hour of a short run (their start-up ramp alone lasts 1 s;
their outputs at steady state need hours per factor and are not measured here).
One process, one thread; CPU time of the runs (time.process_time).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

os.environ.setdefault("TI_CPU_MAX_NUM_THREADS", "1")
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from taimill.model.preset import load_preset  # noqa: E402
from taimill.runs.simulation import run  # noqa: E402

HEADLINE = {
    "collision_rate": ("stress-event rate", "1/s"),
    "median_dissipated": ("median energy dissipated per stress event (normal + friction spectra)", "J"),
    "p90_dissipated_normal": ("P90 of the normal dissipation per stress event", "J"),
    "mean_se": ("mean kinematic stress energy", "J"),
    "dissipated_power": ("dissipated power", "W"),
    "dissipated_power_impact": ("dissipated in impacts", "W"),
    "dissipated_power_persistent": ("dissipated in persistent contacts", "W"),
}


def headline(s: dict) -> dict:
    sp = s["spectra"]
    return {"collision_rate": s["collision_rate"],
            "median_dissipated": sp["dissipated_normal"]["median"] + sp["dissipated_friction"]["median"],
            "p90_dissipated_normal": sp["dissipated_normal"]["p90"], "mean_se": s["mean_se"],
            "dissipated_power": s["dissipated_power"], "dissipated_power_impact": s["dissipated_power_impact"],
            "dissipated_power_persistent": s["dissipated_power_persistent"], "regime": s["regime"], "dt": s["dt"]}


def cy_steel(factor: float, seed: int, duration: float) -> dict:
    p = load_preset("p4-cy-steel", {"softening": factor, "seed": seed, "duration": duration, "analysis_start": 4.0,
                                    "ratio": -2.6})
    t0 = time.process_time()
    s = run(p)
    return headline(s) | {"cpu_seconds": time.process_time() - t0}


def beads(name: str, factor: float, seconds: float) -> dict:
    frames = {"outputs.trajectory_rate": 4.0 / seconds}  # a few frames: the bead presets' 50 Hz has none in 2 ms
    p = load_preset(name, {"softening": factor, "duration": seconds, "analysis_start": seconds / 2} | frames)
    run(load_preset(name, {"softening": factor, "duration": seconds / 4, "analysis_start": 0.0} | frames))  # compile first
    t0 = time.process_time()
    s = run(p)
    cpu = time.process_time() - t0
    return {"preset": name, "factor": factor, "dt": s["dt"], "sim_seconds": seconds, "cpu_seconds": cpu,
            "sim_seconds_per_cpu_hour": seconds / cpu * 3600}


def print_table(rows: dict, factors: list, a) -> None:
    base = rows[factors[0]]
    print(f"\nCY steel, K = -2.6, 200 rpm, seeds {a.seeds}, window 4-{a.duration:g} s: change against factor {factors[0]:g} "
          "(the seeds' half range in brackets)")
    print("| output | " + " | ".join(f"÷{f:g}" for f in factors) + " |")
    print("|---|" + "---|" * len(factors))
    for k, (text, unit) in HEADLINE.items():
        cells = [f"{(rows[f][k] / base[k] - 1) * 100:+.1f} % (±{rows[f]['spread'][k] / base[k] * 100:.1f})" for f in factors]
        print(f"| {text} ({base[k]:.4g} {unit} at ÷{factors[0]:g}) | " + " | ".join(cells) + " |")
    print("| regime | " + " | ".join(", ".join(rows[f]["regimes"]) for f in factors) + " |")
    print("| time step (µs) | " + " | ".join(f"{rows[f]['dt'] * 1e6:.3g}" for f in factors) + " |")
    print("| CPU s per run | " + " | ".join(f"{rows[f]['cpu_seconds']:.3g}" for f in factors) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--factors", default="1,2,3,5,10")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--duration", type=float, default=8.0)
    ap.add_argument("--beads-seconds", type=float, default=0.002)
    ap.add_argument("--bead-factors", default="1,3,10,100")
    ap.add_argument("--json")
    a = ap.parse_args()
    factors = [float(f) for f in a.factors.split(",") if f]  # --factors "": the bead presets only
    seeds = [int(s) for s in a.seeds.split(",")]
    rows = {}
    for f in factors:
        runs = [cy_steel(f, s, a.duration) for s in seeds]
        rows[f] = {k: statistics.fmean(r[k] for r in runs) for k in (*HEADLINE, "dt", "cpu_seconds")}
        rows[f]["spread"] = {k: (max(r[k] for r in runs) - min(r[k] for r in runs)) / 2 for k in HEADLINE}
        rows[f]["regimes"] = sorted({r["regime"] for r in runs})
        print(f"factor {f:g}: " + ", ".join(f"{k} {rows[f][k]:.4g}" for k in (*HEADLINE, "dt")), flush=True)
    if factors:
        print_table(rows, factors, a)
    bead = []
    if a.beads_seconds > 0:
        for name in ("p4-zr500-beads-3mm", "p4-zr80-beads-1mm"):
            for f in (float(x) for x in a.bead_factors.split(",")):
                bead.append(beads(name, f, a.beads_seconds))
                b = bead[-1]
                print(f"{name} ÷{f:g}: dt {b['dt'] * 1e6:.3g} µs, {b['sim_seconds_per_cpu_hour']:.3g} simulated s per CPU hour",
                      flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"cy_steel": {str(k): v for k, v in rows.items()}, "beads": bead}, fh, indent=1)


if __name__ == "__main__":
    main()
