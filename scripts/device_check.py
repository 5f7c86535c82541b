#!/usr/bin/env python
"""The device check: what taimill does on a GPU machine, in one table, within 8 minutes.
Run it through scripts/device_check.sh, which puts the packed Taichi (.device/) on the
path; it installs nothing. Every figure comes from `python -m taimill run` children,
end to end through the command line, each on its backend (TAIMILL_BACKEND) and thread
count (TI_CPU_MAX_NUM_THREADS):

1. Dense bed: bench.py's simple-cubic lattice (dense_case, lattice "sc": every contact
   closing at once, the plate at rest) of 10⁵ and 10⁶ balls (--quick: 10⁴ and 6·10⁴),
   on CUDA and on the CPU with each of --threads (default 1, 4, 16): wall ns per
   ball-step from the difference of a run of N2 steps and one of N1 (bench.py
   per_ball_step: start-up, imports and reading the start cancel), each after an
   untimed run of N1 steps that compiles what Taichi's cache lacks (its kernels are
   cached per arch, thread count and ball count). N2 − N1 is budgeted from today's
   figures (CPU ≈ 94 ns a ball-step on one thread, 20 on 16; CUDA ≈ 9) so that the
   difference takes about DIFF_SECONDS; N1 is the same on every backend, so the N1
   runs are compared (3).
2. Beads: p4-zr80-beads-1mm, simulated seconds per hour on CUDA and on the most
   threads, extrapolated from a run of BEAD_STEPS steps (its realtime_factor, set-up
   and compiling left out, × 3600). Those steps are the start, beads falling from
   their placement: a settled bed costs more a step, so this is an upper bound.
3. Agreement: every summary key of a CUDA run against the CPU run of the same case
   (the 10⁵ bed's N1 runs; the golden CY steel case, 0.3 s): the largest relative
   difference, its key, and whether every event count is equal. The CPU's thread
   counts are compared the same way (to the bit, by design).

--backend cpu is a dry run where no GPU is: the "cuda" rows run on the CPU with all
its cores. Rows that would start after --budget seconds are listed as skipped.

    scripts/device_check.sh [--backend cuda|cpu] [--threads 1,4,16] [--quick] [--skip-million] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT))

import bench  # dense_case, run_child, per_ball_step, DENSE_DT

SIZES = (100_000, 1_000_000)
QUICK_SIZES = (10_000, 60_000)
DIFF_SECONDS = {100_000: 3.0, 1_000_000: 5.0}  # wall seconds the N2 − N1 steps should take
QUICK_DIFF_SECONDS = 3.0
# today's wall ns a ball-step (issue 49, one H100 machine, 16 cores): CPU one thread 94,
# and an Amdahl serial share of 0.16 (4 threads 34, 16 threads 20); CUDA 9, budgeted as 6
# so that a faster CUDA still runs long enough to measure. Only the step counts use them.
CPU_NS, SERIAL_SHARE, CUDA_NS = 94.0, 0.16, 6.0
FUSED_CUDA_NS = 500.0  # a guess: a fused mill on a GPU is one GPU thread
BEADS = "p4-zr80-beads-1mm"
BEAD_STEPS = 1000
SMALL = ("presets/p4-cy-steel.toml", "--duration", "0.3", "--seed", "3")  # tests/test_golden.py's cy-steel, shorter
# s: rows that would start later are skipped, and a run still going BUDGET + OVERRUN s
# after the start is stopped (the row says so): the check ends within 8 minutes
BUDGET, OVERRUN = 390.0, 80.0
TOLERANCE = 1e-9  # relative, every summary key (issue 49)
MACHINE_KEYS = ("wall_seconds", "realtime_factor", "compute")  # taimill.schema.MACHINE_KEYS


# ---------------------------------------------------------------- comparing summaries
def summary_difference(a: dict, b: dict, skip=MACHINE_KEYS) -> dict:
    """Every key of two run summaries compared, nested objects and lists too: the largest
    relative difference of their numbers (|x − y| / max(|x|, |y|)) and its key, the keys
    whose text, kind or presence differ (`unequal`), and whether every event count (a
    key that starts with "events") is equal."""
    worst = {"rel": 0.0, "key": None}
    unequal, counts = [], []

    def walk(x, y, path):
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y)):
                if path == "" and k in skip:
                    continue
                if k not in x or k not in y:
                    unequal.append(f"{path}{k}")
                else:
                    walk(x[k], y[k], f"{path}{k}.")
        elif isinstance(x, (list, tuple)) and isinstance(y, (list, tuple)):
            if len(x) != len(y):
                unequal.append(path.rstrip("."))
            for i, (u, v) in enumerate(zip(x, y)):
                walk(u, v, f"{path}{i}.")
        elif _number(x) and _number(y):
            key = path.rstrip(".")
            if key.split(".")[-1].startswith("events"):
                counts.append(x == y)
            if x == y or (math.isnan(x) and math.isnan(y)):
                return
            rel = abs(x - y) / max(abs(x), abs(y)) if math.isfinite(x) and math.isfinite(y) else math.inf
            if rel > worst["rel"]:
                worst.update(rel=rel, key=key)
        elif x != y:
            unequal.append(path.rstrip("."))

    walk(a, b, "")
    return dict(max_rel=worst["rel"], worst_key=worst["key"], unequal=unequal, events_equal=all(counts),
                event_counts=len(counts), events=a.get("events"))


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def agrees(d: dict) -> bool:
    return d["max_rel"] <= TOLERANCE and not d["unequal"] and d["events_equal"]


# ---------------------------------------------------------------- running children
def child_env(backend: str, threads: int | None) -> dict:
    """The child's environment: this checkout (and the packed Taichi, .device/, kept
    where device_check.sh put it) first on the path, the backend and thread count."""
    path = [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = os.environ | {"PYTHONPATH": os.pathsep.join(path), "TAIMILL_BACKEND": backend}
    env.pop("TI_CPU_MAX_NUM_THREADS", None)
    if threads:
        env["TI_CPU_MAX_NUM_THREADS"] = str(threads)
    return env


def taimill_run(args: list[str], backend: str, threads: int | None, log: Path, timeout: float) -> dict:
    """One `python -m taimill run … --json`: bench.run_child's wall, CPU and peak RSS, and the summary."""
    cmd = [sys.executable, "-m", "taimill", "run", *args, "--json"]
    r = bench.run_child(cmd, ROOT, timeout, child_env(backend, threads), log)
    r["summary"] = json.loads(r.pop("stdout"))
    r["steps"] = r["summary"]["steps"]
    return r


