#!/usr/bin/env python
"""Performance of the taimill engine (CY steel reference case, scaling, sweeps).

Every measurement runs in a fresh interpreter (this script re-run with a hidden
--worker argument), so each gets its own `ti.init` with the requested thread count
and its own peak resident memory (getrusage ru_maxrss). Timed parts exclude process
start, ti.init, kernel compilation, ball placement and the first neighbour-list
build; time is time.perf_counter(), CPU time time.process_time() (all threads).

1. Reference case: presets/p4-cy-steel.toml (CY jar, 12 steel balls, steel-steel,
   Ω = 200 rpm, K = -2.6, automatic dt) through the public path
   `simulation.run(preset, NullSink(), duration=D)`, D = 24 s (3 s with --quick,
   the 24 s wall time then extrapolated). A 0.05 s run in the same process first
   compiles and caches the engine. Rows: one thread; all threads; a Runner on one
   thread without run()'s summary sink, with neighbour lists built from all pairs
   and from the spatial hash (the default); a fused Runner over two copies of the
   mill (B = 2) on all threads, which should use two cores.
2. Scaling with the number of balls: N = 12 ... 100 000 (10 000 with --quick) of the
   preset's balls in a cylindrical jar, height = radius, sized so that the balls
   fill FILL of the volume their centres can reach (N = 12: the CY jar), default
   Runner mode selection, all threads. The first WINDOW_STEPS steps after placement
   (balls falling from their start positions: few contacts, no list rebuilds) are
   timed in launches of about CHUNK_SECONDS, each followed by a drain as in
   Runner.launch, and the window is repeated from a fresh placement until the
   point has TARGET seconds of timing, so every N is timed in the same simulated
   phase. Extra rows force the other launch mode on each side of PARALLEL_ABOVE
   and (full run) time N = 1000 after SETTLE_SECONDS of simulated settling, when
   contacts dominate. The log-log slope of cost per step against N for N >= 1000,
   over the default-mode points and over the fused-mode points, tests the O(N)
   claim (1 = linear).

The machine may be shared. Two columns show what a timed part really got: cpu/wall,
the CPU seconds of the measuring process per wall second (the cores it used), and
others, the busy CPU seconds of every other process per wall second (/proc/stat,
tick-sampled: ±0.2 for bursty or short measurements). With others near 1 on a
2-core machine, a 2-thread figure is not trustworthy.

3. Recording overhead (issue 6): the reference run of section 1 on one thread into a
   NullSink, a RerunSink (.rrd) and a ZarrSink, each in its own worker, interleaved
   (null, rerun, zarr, null, rerun); overhead = best wall time with the sink / best
   with the null sink - 1, target ≤ 20 % for rerun. Each worker first runs
   COMPILE_DURATION into the same kind of sink (compilation, lazy imports: the
   warm-up column, not in the overhead).
4. Sweeps (issue 5): chunks of B = 1, 2, 4 reference mills (3 s each) in one kernel on
   one thread, and two such processes at once (B = 2), as µs per mill-step (this
   chose B and the process count); then the 21-point K sweep (K = 0 ... -4,
   CY steel, Ω = 200 rpm, 24 s per point; 3 s with --quick, the 24 s wall time then
   extrapolated linearly) through the public path `taimill.runs.sweep.run_sweep` on one
   spawned process per core, no store. Timed from the call to the last result: worker start-up, ti.init
   and compilation included (what a user waits for); CPU time includes the workers.

5. Dense beds (issue 16): taimill and LIGGGHTS-PUBLIC 3.8 side by side, end to end through
   their command lines, one core each: steel balls (r = 6 mm, Hertz e = 0.516 as
   hertz-mindlin, Coulomb μ = 0.8, dt = 1 µs) on a lattice of pitch 2r + 1 nm in a
   cylinder (every contact closing at once), the plate at rest (10⁻⁶ rpm: the command
   line refuses 0). Cases: simple cubic of 2·10⁴ and 10⁵ balls and face-centred cubic of
   2·10⁴ (steps 1000 → 3000); the hexagonal close-packed bed of 10⁵ once settled (3000 →
   5000); that bed in a drum turning at 30 rpm about its own axis (1000 → 3000). Each
   code runs N1 steps and N2 steps in child processes (up to 2·10⁴ balls twice each,
   the least time counting), and a figure per ball-step is the difference / ((N2 − N1) n):
   start-up, imports, Taichi's kernels from its cache, reading the start and writing the
   store cancel; CPU time and peak RSS are each child's own (os.wait4). taimill: `python -m
   taimill run` after an untimed warm-up run (compiles what the cache lacks), with the
   events as statistics (`events = "spectra"`, the acceptance figure) and as rows, and on
   2 threads for the simple cubic 10⁵ (parallel efficiency = wall 1 thread / (2 × wall 2
   threads)). LIGGGHTS: `liggghts -in` on the deck `taimill export liggghts` writes, no
   dumps, the box around the jar alone; static cases without the mesh movers and, the
   reference, with LIGGGHTS' primitive walls (zcylinder, zplanes) instead of the STL
   mesh, shown beside the mesh at 2·10⁴ balls; the drum keeps its moving mesh. Ratio =
   taimill / LIGGGHTS CPU per ball-step; targets sc 10⁵ ≤ 0.8, fcc 2·10⁴ ≤ 1.0, settled
   bed ≤ 1.0, drum ≤ 0.8; peak RSS at 10⁵ ≤ 300 MB + 1 kB per ball. Last, one `taimill
   run` of a 10⁶-ball bed, 11 steps, one thread: wall, CPU, peak RSS (--skip-million
   skips it). --quick: simple and face-centred cubic of 2000 balls, 100 → 1100 steps (the
   machinery only: a run's start-up varies by more than those steps cost).

6. Every small-mill preset (issue 19: each ≥ 3x real time on one core): run() into a NullSink on
   one thread, 24 s simulated (3 s with --quick), as simulated seconds per CPU second
   and per wall second.
7. Dense trajectories (issue 19: 10⁵ frames/s ≤ 2x the cost of 100 frames/s): the
   reference preset into a ZarrSink at both rates, 3 s simulated (1 s with --quick),
   interleaved, best of two each; the ratio of CPU and of wall seconds.

On a shared machine the CPU-time columns (time.process_time of the measuring process)
are the per-core figures to quote; wall figures then measure the machine's load.

9. Signals (issue 45: Ctrl-C honoured within 2 s at any stage): SIGINT 1 s, 5 s and 30 s
   after the start of `taimill run` on the 10⁵-ball simple-cubic drum of section 5 (all
   threads; 1 s falls in the imports and set-up, 5 s in the compile or first launches, 30 s
   in the simulation) and of `taimill sweep` (17 K values of the reference case, 24 s
   each, a worker per core), each in a fresh process: seconds from the signal to the
   exit, the exit code (130), the last line said, and whether what is left is readable
   (the run or sweep store opens and checks) or nothing was written.

10. Population balance (issue 47: a condition's 0–64 h curve in well under a second):
   `taimill.outcome.grinding.grind` over 40 √2 classes at the 10 default milling times
   of `taimill sizes predict`, impact and attrition on, on the shipped condition
   examples/outcome/condition-a.json; best of 5 after one untimed call (imports).

11. The step's kernels (issue 49: the serial share of a step ≤ 2 % at 10⁵ balls on one
   thread): every kernel of one large mill's step timed, the serial ones named
   (scripts/bench_kernels.py).

8. A/B (`--ab DIR`, alone): the reference case (CPU µs per step, one thread, 3 s) and the
   settled 10⁵ dense bed of section 5 (CPU ns per ball-step) from this checkout and
   from the one in DIR, interleaved rounds in one run, best of each: a change's
   before/after on the same machine at the same time.

    scripts/bench.py [--quick] [--only reference|scaling|recording|sweep|dense|presets|trajectory|signals|grinding|kernels]
                     [--case NAME] [--skip-million] [--backend cpu|cuda|auto] [--json FILE]
    scripts/bench.py --ab DIR
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "presets" / "p4-cy-steel.toml"
FULL_DURATION = 24.0  # s simulated, the reference run (the thesis' 24 s)
QUICK_DURATION = 3.0  # s simulated, --quick
COMPILE_DURATION = 0.05  # s simulated, the untimed run that compiles the engine
SWEEP_POINTS = 21  # K sweep 0 ... -4 at 0.2
REFERENCE_BALLS = 12  # the preset's count: that scaling point uses the preset's jar
SCALING_N = (REFERENCE_BALLS, 100, 1000, 10_000, 100_000)
QUICK_MAX_N = 10_000
BALL_RADIUS_MM = 6.0  # the preset's balls
FILL = 0.30  # ball volume / volume the ball centres can reach, scaling jars
WINDOW_STEPS = 20_000  # steps timed from one placement (≈ 16-19 ms simulated)
CHUNK_SECONDS = 0.25  # wall seconds per launch in the scaling loop
TARGET = {False: 3.0, True: 1.0}  # timed wall seconds per scaling point: full, quick
SETTLE_SECONDS = 0.1  # simulated, before the "settled" row
KIB_PER_BALL = 30  # peak RSS per ball, measured at 100 000 balls in parallel mode
WORKER_TIMEOUT = 300  # s per subprocess, set-up and compilation included
SWEEP_RATIOS = "0:-4:0.2"  # the 21 K values of the sweep benchmark
SWEEP_TIMEOUT = 3600  # s, the whole sweep in one measuring subprocess
MARKER = "BENCH-RESULT "


# ---------------------------------------------------------------- worker side
def start_taichi(threads: int | None) -> int:
    """ti.init through taimill; returns the number of CPU threads Taichi may use."""
    from taimill.physics.ti import init_taichi, internal

    init_taichi(threads)
    return internal("lang.impl").current_cfg().cpu_max_num_threads


def clocks() -> tuple[float, float, float]:
    """(wall, CPU seconds of this process, busy CPU seconds of the whole machine)."""
    with open("/proc/stat") as f:
        ticks = [int(v) for v in f.readline().split()[1:9]]
    busy = (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")  # all but idle, iowait
    return time.perf_counter(), time.process_time(), busy


def since(start: tuple) -> list[float]:
    return [b - a for a, b in zip(start, clocks())]


def peak_rss_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux


def work_reference(task: dict) -> dict:
    """The reference preset (`copies` mills), timed after a short compiling run."""
    from taimill.model.preset import load_preset
    from taimill.model.spec import from_preset
    from taimill.physics.runner import Runner
    from taimill.runs.simulation import run
    from taimill.store.sinks import NullSink

    threads = start_taichi(task["threads"])
    preset = load_preset(PRESET)
    copies = task["copies"]

    def simulate(duration: float) -> int:
        if task["public"]:
            return run(preset, NullSink(), duration=duration)["steps"]
        runner = Runner([from_preset(preset, duration)] * copies, use_grid=task["use_grid"])
        runner.run([NullSink()] * copies)
        return int(runner.engine.F.state.step[0])

    simulate(COMPILE_DURATION)
    start = clocks()
    steps = simulate(task["duration"])
    wall, cpu, busy = since(start)
    return dict(threads=threads, balls=preset.balls.count, dt=preset.dt, steps=steps,
                wall=wall, cpu=cpu, busy=busy, rss_mib=peak_rss_mib())


def advance(engine, steps: int, chunk: int | None = None, budget: float = math.inf):
    """Advance mill 0 by `steps` steps, at most `chunk` per launch, draining the
    output buffers after every launch as Runner.launch does; stops early once
    `budget` wall seconds have passed. Returns ([wall, cpu, busy] s, steps done)."""
    from taimill.errors import SimulationUnstable
    from taimill.physics import state as S
    from taimill.physics.runner import status_message

    F = engine.F
    start, done = int(F.state.step[0]), 0
    t0 = clocks()
    while done < steps and time.perf_counter() - t0[0] < budget:
        engine.advance(min(chunk or steps, steps - done))
        engine.drain(0)
        code, now = int(F.state.status[0]), int(F.state.step[0]) - start
        if code != S.OK:
            raise SimulationUnstable(status_message(code, int(F.state.bad_ball[0]), (start + now) * F.model.dt[0], F.model.dt[0]))
        if now == done:
            raise RuntimeError(f"the engine stopped advancing at step {start + now}")
        done = now
    return since(t0), done


def compile_event_export(engine):
    """drain() compiles its event export at the first event, which may fall inside
    a timed window: compile it now."""
    import numpy as np

    from taimill.physics import state as S
    from taimill.physics.engine import export_events

    export_events(engine.F, 0, 0, np.zeros((1, S.NCOL)))


def launch_steps(engine) -> int:
    """Steps per launch for launches of about CHUNK_SECONDS, from trial launches of
    doubling length."""
    k = 1
    while True:
        (wall, _, _), done = advance(engine, k)
        if wall > 0.05 or k >= 1 << 20:
            return max(1, int(CHUNK_SECONDS * done / wall))
        k *= 2


def work_scaling(task: dict) -> dict:
    """Cost per step of one mill of N balls: windows of steps from a fresh placement
    (or from a settled bed) until task["seconds"] of wall time are timed."""
    from taimill.model.preset import load_preset
    from taimill.model.spec import from_preset
    from taimill.physics.runner import Runner

    threads = start_taichi(task["threads"])
    overrides = {"jar": task["jar"], "balls.count": task["n"]} if task["jar"] else None
    spec = from_preset(load_preset(PRESET, overrides))  # the 24 s target is never reached
    mode = dict(mode=task["mode"], use_grid=task["use_grid"])
    runner = Runner([spec], **mode)
    advance(runner.engine, 1)  # compiles the step kernels, builds the neighbour lists
    compile_event_export(runner.engine)
    chunk = launch_steps(runner.engine)
    settle = round(task["settle"] / spec.dt)
    advance(runner.engine, settle, chunk)
    timed = [0.0, 0.0, 0.0]  # wall, cpu, busy
    steps, begins, ends = 0, [], []
    while timed[0] < task["seconds"]:
        if not settle:
            runner = Runner([spec], **mode)
            advance(runner.engine, 1)
        begins.append(int(runner.engine.F.state.step[0]))
        spent, done = advance(runner.engine, WINDOW_STEPS, chunk, task["seconds"] - timed[0])
        timed = [a + b for a, b in zip(timed, spent)]
        steps += done
        ends.append(begins[-1] + done)
    wall, cpu, busy = timed
    return dict(threads=threads, mode=runner.engine.mode, grid=runner.engine.use_grid, dt=spec.dt,
                steps=steps, windows=len(begins), wall=wall, cpu=cpu, busy=busy, sim_from=min(begins) * spec.dt,
                sim_to=max(ends) * spec.dt, rss_mib=peak_rss_mib())


def work_recording(task: dict) -> dict:
    """The reference preset into one sink ("null", "zarr" or "rerun"), timed after a
    short run into the same kind of sink (compiles the engine and pays the sink's
    first-use costs: lazy imports — rerun's first Points3D imports pandas, ≈ 0.7 s —
    colour tables, codecs; reported as `warm_wall`). The timed run includes the sink's
    finish (flushing its file)."""
    from taimill.model.preset import load_preset
    from taimill.runs.simulation import run
    from taimill.recording.sink import RerunSink
    from taimill.store.sinks import NullSink
    from taimill.store.writer import ZarrSink

    threads = start_taichi(task["threads"])
    preset = load_preset(PRESET)
    kind = task["sink"]

    def sink(path: Path):
        return NullSink() if kind == "null" else {"zarr": ZarrSink, "rerun": RerunSink}[kind](path)

    with tempfile.TemporaryDirectory(prefix="taimill-bench-") as tmp:
        out = Path(tmp) / f"run.{kind}"
        warm = time.perf_counter()
        run(preset, sink(Path(tmp) / f"warm.{kind}"), duration=COMPILE_DURATION)
        warm = time.perf_counter() - warm
        start = clocks()
        steps = run(preset, sink(out), duration=task["duration"])["steps"]
        wall, cpu, busy = since(start)
        size = sum(f.stat().st_size for f in [out, *out.rglob("*")] if f.is_file()) if out.exists() else 0
    return dict(threads=threads, dt=preset.dt, steps=steps, wall=wall, cpu=cpu, busy=busy, bytes=size,
                warm_wall=warm, rss_mib=peak_rss_mib())


def work_sweep(task: dict) -> dict:
    """The K sweep through run_sweep on `workers` spawned processes (no store)."""
    import resource

    from taimill.runs.sweep import Request, parse_values, run_sweep

    req = Request(str(PRESET), {"duration": task["duration"]}, {"ratio": parse_values(SWEEP_RATIOS, "--ratio")})

    def children_cpu() -> float:
        r = resource.getrusage(resource.RUSAGE_CHILDREN)
        return r.ru_utime + r.ru_stime

    c0, start = children_cpu(), clocks()
    rows, _ = run_sweep(req, None, workers=task["workers"], batch=task["batch"])
    wall, cpu, busy = since(start)
    return dict(points=len(rows), workers=task["workers"], batch=max(r["batch"] for r in rows), wall=wall,
                cpu=cpu + children_cpu() - c0, busy=busy, sim=sum(r["sim_seconds"] for r in rows),
                point_wall=sum(r["wall_seconds"] for r in rows), dt=[min(r["dt"] for r in rows), max(r["dt"] for r in rows)],
                failed=sum(r["status"] != "complete" for r in rows))


def work_batch(task: dict) -> dict:
    """B copies of the reference mill as one sweep chunk (one Runner, one thread), timed
    after a short compiling chunk of the same B."""
    from taimill.model.preset import load_preset
    from taimill.physics.ti import init_taichi
    from taimill.runs.executors import Job, run_chunk

    init_taichi(threads=1)
    B = task["batch"]
    for duration in (COMPILE_DURATION, task["duration"]):
        jobs = [Job(b, load_preset(PRESET, {"duration": duration})) for b in range(B)]
        start = clocks()
        results = run_chunk(0, jobs, False)
    wall, cpu, busy = since(start)
    return dict(batch=B, steps=sum(r.summary["steps"] for r in results), wall=wall, cpu=cpu, busy=busy)


def work_preset(task: dict) -> dict:
    """One preset through run() into a NullSink on one thread, after a compiling run."""
    from taimill.model.preset import load_preset
    from taimill.runs.simulation import run
    from taimill.store.sinks import NullSink

    start_taichi(1)
    preset = load_preset(ROOT / "presets" / task["preset"])
    run(preset, NullSink(), duration=COMPILE_DURATION)
    start = clocks()
    steps = run(preset, NullSink(), duration=task["duration"])["steps"]
    wall, cpu, busy = since(start)
    return dict(balls=preset.balls.count, dt=preset.dt, steps=steps, wall=wall, cpu=cpu, busy=busy)


def work_trajectory(task: dict) -> dict:
    """The reference preset into a ZarrSink at task["rate"] frames per simulated second,
    one thread, after a compiling run at the same rate (which sizes the same buffers)."""
    import dataclasses

    from taimill.model.preset import load_preset
    from taimill.runs.simulation import run
    from taimill.store.writer import ZarrSink

    start_taichi(1)
    preset = dataclasses.replace(load_preset(PRESET), trajectory_rate=task["rate"])
    with tempfile.TemporaryDirectory(prefix="taimill-bench-") as tmp:
        run(preset, ZarrSink(Path(tmp) / "warm.zarr"), duration=COMPILE_DURATION)
        out = Path(tmp) / "run.zarr"
        start, sys0 = clocks(), os.times().system
        steps = run(preset, ZarrSink(out), duration=task["duration"])["steps"]
        wall, cpu, busy = since(start)
        sys_cpu = os.times().system - sys0
        size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    return dict(dt=preset.dt, steps=steps, wall=wall, cpu=cpu, sys=sys_cpu, busy=busy, bytes=size,
                rss_mib=peak_rss_mib())


WORKERS = {"reference": work_reference, "scaling": work_scaling, "recording": work_recording, "sweep": work_sweep,
           "batch": work_batch, "preset": work_preset, "trajectory": work_trajectory}


def worker_main(task_json: str):
    task = json.loads(task_json)
    result = WORKERS[task.pop("kind")](task)
    print(MARKER + json.dumps(result), flush=True)


# ---------------------------------------------------------------- parent side
def measure(task: dict, timeout: float = WORKER_TIMEOUT, root: Path = ROOT) -> dict:
    """Run one measurement in a fresh interpreter: its result, or {"error": why}.
    `root`: the checkout whose taimill (and bench worker) runs it (section 8)."""
    cmd = [sys.executable, str(root / "scripts" / "bench.py"), "--worker", json.dumps(task)]
    env = os.environ | {"PYTHONPATH": str(root)} if root != ROOT else None
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=root, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s"}
    for line in proc.stdout.splitlines():
        if line.startswith(MARKER):
            return json.loads(line[len(MARKER):])
    if proc.returncode < 0:
        oom = " (out of memory?)" if proc.returncode == -9 else ""
        return {"error": f"worker killed by signal {-proc.returncode}{oom}"}
    lines = proc.stderr.strip().splitlines()
    return {"error": lines[-1] if lines else f"worker exit status {proc.returncode}"}


def meminfo_mib(key: str) -> float:
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) / 1024
    return math.nan


def cpu_model() -> str:
    from taimill.physics.backend import cpu_model  # what a run's summary records as its device

    return cpu_model()


def taichi_version() -> str:
    """The Taichi in use, 'taichi 1.7.4' or 'taichi-forge 0.7.0' (taimill's door picks it)."""
    from taimill.physics.ti import describe

    return describe()


def machine() -> dict:
    return dict(
        cpus=os.cpu_count(), processor=cpu_model(), machine=platform.machine(), platform=platform.platform(),
        python=platform.python_version(), taichi=taichi_version(),
        numpy=importlib.metadata.version("numpy"), backend=os.environ.get("TAIMILL_BACKEND") or "cpu",
        mem_total_mib=meminfo_mib("MemTotal"),
        mem_available_mib=meminfo_mib("MemAvailable"), load_start=os.getloadavg(),
    )


def print_machine(m: dict):
    print(f"taimill benchmark, {time.strftime('%Y-%m-%d %H:%M:%S')}")
    print(f"machine:  {m['cpus']} CPUs (os.cpu_count), {m['processor']}, {m['machine']}, {m['platform']}")
    print(f"memory:   {m['mem_total_mib'] / 1024:.1f} GiB, {m['mem_available_mib'] / 1024:.1f} GiB available")
    print(f"software: Python {m['python']}, {m['taichi']}, numpy {m['numpy']}; backend {m['backend']}")
    print("load:     %.2f %.2f %.2f (1, 5, 15 min averages at start)" % m["load_start"])


def si(x: float) -> str:
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(x) >= scale:
            return f"{x / scale:.2f} {unit}"
    return f"{x:.3g}"


# ---- 1. reference case
REFERENCE_ROWS = (
    ("run(), one thread", dict(threads=1, public=True, copies=1, use_grid=True)),
    ("run(), all threads", dict(threads=None, public=True, copies=1, use_grid=True)),
    ("Runner, all pairs, one thread", dict(threads=1, public=False, copies=1, use_grid=False)),
    ("Runner, spatial hash, one thread", dict(threads=1, public=False, copies=1, use_grid=True)),
    ("Runner, B = 2 fused, all threads", dict(threads=None, public=False, copies=2, use_grid=True)),
)


def load_metrics(r: dict) -> dict:
    """Cores this measurement used, and cores other processes used meanwhile."""
    return dict(cpu_per_wall=r["cpu"] / r["wall"], others=(r["busy"] - r["cpu"]) / r["wall"])


def reference_metrics(r: dict, copies: int, duration: float) -> dict:
    """Rates per mill-second and per mill-step; wall time of 24 s of every mill."""
    sim = r["steps"] * r["dt"]
    mill_steps = copies * r["steps"]
    return dict(
        mills=copies, sim_seconds=sim, mill_seconds_per_wall_second=copies * sim / r["wall"],
        us_per_mill_step=r["wall"] / mill_steps * 1e6, ball_steps_per_second=mill_steps * r["balls"] / r["wall"],
        wall_for_24s=r["wall"] * FULL_DURATION / sim, wall_for_24s_measured=duration == FULL_DURATION,
        cpu_us_per_mill_step=r["cpu"] / mill_steps * 1e6, mill_seconds_per_cpu_second=copies * sim / r["cpu"],
        **load_metrics(r),
    )


def reference_section(duration: float) -> tuple[list[dict], float | None]:
    print(f"\n1. Reference case: {PRESET.relative_to(ROOT)}, {duration:g} s simulated per run, compile excluded")
    print(f"  {'':37} {'thr':>3} {'mills':>5} {'mill-s/wall-s':>13} {'µs/step':>8} {'ball-steps/s':>12}"
          f" {'wall for 24 s':>21} {'cpu/wall':>8} {'others':>6} {'RSS MiB':>7} {'cpu µs/step':>11} {'mill-s/cpu-s':>12}")
    rows = []
    for label, kw in REFERENCE_ROWS:
        r = measure(dict(kind="reference", duration=duration, **kw))
        row = dict(label=label, request=kw, **r)
        rows.append(row)
        if "error" in r:
            print(f"  {label:37} failed: {r['error']}")
            continue
        row.update(reference_metrics(r, kw["copies"], duration))
        how = "measured" if row["wall_for_24s_measured"] else "extrapolated"
        print(f"  {label:37} {r['threads']:>3} {kw['copies']:>5} {row['mill_seconds_per_wall_second']:>13.2f}"
              f" {row['us_per_mill_step']:>8.3f} {si(row['ball_steps_per_second']):>12}"
              f" {row['wall_for_24s']:>7.1f} s {how:>12} {row['cpu_per_wall']:>8.2f} {row['others']:>6.2f}"
              f" {r['rss_mib']:>7.0f} {row['cpu_us_per_mill_step']:>11.3f} {row['mill_seconds_per_cpu_second']:>12.2f}",
              flush=True)
    ok = [r for r in rows if "error" not in r]
    if ok:
        print(f"  dt = {ok[0]['dt'] * 1e6:.4f} µs (automatic); µs/step is per mill-step; the cpu columns count this"
              " process's CPU time (all its threads): on a shared machine the per-core figure to quote")
    # a sweep runs one process per core, one mill at a time each (two mills on two
    # threads of one process, the B = 2 row, run ≈ 4x slower each: docs/performance.md)
    single = next((r for r in ok if r["mills"] == 1 and r["threads"] == 1), None)
    sweep = None
    if single:
        cores = os.cpu_count() or 1
        sweep = SWEEP_POINTS * FULL_DURATION / (single["mill_seconds_per_wall_second"] * cores)
        print(f"  a {SWEEP_POINTS}-point K sweep of {FULL_DURATION:g} s, one process per core ({cores}) at the"
              f" one-thread rate, would take ≈ {sweep:.0f} s without start-up (estimate: other K values change the"
              " dynamics and so the cost; section 4 measures it)")
    return rows, sweep


# ---- 2. scaling with the number of balls
def jar_radius_mm(n: int) -> float:
    """R (mm) of the jar with height R in which n balls fill FILL of the volume their
    centres can reach, π (R - r)² (R - 2r); bisection (the volume grows with R)."""
    r = BALL_RADIUS_MM
    need = n * 4.0 / 3.0 * math.pi * r**3 / FILL
    lo, hi = 2.0 * r, 1e4
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if math.pi * (mid - r) ** 2 * (mid - 2 * r) < need else (lo, mid)
    return hi


def fill_fraction(n: int, radius_mm: float, height_mm: float) -> float:
    return n * 4.0 / 3.0 * BALL_RADIUS_MM**3 / (radius_mm**2 * height_mm)


def write_jar(directory: Path, n: int) -> tuple[str, float, float]:
    """A cylindrical jar TOML for n balls: (path, radius mm, ball volume / jar volume)."""
    R = jar_radius_mm(n)
    path = directory / f"bench{n}.toml"
    path.write_text(f'description = "bench.py: cylinder for {n} balls"\nheight_mm = {R:.3f}\n'
                    f'wall_material = "aisi-304"\n\n[[profile]]\ntype = "circle"\nradius_mm = {R:.3f}\n')
    return str(path), R, fill_fraction(n, R, R)


def preset_jar(n: int) -> tuple[None, float, float]:
    """The preset's own jar (jars/CY.toml): (no override, radius mm, fill)."""
    jar = tomllib.loads((ROOT / "jars" / "CY.toml").read_text())
    R = max(p["radius_mm"] for p in jar["profile"] if p["type"] == "circle")
    return None, R, fill_fraction(n, R, jar["height_mm"])


def scaling_rows(quick: bool) -> list[dict]:
    """Labelled requests: the default mode for every N, then the extra rows."""
    def row(label, n, mode=None, use_grid=True, settle=0.0):
        return dict(label=label, n=n, request=dict(mode=mode, use_grid=use_grid, settle=settle))

    ns = [n for n in SCALING_N if not quick or n <= QUICK_MAX_N]
    rows = [row(str(n), n) for n in ns]
    # the other launch mode on each side of PARALLEL_ABOVE = 50 000
    rows += [row(f"{n}, parallel forced", n, "parallel") for n in ns if 1000 <= n <= 10_000]
    rows += [row(f"{n}, fused forced", n, "fused") for n in ns if n > 50_000]
    if not quick:
        rows.append(row(f"1000, settled {SETTLE_SECONDS:g} s", 1000, settle=SETTLE_SECONDS))
    return rows


def scaling_point(row: dict, jar_dir: Path, seconds: float) -> dict:
    n = row["n"]
    jar, R, fill = preset_jar(n) if n == REFERENCE_BALLS else write_jar(jar_dir, n)
    row.update(jar_radius_mm=R, fill=fill)
    need = n * KIB_PER_BALL / 1024
    available = meminfo_mib("MemAvailable")
    if need > 0.8 * available:
        row["error"] = f"skipped: needs ≈ {need:.0f} MiB, {available:.0f} MiB available"
        return row
    r = measure(dict(kind="scaling", n=n, jar=jar, threads=None, seconds=seconds, **row["request"]))
    row.update(r)
    if "error" not in r:
        row.update(us_per_step=r["wall"] / r["steps"] * 1e6, ns_per_ball_step=r["wall"] / (r["steps"] * n) * 1e9,
                   ball_steps_per_second=r["steps"] * n / r["wall"], **load_metrics(r))
    return row


SLOPES = {  # which points enter each fit of cost per step against N
    "default modes": lambda r: r["request"]["mode"] is None,
    "fused mode only": lambda r: r["mode"] == "fused",
}


def loglog_slope(points: list[tuple[float, float]]) -> float | None:
    if len(points) < 2:
        return None
    xs, ys = zip(*((math.log(x), math.log(y)) for x, y in points))
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def scaling_section(quick: bool) -> tuple[list[dict], dict]:
    seconds = TARGET[quick]
    print(f"\n2. Scaling with the number of balls: first ≤ {WINDOW_STEPS} steps after placement,"
          f" {seconds:g} s timed per point, all threads")
    print(f"  {'N':26} {'mode':>8} {'grid':>4} {'thr':>3} {'R mm':>5} {'fill':>4} {'dt µs':>6} {'steps':>7}"
          f" {'sim ms':>11} {'µs/step':>9} {'ns/ball-step':>12} {'ball-steps/s':>12} {'cpu/wall':>8} {'others':>6}"
          f" {'RSS MiB':>7}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="taimill-bench-") as tmp:
        for row in scaling_rows(quick):
            rows.append(scaling_point(row, Path(tmp), seconds))
            print_scaling_row(row)
    slopes = {}
    for name, keep in SLOPES.items():
        fit = [(r["n"], r["us_per_step"]) for r in rows
               if "error" not in r and r["n"] >= 1000 and not r["request"]["settle"] and keep(r)]
        slopes[name] = loglog_slope(fit)
        if slopes[name] is None:
            print(f"  {name}: too few points with N ≥ 1000 for a slope")
        else:
            print(f"  {name}: cost per step ∝ N^{slopes[name]:.2f} over N = {', '.join(str(n) for n, _ in fit)}"
                  " (1 = O(N))")
    return rows, slopes


def print_scaling_row(r: dict):
    if "error" in r:
        print(f"  {r['label']:26} {r['error']}", flush=True)
        return
    window = f"{r['sim_from'] * 1e3:.1f}-{r['sim_to'] * 1e3:.1f}"
    print(f"  {r['label']:26} {r['mode']:>8} {'on' if r['grid'] else 'off':>4} {r['threads']:>3}"
          f" {r['jar_radius_mm']:>5.0f} {r['fill']:>4.0%} {r['dt'] * 1e6:>6.3f} {r['steps']:>7}"
          f" {window:>11} {r['us_per_step']:>9.2f} {r['ns_per_ball_step']:>12.1f}"
          f" {si(r['ball_steps_per_second']):>12} {r['cpu_per_wall']:>8.2f} {r['others']:>6.2f} {r['rss_mib']:>7.0f}",
          flush=True)


# ---- 3. recording overhead
RECORDING_ORDER = ("null", "rerun", "zarr", "null", "rerun")  # interleaved: drift hits both
RECORDING_TARGET = 0.20  # issue 6: a recording may slow a 24 s run by at most 20 %


def recording_section(duration: float) -> tuple[list[dict], dict]:
    print(f"\n3. Recording overhead: {PRESET.relative_to(ROOT)}, {duration:g} s simulated into each sink,"
          f" one thread, best of {RECORDING_ORDER.count('null')} for null and rerun")
    print(f"  {'sink':6} {'wall s':>7} {'cpu s':>7} {'file MiB':>8} {'cpu/wall':>8} {'others':>6} {'warm-up s':>9}")
    rows = []
    for sink in RECORDING_ORDER:
        r = measure(dict(kind="recording", sink=sink, duration=duration, threads=1))
        rows.append(dict(sink=sink, **r))
        if "error" in r:
            print(f"  {sink:6} failed: {r['error']}")
            continue
        m = load_metrics(r)
        print(f"  {sink:6} {r['wall']:>7.2f} {r['cpu']:>7.2f} {r['bytes'] / 2**20:>8.1f} {m['cpu_per_wall']:>8.2f}"
              f" {m['others']:>6.2f} {r['warm_wall']:>9.2f}", flush=True)
    best = {}  # sink -> smallest wall and smallest cpu seconds over its repeats
    for sink in dict.fromkeys(RECORDING_ORDER):
        ok = [r for r in rows if r["sink"] == sink and "error" not in r]
        if ok:
            best[sink] = {k: min(r[k] for r in ok) for k in ("wall", "cpu")}
    overhead = {}
    if "null" in best:
        for sink in ("rerun", "zarr"):
            if sink in best:
                overhead[sink] = {k: best[sink][k] / best["null"][k] - 1 for k in ("wall", "cpu")}
                verdict = "" if sink != "rerun" else "; target ≤ 20 %: " + ", ".join(
                    f"{k} {'met' if v <= RECORDING_TARGET else 'MISSED'}" for k, v in overhead[sink].items())
                print(f"  {sink} overhead over the null sink: wall {overhead[sink]['wall']:+.1%},"
                      f" cpu {overhead[sink]['cpu']:+.1%}{verdict}")
        print("  (cpu counts every thread of the worker: rerun encodes and writes on its own threads;"
              " with others > 0.5 the wall figures are not trustworthy)")
    return rows, overhead


# ---- 6. every small-mill preset
PRESET_TARGET = 3.0  # issue 19: every preset at least 3x real time on one core
SMALL_MILL_BALLS = 100


def presets_section(duration: float) -> list[dict]:
    """Every preset through run() on one thread: simulated s per CPU s (the per-core
    figure, robust to a busy machine) and per wall s."""
    from taimill.model.preset import load_preset

    # small mills only: the bead presets (10³-10⁴ balls, dt < 0.3 µs, hours per 24 s)
    # are large-N cases, section 5's business
    names = sorted(p.name for p in (ROOT / "presets").glob("*.toml") if load_preset(p).balls.count <= SMALL_MILL_BALLS)
    print(f"\n6. Every preset: run() into a NullSink, {duration:g} s simulated each, one thread, compile excluded;"
          f" target ≥ {PRESET_TARGET:g}x real time per core")
    print(f"  {'preset':28} {'balls':>5} {'dt µs':>6} {'cpu µs/step':>11} {'sim-s/cpu-s':>11} {'sim-s/wall-s':>12}"
          f" {'cpu/wall':>8} {'others':>6}")
    rows = []
    for name in names:
        r = measure(dict(kind="preset", preset=name, duration=duration))
        rows.append(dict(preset=name, **r))
        if "error" in r:
            print(f"  {name:28} failed: {r['error']}")
            continue
        sim = r["steps"] * r["dt"]
        m = load_metrics(r)
        rows[-1].update(sim_per_cpu=sim / r["cpu"], sim_per_wall=sim / r["wall"], cpu_us_per_step=r["cpu"] / r["steps"] * 1e6,
                        **m)
        flag = "" if sim / r["cpu"] >= PRESET_TARGET else "  below target"
        print(f"  {name:28} {r['balls']:>5} {r['dt'] * 1e6:>6.3f} {rows[-1]['cpu_us_per_step']:>11.3f}"
              f" {sim / r['cpu']:>11.2f} {sim / r['wall']:>12.2f} {m['cpu_per_wall']:>8.2f} {m['others']:>6.2f}{flag}",
              flush=True)
    return rows


# ---- 7. dense trajectories
DENSE_RATES = (100.0, 1e5) * 3  # frames per simulated second, interleaved
DENSE_TARGET = 2.0  # issue 19: 10^5 frames/s may cost at most twice the 100 frames/s run


def trajectory_section(duration: float) -> dict:
    print(f"\n7. Dense trajectories: {PRESET.relative_to(ROOT)}, {duration:g} s simulated into a ZarrSink at 100 and"
          f" 10⁵ frames/s, one thread, interleaved; target: 10⁵ costs ≤ {DENSE_TARGET:g}x 100")
    print(f"  {'frames/s':>8} {'wall s':>7} {'cpu s':>7} {'user s':>7} {'sys s':>6} {'store MiB':>9} {'cpu/wall':>8}"
          f" {'others':>6}")
    rows = []
    for rate in DENSE_RATES:
        r = measure(dict(kind="trajectory", rate=rate, duration=duration))
        rows.append(dict(rate=rate, **r))
        if "error" in r:
            print(f"  {rate:>8g} failed: {r['error']}")
            continue
        m = load_metrics(r)
        r["user"] = rows[-1]["user"] = r["cpu"] - r["sys"]
        print(f"  {rate:>8g} {r['wall']:>7.2f} {r['cpu']:>7.2f} {r['user']:>7.2f} {r['sys']:>6.2f}"
              f" {r['bytes'] / 2**20:>9.1f} {m['cpu_per_wall']:>8.2f} {m['others']:>6.2f}", flush=True)
    best = {}
    for rate in dict.fromkeys(DENSE_RATES):
        ok = [r for r in rows if r["rate"] == rate and "error" not in r]
        if ok:
            best[rate] = {k: min(r[k] for r in ok) for k in ("wall", "cpu", "user")}
    ratio = {}
    if len(best) == 2:
        ratio = {k: best[1e5][k] / best[100.0][k] for k in ("wall", "cpu", "user")}
        verdict = {k: "met" if ratio[k] <= DENSE_TARGET else "MISSED" for k in ratio}
        print(f"  10⁵ / 100 frames/s (best of each): cpu {ratio['cpu']:.2f}x, wall {ratio['wall']:.2f}x; target ≤"
              f" {DENSE_TARGET:g}x: cpu {verdict['cpu']} (the acceptance figure: CPU seconds of every thread),"
              f" wall {verdict['wall']} (wall counts the disk and the machine's other load)")
        print(f"  of which user {ratio['user']:.2f}x ({verdict['user']}): 'sys' is the operating system's, mostly"
              " copying the store's bytes into the page cache (on a fresh VM its pages are first touched then:"
              " ≈ 2-3 ms per MB) and creating the store's ≈ 500 files and folders (docs/performance.md)")
    return dict(rows=rows, ratio=ratio)


# ---- 4. sweep
BATCH_ROWS = ((1, 1), (2, 1), (4, 1), (2, 2))  # (B, concurrent processes)


def batching_rows(duration: float) -> list[dict]:
    """µs per mill-step for B mills in one kernel on one process, and for two such
    processes at once (they should each keep their one-process rate on two cores)."""
    from concurrent.futures import ThreadPoolExecutor

    print(f"  chunks of B reference mills ({duration:g} s each) on one thread per process:")
    print(f"  {'B':>3} {'procs':>5} {'µs/mill-step wall':>18} {'cpu':>6} {'mill-s/wall-s':>13} {'cpu/wall':>8} {'others':>6}")
    rows = []
    for batch, procs in BATCH_ROWS:
        with ThreadPoolExecutor(procs) as pool:
            got = list(pool.map(measure, [dict(kind="batch", batch=batch, duration=duration)] * procs))
        for r in got:
            rows.append(dict(procs=procs, **r))
            if "error" in r:
                print(f"  {batch:>3} {procs:>5} failed: {r['error']}")
                continue
            m = load_metrics(r)
            print(f"  {batch:>3} {procs:>5} {r['wall'] / r['steps'] * 1e6:>18.3f} {r['cpu'] / r['steps'] * 1e6:>6.3f}"
                  f" {batch * duration / r['wall']:>13.2f}"
                  f" {m['cpu_per_wall']:>8.2f} {m['others']:>6.2f}", flush=True)
    return rows


def sweep_section(quick: bool) -> dict:
    duration = QUICK_DURATION if quick else FULL_DURATION
    workers = os.cpu_count() or 1
    print("\n4. Sweeps")
    batching = batching_rows(QUICK_DURATION)
    print(f"  K sweep: K = {SWEEP_RATIOS} ({SWEEP_POINTS} points), {PRESET.relative_to(ROOT)}, {duration:g} s per point,"
          f" {workers} spawned processes, start-up and compilation included")
    r = measure(dict(kind="sweep", duration=duration, workers=workers, batch=None), timeout=SWEEP_TIMEOUT)
    r["batching"] = batching
    if "error" in r:
        print(f"  failed: {r['error']}")
        return r
    scale = FULL_DURATION / duration
    r.update(duration=duration, wall_for_24s=r["wall"] * scale, wall_for_24s_measured=not quick,
             idle_estimate_for_24s=r["cpu"] * scale / workers,
             mill_seconds_per_wall_second_per_core=r["sim"] / r["wall"] / workers,
             compute_mill_seconds_per_wall_second=r["sim"] / r["point_wall"], **load_metrics(r))
    how = "measured" if not quick else f"extrapolated x{scale:g} from {duration:g} s per point"
    print(f"  {r['points']} points, B = {r['batch']}, dt {r['dt'][0] * 1e6:.3f}-{r['dt'][1] * 1e6:.3f} µs, {r['failed']} failed")
    print(f"  wall {r['wall']:.1f} s; 24 s per point: {r['wall_for_24s']:.0f} s = {r['wall_for_24s'] / 60:.1f} min ({how});"
          f" target ≤ 60 s")
    print(f"  {r['mill_seconds_per_wall_second_per_core']:.2f} simulated s per wall s per core"
          f" ({r['compute_mill_seconds_per_wall_second']:.2f} per core inside the workers' chunks);"
          f" cpu/wall {r['cpu_per_wall']:.2f}, others {r['others']:.2f}", flush=True)
    print(f"  if every core were ours (CPU s x{scale:g} / {workers} cores, start-up scaled too): "
          f"{r['idle_estimate_for_24s']:.0f} s = {r['idle_estimate_for_24s'] / 60:.1f} min")
    return r


# ---- 5. dense beds, side by side with LIGGGHTS (issue 16)
DENSE_STEPS = {10_000: 1000, 100_000: 1000, 1_000_000: 100}  # steps per case of dense_case's preset (section 8)
# the bed of 10⁵ balls is timed a second time, after this many more steps: a bed that
# has settled, holding every contact it will hold (its first steps are the bed closing
# its gaps; contacts open for long had scattered their data over memory and cost 1.8x)
DENSE_SETTLE = {100_000: 3000}
DENSE_RADIUS_MM = 6.0  # steel balls of the thesis
DENSE_GAP = 1e-9  # m between neighbours of the close-packed bed: a bed at rest, every contact closing at once
DRUM_RPM = 30.0  # the drum variant: the jar turns about its own axis at this speed
DENSE_DT = 1e-6  # s, every dense preset's time step
# packed volume per ball in units of the pitch³: simple cubic; face-centred cubic and
# hexagonal close packing (both 12 neighbours, 74 % of space at gap 0)
LATTICE_VOLUME = {"sc": 1.0, "fcc": 1 / math.sqrt(2), "hcp": 1 / math.sqrt(2)}


def dense_case(directory: Path, n: int, drum: bool, lattice: str = "hcp") -> Path:
    """A preset of n steel balls (r = 6 mm) in a bed filling the lower part of a cylinder
    of height 1.5 R (at most 1 m), start positions in start.npz: Hertz with constant
    restitution 0.516 (hertz-mindlin), Coulomb μ = 0.8, dt = 1 µs. The bed: `lattice` "hcp"
    (hexagonal close packing, bed_placement), "sc" (simple cubic) or "fcc" (face-centred
    cubic), neighbours 2r + DENSE_GAP apart, the lowest n sites. Static: the drive at
    10⁻⁶ rpm (work_dense sets it to exactly 0; the command line refuses 0); drum: the jar
    turns at DRUM_RPM about its own axis after a 1 ms start-up."""
    import numpy as np

    from taimill.model.geometry import build_profile
    from taimill.model.placement import bed_placement

    r = DENSE_RADIUS_MM * 1e-3
    pitch = 2 * r + DENSE_GAP
    # a bed about R high (R grown until n sites fit: a cubic lattice loses more at the wall)
    R = (n * pitch**3 * LATTICE_VOLUME[lattice] / math.pi) ** (1 / 3) + 2 * r
    while True:
        H = min(1.5 * R, 0.999)  # jar files allow up to 1 m
        if lattice == "hcp":
            x = bed_placement(n, r, build_profile((("circle", {"radius": R}),), 0.0), H, gap=DENSE_GAP)
            break
        x = lattice_sites(lattice, pitch, R - r - DENSE_GAP, r + DENSE_GAP, H - r - DENSE_GAP)
        if len(x) >= n:
            x = x[:n]
            break
        R *= 1.05
    name = {"hcp": "bed", "sc": "sc", "fcc": "fcc"}[lattice]
    case = directory / f"{'drum' if drum else name}{n}"
    case.mkdir(parents=True, exist_ok=True)
    (case / "jar.toml").write_text(f'description = "bench.py: cylinder for a bed of {n} balls"\n'
                                   f'height_mm = {1e3 * H!r}\nwall_material = "aisi-304"\n\n'
                                   f'[[profile]]\ntype = "circle"\nradius_mm = {1e3 * R!r}\n')
    np.savez(case / "start.npz", positions=x)
    drive = f"plate_rpm = 1e-6\njar_rpm = {DRUM_RPM}\nramp_time = 0.001\n" if drum else "plate_rpm = 1e-6\nratio = 1\n"
    drive += "plate_radius_mm = 2000\n"  # the plate all but rests (Ω = 1e-6 rpm): R_p need only lie outside the jar
    duration = (2 * DENSE_STEPS.get(n, 1000) + DENSE_SETTLE.get(n, 0)) * DENSE_DT + 2 * DENSE_DT
    (case / "bed.toml").write_text(
        'jar = "jar.toml"\npair = "steel-steel"\nlaw = "hertz-mindlin"\n' + drive
        + f'duration = {duration!r}\ndt = {DENSE_DT!r}\nseed = 1\ninitial_positions = "start.npz"\n'
        f'\n[friction]\nmu_s = 0.8\nmu_d = 0.8\n\n[balls]\ncount = {n}\nmaterial = "steel-c1020"\n'
        f'radius_mm = {DENSE_RADIUS_MM}\n\n[outputs]\ntrajectory_rate = {1 / duration!r}\n')  # one frame interval: frames at both ends
    return case / "bed.toml"


def lattice_sites(lattice: str, pitch: float, reach: float, z_lo: float, z_hi: float):
    """Sites of a simple cubic ("sc") or face-centred cubic ("fcc") lattice whose nearest
    neighbours are `pitch` apart, centres within `reach` of the z axis and z_lo ≤ z ≤ z_hi,
    lowest layers first (sorted by z, then y, then x, as bed_placement's)."""
    import numpy as np

    if lattice == "sc":
        a, basis = pitch, np.zeros((1, 3))
    else:  # cubic cell a = pitch √2, 4 sites: the face centres are pitch from the corners
        a = pitch * math.sqrt(2)
        basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * a
    m = int(reach / a) + 1
    i, j, k = np.meshgrid(np.arange(-m, m + 1), np.arange(-m, m + 1), np.arange(int((z_hi - z_lo) / a) + 1),
                          indexing="ij")
    cells = np.column_stack([i.ravel() * a, j.ravel() * a, z_lo + k.ravel() * a])
    pts = (cells[:, None, :] + basis[None, :, :]).reshape(-1, 3)
    pts = pts[(np.hypot(pts[:, 0], pts[:, 1]) <= reach) & (pts[:, 2] <= z_hi + 1e-12)]
    return pts[np.lexsort((pts[:, 0], pts[:, 1], pts[:, 2]))]


def vm_hwm_mib() -> float:
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) for ln in f if ln.startswith("VmHWM")) / 1024