def expected_ns(backend: str, threads: int, n: int) -> float:
    from taimill.physics.runner import parallel_above  # which mode a mill of n balls runs in there

    fused = n <= parallel_above(backend, threads)
    if backend == "cuda":
        return FUSED_CUDA_NS if fused else CUDA_NS
    t = 1 if fused else threads
    return CPU_NS * (SERIAL_SHARE + (1 - SERIAL_SHARE) / t)


def bed_preset(tmp: Path, n: int, every: int) -> Path:
    """bench.dense_case's simple-cubic bed of n balls, frames every `every` steps, the
    events kept as spectra (bench.py's acceptance figure)."""
    preset = bench.dense_case(tmp / "beds", n, False, "sc")
    cli = preset.with_name(f"check-{every}.toml")  # beside the preset: its jar and start are relative paths
    rate = float(f"{1 / (every * bench.DENSE_DT):.9g}")
    cli.write_text(preset.read_text().split("[outputs]")[0] + f'[outputs]\ntrajectory_rate = {rate!r}\nevents = "spectra"\n')
    return cli


def steps_args(preset: Path, steps: int) -> list[str]:
    # whole frame intervals: from_preset rounds duration / (every dt); + ¼ step for the rounding
    return [str(preset), "--duration", repr((steps + 0.25) * bench.DENSE_DT)]