def work_dense(task: dict) -> dict:
    """taimill on a dense bed: set-up (interpreter start to the first step done: imports,
    ti.init, preset and position check, fields, compilation, first neighbour lists),
    then task["steps"] steps timed, drained as Runner.launch does; with task["settle"],
    that many steps more untimed and task["steps"] timed again (result "settled")."""
    from taimill.model.frame import Ramp
    from taimill.model.preset import load_preset
    from taimill.model.spec import from_preset
    from taimill.physics.runner import Runner

    threads = start_taichi(task["threads"])
    spec = from_preset(load_preset(task["preset"]))
    if not task["drum"]:
        spec = spec.replace(plate=Ramp(0.0, 0.0, 0.0, 1.0), jar=Ramp(0.0, 0.0, 0.0, 1.0))
    runner = Runner([spec])
    advance(runner.engine, 1)
    compile_event_export(runner.engine)
    setup = time.time() - task["spawned"]
    rss_setup = vm_hwm_mib()
    (wall, cpu, busy), steps = advance(runner.engine, task["steps"], 1000)
    out = dict(threads=threads, mode=runner.engine.mode, setup=setup, steps=steps, wall=wall, cpu=cpu, busy=busy,
               rss_setup_mib=rss_setup)
    if task.get("settle"):
        advance(runner.engine, task["settle"], 1000)
        (wall, cpu, busy), steps = advance(runner.engine, task["steps"], 1000)
        out["settled"] = dict(steps=steps, wall=wall, cpu=cpu, busy=busy)
    return out | dict(rss_mib=vm_hwm_mib())