# ---------------------------------------------------------------- the check
class Check:
    def __init__(self, args):
        self.args, self.rows, self.t0 = args, [], time.perf_counter()
        self.cuda = args.backend  # what the "cuda" rows run on
        self.tmp = Path(tempfile.mkdtemp(prefix="taimill-device-check-"))

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def over_budget(self) -> bool:
        return self.elapsed() > self.args.budget

    def timeout(self) -> float:
        return max(10.0, self.args.budget + OVERRUN - self.elapsed())

    def add(self, check, on, threads, result, detail="", **numbers):
        row = dict(check=check, on=on, threads=threads, result=result, detail=detail, **numbers)
        self.rows.append(row)
        print(f"[{self.elapsed():5.0f} s] {check} | {on} | {threads} | {result} | {detail}", file=sys.stderr, flush=True)
        return row

    def configs(self) -> list[tuple[str, str, int | None]]:
        """(label, backend, threads): the "cuda" row first, then each CPU thread count."""
        return [("cuda" if self.cuda == "cuda" else "cuda (dry run: cpu)", self.cuda, None)] + \
               [("cpu", "cpu", t) for t in self.args.threads]

    def bed(self, n: int) -> dict:
        """Section 1 for n balls; returns the N1 runs' (label, summary), in configs' order."""
        diff = QUICK_DIFF_SECONDS if self.args.quick else DIFF_SECONDS[n]
        cores = os.cpu_count() or 1
        need = {(b, t): max(20, round(diff / (expected_ns(b, t or cores, n) * 1e-9 * n))) for _, b, t in self.configs()}
        n1 = math.ceil(min(need.values()) / 2)  # the slowest's N2 − N1 is 2 N1: its runs N1, N1, 3 N1
        preset = bed_preset(self.tmp, n, n1)
        firsts, one = [], None
        for label, backend, threads in self.configs():
            name = f"sc {n}"
            if self.over_budget():
                self.add(name, label, threads or "all", "skipped", f"over the {self.args.budget:g} s budget")
                continue
            n2 = n1 * (1 + max(1, math.ceil(need[backend, threads] / n1)))
            try:
                runs = []
                for k, steps in enumerate((n1, n1, n2)):  # the first compiles what the cache lacks: untimed
                    r = taimill_run(steps_args(preset, steps), backend, threads, self.tmp / f"sc{n}-{backend}-{threads}-{k}.log",
                                    self.timeout())
                    runs.append(r)
                fig = bench.per_ball_step(runs[1:], n)
            except RuntimeError as err:
                self.add(name, label, threads or "all", "failed", str(err))
                continue
            compute = runs[1]["summary"]["compute"]
            firsts.append((label, runs[1]["summary"]))
            detail = (f"{compute['backend']} {compute['device']}; steps {n1}→{n2}; set-up {fig['setup']:.1f} s "
                      f"(warm-up {runs[0]['wall']:.1f} s); CPU {fig['ns_cpu']:.1f} ns; peak RSS {fig['rss_mib']:.0f} MiB")
            if backend == "cpu" and threads == 1:
                one = fig["ns_wall"]
            elif backend == "cpu" and one and threads:
                detail += f"; efficiency {one / (threads * fig['ns_wall']):.2f}"
            self.add(name, label, compute["threads"] if backend == "cpu" else "-", f"{fig['ns_wall']:.2f} ns/ball-step",
                     detail, n=n, ns_wall=fig["ns_wall"], ns_cpu=fig["ns_cpu"], steps=[n1, n2], setup=fig["setup"],
                     rss_mib=fig["rss_mib"], compute=compute)
        return firsts

    def compare(self, what: str, runs: list[tuple[str, dict]]):
        """Section 3 on the runs of one case, (label, summary) each: the "cuda" run
        against the CPU's with the most threads, and the CPU's thread counts each
        against the next."""
        gpu = [s for label, s in runs if label != "cpu"]
        cpu = [s for label, s in runs if label == "cpu"]
        pairs = [(f"{runs[0][0]} vs cpu {cpu[-1]['compute']['threads']} threads", gpu[0], cpu[-1])] if gpu and cpu else []
        pairs += [(f"cpu {a['compute']['threads']} vs {b['compute']['threads']} threads", a, b) for a, b in zip(cpu, cpu[1:])]
        for on, a, b in pairs:
            d = summary_difference(a, b)
            detail = (f"worst key {d['worst_key']}; events {d['events']}; {d['event_counts']} event counts "
                      f"{'all equal' if d['events_equal'] else 'NOT all equal'}")
            if d["unequal"]:
                detail += f"; differing: {', '.join(d['unequal'][:5])}"
            self.add(f"agreement: {what}", on, "-", f"max rel {d['max_rel']:.1e}: {'equal' if agrees(d) else 'DIFFERENT'}",
                     detail, **d)

    def small(self):
        """Section 3 on the golden CY steel case: the "cuda" run and the most threads'."""
        runs = []
        for label, backend, threads in (self.configs()[0], self.configs()[-1]):
            if self.over_budget():
                self.add("agreement: CY steel 0.3 s", label, threads or "all", "skipped", "over budget")
                return
            try:
                r = taimill_run(list(SMALL), backend, threads, self.tmp / f"small-{backend}.log", self.timeout())
            except RuntimeError as err:
                self.add("agreement: CY steel 0.3 s", label, threads or "all", "failed", str(err))
                return
            runs.append((label, r["summary"]))
        self.compare("CY steel 0.3 s", runs)

    def beads(self):
        from taimill.model.preset import load_preset

        p = load_preset(BEADS)
        preset = self.tmp / "beads.toml"
        text = Path(p.source).read_text().split("[outputs]")[0]
        preset.write_text(text + f"[outputs]\ntrajectory_rate = {1 / (BEAD_STEPS * p.dt)!r}\n")
        most = max(self.args.threads)
        for label, backend, threads in (self.configs()[0], ("cpu", "cpu", most)):
            if self.over_budget():
                self.add(BEADS, label, threads or "all", "skipped", "over budget")
                continue
            try:
                r = taimill_run([str(preset), "--duration", repr((BEAD_STEPS + 0.25) * p.dt)], backend, threads,
                                self.tmp / f"beads-{backend}.log", self.timeout())
            except RuntimeError as err:
                self.add(BEADS, label, threads or "all", "failed", str(err))
                continue
            s = r["summary"]
            per_hour = s["realtime_factor"] * 3600
            self.add(BEADS, label, s["compute"]["threads"] if backend == "cpu" else "-",
                     f"{per_hour:.3g} simulated s per hour",
                     f"extrapolated from {s['steps']} steps ({s['sim_seconds']:.2g} s simulated, the beads falling "
                     f"from their placement) in {s['wall_seconds']:.1f} s; {s['compute']['device']}",
                     per_hour=per_hour, steps=s["steps"], wall=s["wall_seconds"], compute=s["compute"])

    def run(self):
        sizes = QUICK_SIZES if self.args.quick else SIZES
        if self.args.skip_million:
            sizes = tuple(n for n in sizes if n < 1_000_000)
        first = self.bed(sizes[0])
        self.compare(f"sc {sizes[0]}, {first[0][1]['steps'] if first else '-'} steps", first)
        self.small()
        self.beads()
        for n in sizes[1:]:
            runs = self.bed(n)
            self.compare(f"sc {n}, {runs[0][1]['steps'] if runs else '-'} steps", runs)