# The dense section times both codes end to end through their command lines: every
# measurement is a child process run N1 steps and one run N2 steps, and a figure per
# ball-step is (N2-run − N1-run) / ((N2 − N1) n): the set-up (interpreter start, imports,
# kernels from Taichi's cache, reading the start, the store; LIGGGHTS' input and first
# neighbour lists) cancels. CPU time and peak RSS are the child's own (os.wait4).
DENSE_CASES = (  # name, balls, lattice, drum, (N1, N2), target (taimill spectra / LIGGGHTS), LIGGGHTS walls
    dict(case="sc 20000", n=20_000, lattice="sc", drum=False, steps=(1000, 3000), target=None,
         walls=("primitive", "mesh")),
    dict(case="sc 100000", n=100_000, lattice="sc", drum=False, steps=(1000, 3000), target=0.8,
         walls=("primitive",), threads2=True, rss_check=True),
    dict(case="fcc 20000", n=20_000, lattice="fcc", drum=False, steps=(1000, 3000), target=1.0,
         walls=("primitive", "mesh")),
    dict(case="bed 100000 settled", n=100_000, lattice="hcp", drum=False, steps=(3000, 5000), target=1.0,
         walls=("primitive",), rss_check=True),
    dict(case="drum 100000", n=100_000, lattice="hcp", drum=True, steps=(1000, 3000), target=0.8, walls=("mesh",),
         rss_check=True),
)
QUICK_DENSE_CASES = (  # --quick: the machinery in about a minute (1000 steps: 200 were below the noise of a run)
    dict(case="sc 2000", n=2000, lattice="sc", drum=False, steps=(100, 1100), target=None,
         walls=("primitive", "mesh"), threads2=True),
    dict(case="fcc 2000", n=2000, lattice="fcc", drum=False, steps=(100, 1100), target=None,
         walls=("primitive", "mesh")),
)
DENSE_MILLION = 1_000_000  # balls of the taimill-only run that proves the size runs (--skip-million skips it)
MILLION_STEPS = 10  # its --duration in steps, one frame interval (taimill takes 11: frames at both ends)
DENSE_RSS_BASE, DENSE_RSS_PER_BALL = 300e6, 1e3  # bytes: peak RSS at 10⁵ balls ≤ 300 MB + 1 kB per ball
DENSE_TIMEOUT = 1800  # s per child process
DENSE_EVENTS = ("spectra", "rows")  # taimill's event outputs; the target applies to the spectra
# runs of each length per measurement up to this many balls, the least time of each
# counting: a run's start-up varies by ± 0.3 s, 7 % of what 2000 steps of 20 000 balls cost
DENSE_REPEATS, DENSE_REPEAT_UP_TO = 2, 20_000


def run_child(cmd: list[str], cwd: Path, timeout: float, env: dict | None = None, log: Path | None = None) -> dict:
    """Run cmd to its end: wall seconds, CPU seconds (user + system, all its threads) and
    peak RSS of that child alone (os.wait4), its stdout. Output goes to files (no pipe to
    drain: the child is reaped by os.wait4, not by Popen). RuntimeError on failure."""
    log = log or Path(tempfile.mkstemp(prefix="bench-child-", suffix=".log")[1])
    with open(log, "w") as out, open(log.with_suffix(".err"), "w") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > timeout:
                proc.kill()
                os.wait4(proc.pid, 0)
                proc.returncode = -9
                raise RuntimeError(f"{Path(cmd[0]).name} timed out after {timeout:g} s")
            time.sleep(0.02)
        wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    stdout, stderr = log.read_text(), log.with_suffix(".err").read_text()
    if proc.returncode:
        tail = (stderr.strip() or stdout.strip()).splitlines()
        raise RuntimeError(f"{Path(cmd[0]).name} exit {proc.returncode}: {tail[-1] if tail else ''}")
    return dict(wall=wall, cpu=usage.ru_utime + usage.ru_stime, rss_mib=usage.ru_maxrss / 1024, stdout=stdout)


def per_ball_step(runs: list[dict], n: int) -> dict:
    """The figures of runs of N1 and of N2 steps (one or more of each: the least wall and
    the least CPU time of each length count): ns per ball-step from their difference, the
    set-up (the N1 run's wall less its steps' share), the largest peak RSS."""
    first, last = min(r["steps"] for r in runs), max(r["steps"] for r in runs)
    best = {k: [min(r[k] for r in runs if r["steps"] == s) for s in (first, last)] for k in ("wall", "cpu")}
    (w1, w2), (c1, c2) = best["wall"], best["cpu"]
    ns_wall = (w2 - w1) / ((last - first) * n) * 1e9
    return dict(steps=[first, last], wall=[w1, w2], cpu=[c1, c2], runs=len(runs) // 2,
                ns_cpu=(c2 - c1) / ((last - first) * n) * 1e9, ns_wall=ns_wall,
                setup=w1 - ns_wall * first * n * 1e-9, rss_mib=max(r["rss_mib"] for r in runs))