def machine_lines(backend: str) -> list[str]:
    from taimill.physics.backend import cpu_model, cuda_devices
    from taimill.physics.ti import describe

    gpus = ", ".join(cuda_devices()) or "none found"
    return [f"taimill device check, {time.strftime('%Y-%m-%d %H:%M:%S')}; the \"cuda\" rows ran on {backend}",
            f"machine: {os.cpu_count()} CPUs, {cpu_model()}; CUDA devices: {gpus}",
            f"software: Python {platform.python_version()}, {describe()}"]


def table(rows: list[dict]) -> str:
    head = ("check", "on", "threads", "result", "detail")
    cells = [head] + [tuple(str(r[k]) for k in head) for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(4)]
    lines = ["| " + " | ".join(c[i].ljust(widths[i]) if i < 4 else c[i] for i in range(5)) + " |" for c in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|---|")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="cuda", choices=("cuda", "cpu"),
                    help="what the \"cuda\" rows run on (default cuda; cpu: a dry run where no GPU is)")
    ap.add_argument("--threads", default="1,4,16", help="CPU thread counts, e.g. 1,2 (default 1,4,16)")
    ap.add_argument("--quick", action="store_true", help=f"beds of {QUICK_SIZES[0]} and {QUICK_SIZES[1]} balls, shorter")
    ap.add_argument("--skip-million", action="store_true", help="leave out the bed of 10⁶ balls")
    ap.add_argument("--budget", type=float, default=BUDGET, help=f"seconds after which no row starts (default {BUDGET:g})")
    ap.add_argument("--json", type=Path, metavar="FILE", help="write every number to FILE")
    args = ap.parse_args()
    try:
        args.threads = sorted({int(t) for t in args.threads.split(",")})
    except ValueError:
        ap.error(f"--threads {args.threads!r}: comma-separated integers, e.g. 1,4,16")
    from taimill.physics.backend import cuda_devices

    if args.backend == "cuda" and not cuda_devices():
        sys.exit("device_check: no CUDA device was found; --backend cpu makes a dry run on the CPU")
    check = Check(args)
    lines = machine_lines(args.backend)
    print("\n".join(lines), file=sys.stderr, flush=True)
    check.run()
    print("\n".join(lines))
    print(table(check.rows))
    print(f"took {check.elapsed():.0f} s; the bead figures are extrapolated from a short run of the start")
    if any(r["result"] == "failed" for r in check.rows):
        print(f"the failed runs' logs are in {check.tmp}")
    else:
        shutil.rmtree(check.tmp, ignore_errors=True)
    if args.json:
        args.json.write_text(json.dumps(dict(machine=lines, rows=check.rows, seconds=check.elapsed()), indent=1) + "\n")


if __name__ == "__main__":
    main()