def taimill_cli(preset: Path, tmp: Path, n: int, steps: tuple, events: str, threads: int, repeats: int = 1,
                warm: int | None = None) -> dict:
    """`python -m taimill run PRESET --duration D --out X.zarr --json` with
    TI_CPU_MAX_NUM_THREADS = threads: an untimed warm-up run of `warm` steps, by default
    one frame interval (compiles what Taichi's cache lacks: every kernel runs in the
    first step; a drum's run must outlast its start-up ramp, so its warm-up is N1), then
    `repeats` runs of N1 steps and of N2 steps. Frames every gcd(N1, N2) steps; the
    store holds the events as rows or as spectra."""
    import shutil

    every = math.gcd(*steps)
    cli = preset.with_name(f"cli-{events}.toml")  # beside the preset: its jar and start are relative paths
    cli.write_text(preset.read_text().split("[outputs]")[0]
                   + f'[outputs]\ntrajectory_rate = {float(f"{1 / (every * DENSE_DT):.9g}")!r}\nevents = "{events}"\n')
    env = os.environ | {"PYTHONPATH": str(ROOT), "TI_CPU_MAX_NUM_THREADS": str(threads)}
    runs = []
    for k, n_steps in enumerate((warm or every, *[s for s in steps for _ in range(repeats)])):
        name = f"{preset.parent.name}-{events}-{threads}-{k}"
        # a duration of whole frame intervals: from_preset rounds duration / (every dt), + ¼ step for the rounding
        cmd = [sys.executable, "-m", "taimill", "run", str(cli), "--duration", repr((n_steps + 0.25) * DENSE_DT),
               "--out", str(tmp / f"{name}.zarr"), "--json", "--overwrite"]
        try:
            r = run_child(cmd, ROOT, DENSE_TIMEOUT, env, tmp / f"{name}.log")
        finally:
            shutil.rmtree(tmp / f"{name}.zarr", ignore_errors=True)
        r["steps"] = json.loads(r.pop("stdout"))["steps"]
        if r["steps"] != n_steps + 1:  # taimill takes frames at both ends: N steps after the first
            raise RuntimeError(f"taimill ran {r['steps']} steps, expected {n_steps + 1}")
        runs.append(r)
    out = per_ball_step(runs[1:], n)
    out["warm_up"] = {k: runs[0][k] for k in ("steps", "wall", "cpu", "rss_mib")}
    out["rss_mib"] = max(out["rss_mib"], runs[0]["rss_mib"])
    return out


def liggghts_deck(preset: Path, case: Path, walls: str, drum: bool) -> list[str]:
    """The deck `taimill export liggghts` writes for the preset, without its dumps and
    time-step check, the movers dropped for a static jar; the box around the jar alone
    (the export's spans the jar's path around the plate axis, R_p = 2 m: tens of
    millions of empty neighbour bins). walls "primitive": the STL mesh replaced by
    LIGGGHTS' own zcylinder and two zplanes (floor and lid), same contact models."""
    from taimill.bridge.liggghts import export_case
    from taimill.model.preset import load_preset

    p = load_preset(preset)
    export_case(p, case)
    R, H, reach = p.jar.radius, p.jar.height, p.jar.radius + 4 * p.balls.radius
    keep = []
    for line in (case / "in.taimill").read_text().splitlines():
        if line.startswith(("dump", "fix dtcheck", "run ")) or not drum and line.startswith(("fix plate", "fix spin")):
            continue
        words = line.split()
        if line.startswith("fix jar all mesh/surface"):
            xc = float(words[words.index("move") + 1])  # the jar's axis: the mesh moved by R_p along x
            if abs(xc - p.plate_radius) > 1e-12:
                raise RuntimeError(f"the deck moves the jar to x = {xc}, not R_p = {p.plate_radius}")
            if walls == "primitive":
                continue
        if line.startswith("fix walls all wall/gran") and walls == "primitive":
            at = words.index("mesh")  # fix walls all wall/gran MODELS mesh n_meshes 1 meshes jar SETTINGS
            models, settings = " ".join(words[4:at]), " ".join(words[at + 5:])
            keep += [f"fix cyl all wall/gran {models} primitive type 2 zcylinder {R!r} {xc!r} 0. {settings}",
                     f"fix floor all wall/gran {models} primitive type 2 zplane 0. {settings}",
                     f"fix lid all wall/gran {models} primitive type 2 zplane {H!r} {settings}"]
            continue
        keep.append(line)
    data = (case / "start.data").read_text().splitlines()
    for i, line in enumerate(data):
        if line.endswith("xlo xhi"):
            data[i] = f"{p.plate_radius - reach!r} {p.plate_radius + reach!r} xlo xhi"
        elif line.endswith("ylo yhi"):
            data[i] = f"{-reach!r} {reach!r} ylo yhi"
    (case / "start.data").write_text("\n".join(data) + "\n")
    return keep


def liggghts_cli(preset: Path, tmp: Path, n: int, steps: tuple, walls: str, drum: bool, repeats: int = 1) -> dict:
    """`liggghts -in DECK -log LOG` on one core, `repeats` runs of N1 steps and of N2
    steps (liggghts_deck); each log must show n atoms at its end (the deck stops on a
    lost atom). loop_ns_wall: the same difference of LIGGGHTS' own loop times."""
    case = tmp / f"lig-{preset.parent.name}-{walls}"
    deck = liggghts_deck(preset, case, walls, drum)
    runs = []
    for k, n_steps in enumerate(s for s in steps for _ in range(repeats)):
        (case / f"in.{n_steps}").write_text("\n".join(deck + [f"run {n_steps}", ""]))
        r = run_child(["liggghts", "-in", f"in.{n_steps}", "-log", f"log.{k}"], case, DENSE_TIMEOUT,
                      log=case / f"out.{k}")
        loop = [ln.split() for ln in (case / f"log.{k}").read_text().splitlines()
                if ln.startswith("Loop time of")]  # Loop time of T on P procs for S steps with N atoms
        if not loop or int(loop[-1][8]) != n_steps or int(loop[-1][11]) != n:
            raise RuntimeError(f"LIGGGHTS log.{k}: {' '.join(loop[-1]) if loop else 'no loop line'}"
                               f" (expected {n_steps} steps with {n} atoms)")
        runs.append(dict(r, steps=n_steps, loop_wall=float(loop[-1][3]), procs=int(loop[-1][5])))
    loop = [min(r["loop_wall"] for r in runs if r["steps"] == s) for s in steps]
    return per_ball_step(runs, n) | dict(loop_ns_wall=(loop[1] - loop[0]) / ((steps[1] - steps[0]) * n) * 1e9,
                                         procs=runs[0]["procs"])


def print_dense_header():
    print(f"  {'case':19} {'code':19} {'thr':>3} {'steps':>9} {'set-up s':>8} {'ns CPU/ball-step':>16}"
          f" {'ns wall/ball-step':>17} {'RSS MiB':>7} {'/LIGGGHTS':>9} {'target':>6}", flush=True)


def print_dense_row(r: dict):
    steps = "{}→{}".format(*r["steps_asked"])
    if "error" in r:
        print(f"  {r['case']:19} {r['code']:19} {r['threads']:>3} {steps:>9} failed: {r['error']}", flush=True)
        return
    ratio = f"{r['ratio']:.2f}" if r.get("ratio") is not None else "-"
    target = f"≤ {r['target']:g} {r['verdict']}" if r.get("verdict") else ""
    print(f"  {r['case']:19} {r['code']:19} {r['threads']:>3} {steps:>9} {r['setup']:>8.1f} {r['ns_cpu']:>16.1f}"
          f" {r['ns_wall']:>17.1f} {r['rss_mib']:>7.0f} {ratio:>9} {target}", flush=True)


def dense_million(tmp: Path) -> dict:
    """One `taimill run` of DENSE_MILLION balls (close-packed bed, statistics), MILLION_STEPS
    steps on one thread, end to end: wall, CPU, peak RSS of the process."""
    preset = dense_case(tmp, DENSE_MILLION, False)
    cli = preset.with_name("cli.toml")
    cli.write_text(preset.read_text().split("[outputs]")[0]
                   + f'[outputs]\ntrajectory_rate = {float(f"{1 / (MILLION_STEPS * DENSE_DT):.9g}")!r}\nevents = "spectra"\n')
    out = tmp / "million.zarr"
    cmd = [sys.executable, "-m", "taimill", "run", str(cli), "--duration", repr((MILLION_STEPS + 0.25) * DENSE_DT),
           "--out", str(out), "--json", "--overwrite"]
    env = os.environ | {"PYTHONPATH": str(ROOT), "TI_CPU_MAX_NUM_THREADS": "1"}
    r = run_child(cmd, ROOT, DENSE_TIMEOUT, env, tmp / "million.log")
    summary = json.loads(r.pop("stdout"))
    return r | dict(steps=summary["steps"], run_wall=summary.get("wall_seconds"))


def dense_section(quick: bool, million: bool = True, only: str | None = None) -> list[dict]:
    """`only`: the cases whose name contains it (and no 10⁶ run)."""
    import shutil

    if not shutil.which("liggghts"):
        print("\n5. Dense beds: liggghts not on PATH, LIGGGHTS rows skipped")
    cases = [c for c in (QUICK_DENSE_CASES if quick else DENSE_CASES) if only is None or only in c["case"]]
    million = million and only is None
    print(f"\n5. Dense beds: steel balls (r = {DENSE_RADIUS_MM:g} mm) on lattices of pitch 2r + {DENSE_GAP:g} m in a"
          " cylinder, Hertz e = 0.516, μ = 0.8, dt = 1 µs; taimill and LIGGGHTS 3.8 end to end through their"
          f" command lines, one core each (taimill: a warm-up run first; up to {DENSE_REPEAT_UP_TO} balls the best of"
          f" {DENSE_REPEATS} runs of each length); per ball-step = (N2-step run − N1-step run)"
          " / ((N2 − N1) n); ratio = taimill / LIGGGHTS (primitive walls; mesh for the drum), CPU")
    print_dense_header()
    rows = []
    with tempfile.TemporaryDirectory(prefix="taimill-dense-") as tmp_name:
        tmp = Path(tmp_name)
        for c in cases:
            base = dict(case=c["case"], n=c["n"], lattice=c["lattice"], drum=c["drum"], steps_asked=list(c["steps"]))
            try:
                preset = dense_case(tmp, c["n"], c["drum"], c["lattice"])
            except Exception as e:  # noqa: BLE001 - one line, the section goes on
                rows.append(dict(base, code="set-up", threads=1, error=f"{type(e).__name__}: {e}"))
                print_dense_row(rows[-1])
                continue
            rep = DENSE_REPEATS if c["n"] <= DENSE_REPEAT_UP_TO else 1
            jobs = [(f"LIGGGHTS {w}", 1, lambda w=w: liggghts_cli(preset, tmp, c["n"], c["steps"], w, c["drum"], rep))
                    for w in c["walls"] if shutil.which("liggghts")]
            warm = c["steps"][0] if c["drum"] else None
            jobs += [(f"taimill {ev}", 1, lambda ev=ev: taimill_cli(preset, tmp, c["n"], c["steps"], ev, 1, rep, warm))
                     for ev in DENSE_EVENTS]
            if c.get("threads2"):
                jobs.append(("taimill 2 threads", 2,
                             lambda: taimill_cli(preset, tmp, c["n"], c["steps"], "spectra", 2, rep, warm)))
            here = []
            for code, threads, job in jobs:
                try:
                    r = dict(base, code=code, threads=threads, **job())
                except Exception as e:  # noqa: BLE001 - one line, the section goes on
                    r = dict(base, code=code, threads=threads, error=f"{type(e).__name__}: {e}")
                here.append(r)
            reference = next((r for r in here if r["code"] == f"LIGGGHTS {'mesh' if c['drum'] else 'primitive'}"
                              and "error" not in r), None)
            for r in here:
                if r["code"].startswith("taimill") and r["threads"] == 1 and "error" not in r and reference:
                    r["ratio"] = r["ns_cpu"] / reference["ns_cpu"]
                    if r["code"] == "taimill spectra" and c["target"] is not None:
                        r.update(target=c["target"], verdict="PASS" if r["ratio"] <= c["target"] else "MISS")
                print_dense_row(r)
            rows += here
            one = next((r for r in here if r["code"] == "taimill spectra" and "error" not in r), None)
            two = next((r for r in here if r["code"] == "taimill 2 threads" and "error" not in r), None)
            if one and two:
                eff = one["ns_wall"] / (2 * two["ns_wall"])
                rows.append(dict(base, code="parallel efficiency", threads=2, wall_1=one["ns_wall"],
                                 wall_2=two["ns_wall"], efficiency=eff))
                print(f"  {'':19} 2 threads: wall {one['ns_wall']:.1f} → {two['ns_wall']:.1f} ns/ball-step,"
                      f" parallel efficiency {eff:.2f} (wall 1 thread / (2 × wall 2 threads))", flush=True)
            if c.get("rss_check") and one:
                limit = (DENSE_RSS_BASE + DENSE_RSS_PER_BALL * c["n"]) / 1e6
                mb = one["rss_mib"] * 2**20 / 1e6
                verdict = "PASS" if mb <= limit else "MISS"
                rows.append(dict(base, code="RSS check", threads=1, rss_mb=mb, limit_mb=limit, verdict=verdict))
                print(f"  {'':19} peak RSS (taimill spectra, one thread): {mb:.0f} MB = 300 MB +"
                      f" {(mb * 1e6 - DENSE_RSS_BASE) / c['n'] / 1e3:.2f} kB/ball; limit 300 MB + 1 kB/ball ="
                      f" {limit:.0f} MB: {verdict}", flush=True)
        if million and not quick:
            base = dict(case=f"bed {DENSE_MILLION}", n=DENSE_MILLION, lattice="hcp", drum=False, code="taimill run",
                        threads=1)
            try:
                r = dict(base, **dense_million(tmp))
                print(f"  {r['case']:19} {r['code']:19} {1:>3} whole process {r['steps']} steps: wall {r['wall']:.1f} s,"
                      f" CPU {r['cpu']:.1f} s, peak RSS {r['rss_mib']:.0f} MiB"
                      f" ({r['rss_mib'] * 2**20 / DENSE_MILLION / 1e3:.2f} kB/ball)", flush=True)
            except Exception as e:  # noqa: BLE001
                r = dict(base, error=f"{type(e).__name__}: {e}")
                print(f"  {r['case']:19} {r['code']:19} failed: {r['error']}", flush=True)
            rows.append(r)
    return rows


WORKERS.update(dense=work_dense)

from bench_kernels import kernels_section, work_kernels  # noqa: E402 - section 11, its own file

WORKERS.update(kernels=work_kernels)


# ---------------------------------------------------------------- main
# ---- 8. A/B against another checkout
AB_ROUNDS = 3  # interleaved rounds: this tree, the other, ...; the best of each is quoted
AB_REFERENCE_SECONDS = 3.0  # s simulated, CY steel on one thread
AB_BED_N = 100_000  # the settled dense bed of section 5


def ab_section(other: Path, rounds: int = None, cases: str = "both") -> list[dict]:
    """The same measurements from this checkout and from `other` (e.g. a worktree of
    the commit before a change), interleaved in one run so that both see the same
    machine: the reference case on one thread (CPU µs per step) and the settled 10⁵
    dense bed (CPU ns per ball-step after DENSE_SETTLE steps). Each worker imports the
    taimill of its own checkout (PYTHONPATH)."""
    rounds = rounds or AB_ROUNDS
    print(f"\n8. A/B: this checkout ({ROOT}) against {other}, {rounds} interleaved rounds, best of each;"
          " one thread, CPU time")
    rows = []
    with tempfile.TemporaryDirectory(prefix="taimill-ab-") as tmp:
        bed = dense_case(Path(tmp), AB_BED_N, False) if cases in ("both", "bed") else None
        for rnd in range(rounds):
            for label, root in (("this", ROOT), ("other", other)):
                if cases in ("both", "cy"):
                    r = measure(dict(kind="reference", duration=AB_REFERENCE_SECONDS, threads=1, copies=1, public=False,
                                     use_grid=False), root=root)
                    rows.append(dict(case="CY steel", tree=label, round=rnd, value=r["cpu"] / r["steps"] * 1e6
                                     if "cpu" in r else None, unit="CPU µs/step", **r))
                    print(f"  round {rnd} {label:5} CY steel             {rows[-1]['value']:.4f} CPU µs/step", flush=True)
                if bed is None:
                    continue
                r = measure(dict(kind="dense", preset=str(bed), steps=DENSE_STEPS[AB_BED_N], threads=1, drum=False,
                                 settle=DENSE_SETTLE[AB_BED_N], spawned=time.time()), timeout=3600, root=root)
                settled = r.get("settled", {})
                value = settled["cpu"] / (settled["steps"] * AB_BED_N) * 1e9 if settled else None
                rows.append(dict(case=f"bed {AB_BED_N} settled", tree=label, round=rnd, value=value,
                                 unit="CPU ns/ball-step", **r))
                row = rows[-1]
                shown = f"{row['value']:.4f}" if row["value"] is not None else row.get("error", "failed")
                print(f"  round {rnd} {row['tree']:5} {row['case']:20} {shown} {row['unit']}", flush=True)
    for case, unit in dict.fromkeys((r["case"], r["unit"]) for r in rows):
        best = {t: min((r["value"] for r in rows if r["case"] == case and r["tree"] == t and r["value"] is not None),
                       default=None) for t in ("this", "other")}
        if None not in best.values():
            print(f"  {case}: this {best['this']:.4f}, other {best['other']:.4f} {unit} (best of {rounds});"
                  f" this / other = {best['this'] / best['other']:.3f}")
    return rows


SIGNAL_DELAYS = (1.0, 5.0, 30.0)  # s after the command started
SIGNAL_LIMIT = 2.0  # s from the signal to the exit


def interrupted_at(cmd: list[str], delay: float, out: Path, env: dict) -> dict:
    """Start cmd, SIGINT it `delay` s later; how long it took to exit, its code, its
    last stderr line, and whether `out` is readable (or absent)."""
    import shutil
    import signal as sig

    from taimill.store.run import open_run
    from taimill.store.sweep import open_sweep

    shutil.rmtree(out, ignore_errors=True)
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    ended = proc.poll() is not None
    t0 = time.perf_counter()
    proc.send_signal(sig.SIGINT)
    _, err = proc.communicate(timeout=600)
    latency = time.perf_counter() - t0
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if not out.exists():
        store = "nothing written"
    else:
        try:
            s = open_sweep(out) if "sweep" in cmd else open_run(out)
            store = f"readable ({getattr(s, 'status', None) or 'sweep'})"
        except Exception as e:  # noqa: BLE001 - what the bench reports
            store = f"UNREADABLE: {e}"
    shutil.rmtree(out, ignore_errors=True)
    return dict(delay=delay, seconds=latency, code=proc.returncode, ended_before=ended, line=lines[-1] if lines else "",
                store=store, ok=not ended and latency <= SIGNAL_LIMIT and proc.returncode == 130
                and "Traceback" not in err and not store.startswith("UNREADABLE"))


def signals_section() -> list[dict]:
    print(f"\n9. Signals: SIGINT {', '.join(f'{d:g}' for d in SIGNAL_DELAYS)} s into a run of 10⁵ balls and into a"
          f" sweep; exit within {SIGNAL_LIMIT:g} s, the store readable")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-signals-") as tmp:
        tmp = Path(tmp)
        case = dense_case(tmp, 100_000, drum=True, lattice="sc")
        env = os.environ | {"PYTHONPATH": str(ROOT)}
        cmds = {"run 10⁵ balls": [sys.executable, "-m", "taimill", "run", str(case), "--duration", "1", "--yes",
                                  "--out", str(tmp / "run.zarr")],
                "sweep, 17 points": [sys.executable, "-m", "taimill", "sweep", str(PRESET), "--ratio", "0:-4:0.25",
                                     "--duration", "24", "--out", str(tmp / "sweep.zarr")]}
        # an untimed warm-up: the kernels of both in Taichi's cache, as on a user's second day
        for what, cmd in cmds.items():
            interrupted_at(cmd, 15.0, Path(cmd[-1]), env)
        for what, cmd in cmds.items():
            for delay in SIGNAL_DELAYS:
                r = interrupted_at(cmd, delay, Path(cmd[-1]), env) | {"what": what}
                rows.append(r)
                print(f"  {what:18s} at {delay:4.0f} s: exit {r['code']} after {r['seconds']:5.2f} s  "
                      f"{'ok ' if r['ok'] else 'BAD'}  {r['store']:28s} {r['line'][:90]}")
    return rows


def grinding_section() -> dict:
    from taimill.outcome.condition import read_file
    from taimill.outcome.grinding import Austin, Grinding, SizeClasses, feed, grind

    cond = read_file(ROOT / "examples" / "outcome" / "condition-a.json")
    classes = SizeClasses(8e-4, 39)  # 40 classes with the sink
    g = Grinding(Austin(0.4, 0.9, 3.5), capture_g=1e-3, f_mat=0.5, xw_min=0.05, k_att=1e-4)
    m0 = feed(classes, 200e-6, 0.5)
    hours = [0, 0.25, 0.5, 1, 2, 4, 8, 16, 32, 64]
    t = [3600.0 * h for h in hours]
    grind(g, classes, cond, m0, t)
    walls, cpus = [], []
    for _ in range(5):
        w0, c0 = time.perf_counter(), time.process_time()
        grind(g, classes, cond, m0, t)
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    out = {"classes": len(classes), "times": len(t), "wall_s": min(walls), "cpu_s": min(cpus)}
    print(f"\n10. Population balance: {len(classes)} classes, {len(t)} times 0-64 h: "
          f"{1e3 * out['wall_s']:.1f} ms wall, {1e3 * out['cpu_s']:.1f} ms CPU (best of 5)")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short run for CI (< 2 min)")
    ap.add_argument("--only", choices=("reference", "scaling", "recording", "sweep", "dense", "presets", "trajectory",
                                       "signals", "grinding", "kernels"),
                    help="run one section")
    ap.add_argument("--skip-million", action="store_true", help="dense beds: skip the taimill run of 10⁶ balls")
    ap.add_argument("--case", help="dense beds: only the cases whose name contains this ('sc 100000')")
    ap.add_argument("--json", type=Path, metavar="FILE", help="write every number to FILE")
    ap.add_argument("--ab", type=Path, metavar="DIR", help="only section 8: this checkout against the one in DIR"
                    " (e.g. `git worktree add DIR HEAD~1`), interleaved")
    ap.add_argument("--ab-rounds", type=int, help=f"rounds of --ab (default {AB_ROUNDS})")
    ap.add_argument("--ab-cases", choices=("both", "cy", "bed"), default="both", help="cases of --ab")
    ap.add_argument("--backend", help="where taimill's kernels run: cpu (default), cuda or auto; every worker and "
                    "`taimill run` child inherits it (TAIMILL_BACKEND)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker_main(args.worker)
        return
    if args.backend:
        from taimill.physics.backend import select

        try:
            select(args.backend)  # TAIMILL_BACKEND, which start_taichi's workers and the dense runs inherit
        except ValueError as err:
            sys.exit(f"bench.py: {err}")
    t0 = time.perf_counter()
    report = dict(machine=machine(), quick=args.quick)
    print_machine(report["machine"])
    if args.ab:
        report["ab"] = ab_section(args.ab.resolve(), args.ab_rounds, args.ab_cases)
        args.only = "ab"
    if args.only in (None, "reference"):
        duration = QUICK_DURATION if args.quick else FULL_DURATION
        report["reference_duration"] = duration
        report["reference"], report["sweep_estimate_seconds"] = reference_section(duration)
    if args.only in (None, "scaling"):
        report["scaling"], report["scaling_slopes"] = scaling_section(args.quick)
    if args.only in (None, "recording"):
        duration = QUICK_DURATION if args.quick else FULL_DURATION
        report["recording"], report["recording_overhead"] = recording_section(duration)
    if args.only in (None, "sweep"):
        report["sweep"] = sweep_section(args.quick)
    if args.only in (None, "dense"):
        report["dense"] = dense_section(args.quick, not args.skip_million, args.case)
    if args.only in (None, "presets"):
        report["presets"] = presets_section(QUICK_DURATION if args.quick else FULL_DURATION)
    if args.only in (None, "trajectory"):
        report["trajectory"] = trajectory_section(1.0 if args.quick else QUICK_DURATION)
    if args.only in (None, "signals") and not args.quick:
        report["signals"] = signals_section()
    if args.only in (None, "grinding"):
        report["grinding"] = grinding_section()
    if args.only in (None, "kernels"):
        with tempfile.TemporaryDirectory(prefix="bench-kernels-") as tmp:
            report["kernels"] = kernels_section(args.quick, measure, dense_case, Path(tmp))
    report["machine"]["load_end"] = os.getloadavg()
    report["total_wall_seconds"] = time.perf_counter() - t0
    print("\nload: %.2f %.2f %.2f at the end;" % report["machine"]["load_end"],
          f"benchmark took {report['total_wall_seconds']:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")
        print(f"numbers written to {args.json}")


if __name__ == "__main__":
    main()
