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

5. Dense beds (issue 16): N = 10⁴, 10⁵, 10⁶ (10⁴ with --quick) steel balls (r = 6 mm)
   close-packed at rest in a cylinder (gaps of 1 nm: every contact loads at once),
   Hertz e = 0.516 (hertz-mindlin), Coulomb μ = 0.8, dt = 1 µs, plus a rotating-drum
   variant (the jar turning about its own axis at 30 rpm); taimill on one thread
   (the per-core cost; CPU time of the process) and, when `liggghts` is on PATH, LIGGGHTS-PUBLIC from the same
   start with the deck `taimill export liggghts` writes (no dumps, no mesh movers for
   the static bed), its loop time from its log (CPU = loop time × the process' CPU
   share; it runs on one core). Also the whole `taimill run` process of the 10⁵ case
   (set-up, 11 steps, store, summary; all threads): wall and CPU time, peak RSS, and its
   set-up alone: interpreter start to the first step done (issue 16: ≤ 10 s), wall and
   CPU seconds; twice ("CLI run", then "CLI again"), since the first run of a size on a
   machine compiles its kernels (≈ 7 s and ≈ 100 MB of peak RSS at 10⁵ balls) and the
   second finds them in Taichi's cache, as every later run does.

6. Every small-mill preset (issue 19: each ≥ 3x real time on one core): run() into a NullSink on
   one thread, 24 s simulated (3 s with --quick), as simulated seconds per CPU second
   and per wall second.
7. Dense trajectories (issue 19: 10⁵ frames/s ≤ 2x the cost of 100 frames/s): the
   reference preset into a ZarrSink at both rates, 3 s simulated (1 s with --quick),
   interleaved, best of two each; the ratio of CPU and of wall seconds.

On a shared machine the CPU-time columns (time.process_time of the measuring process)
are the per-core figures to quote; wall figures then measure the machine's load.

8. A/B (`--ab DIR`, alone): the reference case (CPU µs per step, one thread, 3 s) and the
   settled 10⁵ dense bed of section 5 (CPU ns per ball-step) from this checkout and
   from the one in DIR, interleaved rounds in one run, best of each: a change's
   before/after on the same machine at the same time.

    scripts/bench.py [--quick] [--only reference|scaling|recording|sweep|dense|presets|trajectory] [--liggghts-all] [--json FILE]
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
    import taichi as ti

    from taimill.physics.runner import init_taichi

    init_taichi(threads)
    return ti.lang.impl.current_cfg().cpu_max_num_threads


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
    from taimill.store.run import ZarrSink

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
    from taimill.physics.runner import init_taichi
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
    from taimill.store.run import ZarrSink

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
    if platform.processor():
        return platform.processor()
    with open("/proc/cpuinfo") as f:
        return next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), "unknown")


def machine() -> dict:
    return dict(
        cpus=os.cpu_count(), processor=cpu_model(), machine=platform.machine(), platform=platform.platform(),
        python=platform.python_version(), taichi=importlib.metadata.version("taichi"),
        numpy=importlib.metadata.version("numpy"), mem_total_mib=meminfo_mib("MemTotal"),
        mem_available_mib=meminfo_mib("MemAvailable"), load_start=os.getloadavg(),
    )


def print_machine(m: dict):
    print(f"taimill benchmark, {time.strftime('%Y-%m-%d %H:%M:%S')}")
    print(f"machine:  {m['cpus']} CPUs (os.cpu_count), {m['processor']}, {m['machine']}, {m['platform']}")
    print(f"memory:   {m['mem_total_mib'] / 1024:.1f} GiB, {m['mem_available_mib'] / 1024:.1f} GiB available")
    print(f"software: Python {m['python']}, taichi {m['taichi']}, numpy {m['numpy']}")
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
DENSE_N = (10_000, 100_000, 1_000_000)
DENSE_STEPS = {10_000: 1000, 100_000: 1000, 1_000_000: 100}  # timed steps per case
# the bed of 10⁵ balls is timed a second time, after this many more steps: a bed that
# has settled, holding every contact it will hold (its first steps are the bed closing
# its gaps; contacts open for long had scattered their data over memory and cost 1.8x)
DENSE_SETTLE = {100_000: 3000}
DENSE_RADIUS_MM = 6.0  # steel balls of the thesis
DENSE_GAP = 1e-9  # m between neighbours of the close-packed bed: a bed at rest, every contact closing at once
LIGGGHTS_MAX_N = 100_000  # 10⁶ balls in LIGGGHTS: ≈ 100 s per 1000 steps, skipped unless --liggghts-all
DRUM_RPM = 30.0  # the drum variant: the jar turns about its own axis at this speed


def dense_case(directory: Path, n: int, drum: bool) -> Path:
    """A preset of n steel balls (r = 6 mm) in a close-packed bed filling the lower part
    of a cylinder of height 1.5 R (at most 1 m), start positions in start.npz: Hertz with constant
    restitution 0.516 (hertz-mindlin), Coulomb μ = 0.8, dt = 1 µs. Static: the drive at
    10⁻⁶ rpm (the worker sets it to exactly 0); drum: the jar turns at DRUM_RPM about
    its own axis after a 1 ms start-up."""
    import numpy as np

    from taimill.model.geometry import build_profile
    from taimill.model.placement import bed_placement

    r = DENSE_RADIUS_MM * 1e-3
    R = (n * (2 * r) ** 3 / math.sqrt(2) / math.pi) ** (1 / 3) + 2 * r  # the bed about R high
    H = min(1.5 * R, 0.999)  # jar files allow up to 1 m
    x = bed_placement(n, r, build_profile((("circle", {"radius": R}),), 0.0), H, gap=DENSE_GAP)
    case = directory / f"{'drum' if drum else 'bed'}{n}"
    case.mkdir(parents=True, exist_ok=True)
    (case / "jar.toml").write_text(f'description = "bench.py: cylinder for a bed of {n} balls"\n'
                                   f'height_mm = {1e3 * H!r}\nwall_material = "aisi-304"\n\n'
                                   f'[[profile]]\ntype = "circle"\nradius_mm = {1e3 * R!r}\n')
    np.savez(case / "start.npz", positions=x)
    drive = f"plate_rpm = 1e-6\njar_rpm = {DRUM_RPM}\nramp_time = 0.001\n" if drum else "plate_rpm = 1e-6\nratio = 1\n"
    drive += "plate_radius_mm = 2000\n"  # the plate all but rests (Ω = 1e-6 rpm): R_p need only lie outside the jar
    duration = (2 * DENSE_STEPS[n] + DENSE_SETTLE.get(n, 0)) * 1e-6 + 2e-6
    (case / "bed.toml").write_text(
        'jar = "jar.toml"\npair = "steel-steel"\nlaw = "hertz-mindlin"\n' + drive
        + f'duration = {duration!r}\ndt = 1e-6\nseed = 1\ninitial_positions = "start.npz"\n'
        f'\n[friction]\nmu_s = 0.8\nmu_d = 0.8\n\n[balls]\ncount = {n}\nmaterial = "steel-c1020"\n'
        f'radius_mm = {DENSE_RADIUS_MM}\n\n[outputs]\ntrajectory_rate = {1 / duration!r}\n')  # one frame interval: frames at both ends
    return case / "bed.toml"


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


def work_liggghts(task: dict) -> dict:
    """LIGGGHTS on the same case from the same start: the deck taimill exports (static:
    without the mesh movers), `task["steps"]` steps, no dumps; its loop time from the
    log, CPU seconds and peak memory of its process; with task["settle"], that many
    steps more and task["steps"] again (result "settled")."""
    import resource

    from taimill.bridge.liggghts import export_case
    from taimill.model.preset import load_preset

    case = Path(task["dir"])
    export_case(load_preset(task["preset"]), case)
    keep = []
    for line in (case / "in.taimill").read_text().splitlines():
        if line.startswith(("dump", "fix dtcheck")) or (not task["drum"] and line.startswith(("fix plate", "fix spin"))):
            continue
        if line.startswith("run "):
            keep += [f"run {task['steps']}"] + [f"run {task['settle']}", f"run {task['steps']}"] * bool(task["settle"])
        else:
            keep.append(line)
    (case / "in.taimill").write_text("\n".join(keep) + "\n")
    t0 = time.perf_counter()
    proc = subprocess.run(["liggghts", "-in", "in.taimill", "-log", "log.liggghts"], cwd=case, capture_output=True,
                          text=True, timeout=task["timeout"])
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    log = (case / "log.liggghts").read_text() if (case / "log.liggghts").exists() else proc.stdout
    loop = [ln for ln in log.splitlines() if ln.startswith("Loop time of")]
    if proc.returncode or not loop:
        raise RuntimeError(f"liggghts failed ({proc.returncode}): {(proc.stderr or proc.stdout)[-300:]}")
    words = [ln.split() for ln in loop]  # Loop time of T on P procs for S steps with N atoms
    cpu = usage.ru_utime + usage.ru_stime
    loop_wall, steps, atoms = float(words[0][3]), int(words[0][8]), int(words[0][11])
    out = dict(threads=int(words[0][5]), wall=wall, loop_wall=loop_wall, steps=steps, atoms=atoms, cpu=cpu,
               loop_cpu=loop_wall * min(1.0, cpu / wall), setup=wall - sum(float(w[3]) for w in words),
               rss_mib=usage.ru_maxrss / 1024)
    if task["settle"]:
        late = float(words[-1][3])
        out["settled"] = dict(loop_wall=late, steps=int(words[-1][8]), loop_cpu=late * min(1.0, cpu / wall))
    return out


# `python -m taimill` with the end of its first step marked: the first launch advances
# one step alone (in either launch mode the same steps as one launch), then its
# (wall clock, CPU seconds of the process) go to stderr behind SETUP_MARKER.
SETUP_MARKER = "BENCH-SETUP "
CLI_LAUNCHER = f"""
import json, sys, time
from taimill.physics.engine import Engine
advance = Engine.advance
def first(self, n_steps):
    Engine.advance = advance
    advance(self, 1)
    print({SETUP_MARKER!r} + json.dumps([time.time(), time.process_time()]), file=sys.stderr, flush=True)
    if n_steps > 1:
        advance(self, n_steps - 1)
Engine.advance = first
sys.argv[0] = "taimill"
from taimill.cli import main
sys.exit(main())
"""


def work_cli(task: dict) -> dict:
    """The whole `taimill run PRESET --out RUN.zarr --json` process: wall seconds, CPU
    seconds and peak resident memory (what a user waits for and needs), and its set-up:
    from the spawn (interpreter start) to the first step done — imports, preset and
    positions, summary and store, Taichi's fields, kernels, the first neighbour lists."""
    import resource

    preset = Path(task["preset"])  # frames every 10 steps of 1 µs: a run of one frame interval is 11 steps
    cli = preset.with_name("cli.toml")
    cli.write_text(preset.read_text().split("[outputs]")[0] + "[outputs]\ntrajectory_rate = 100000\n")
    t0, spawned = time.perf_counter(), time.time()
    proc = subprocess.run([sys.executable, "-c", CLI_LAUNCHER, "run", str(cli), "--duration", "1e-5", "--out",
                           task["out"], "--json"], capture_output=True, text=True, timeout=task["timeout"], cwd=ROOT)
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise RuntimeError(proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "taimill run failed")
    summary = json.loads(proc.stdout)
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    mark = [json.loads(ln[len(SETUP_MARKER):]) for ln in proc.stderr.splitlines() if ln.startswith(SETUP_MARKER)]
    setup, setup_cpu = (mark[0][0] - spawned, mark[0][1]) if mark else (math.nan, math.nan)
    return dict(wall=wall, cpu=usage.ru_utime + usage.ru_stime, setup=setup, setup_cpu=setup_cpu,
                run_wall=summary["wall_seconds"], steps=summary["steps"], rss_mib=usage.ru_maxrss / 1024)


def dense_section(quick: bool, liggghts_all: bool) -> list[dict]:
    import shutil

    ns = DENSE_N[:1] if quick else DENSE_N
    have = shutil.which("liggghts") is not None
    print(f"\n5. Dense beds: close-packed steel balls (r = {DENSE_RADIUS_MM:g} mm) at rest in a cylinder, Hertz e = 0.516,"
          f" μ = 0.8, dt = 1 µs; one core each: CPU time per ball-step, peak RSS, set-up;"
          f" LIGGGHTS {'from the same start' if have else 'not installed (liggghts not on PATH)'}")
    print(f"  {'case':18} {'code':9} {'thr':>3} {'steps':>5} {'set-up s':>8} {'ns CPU/ball-step':>16}"
          f" {'ns wall/ball-step':>17} {'RSS MiB':>8} {'KiB/ball':>8} {'others':>6}")
    rows = []
    with tempfile.TemporaryDirectory(prefix="taimill-dense-") as tmp:
        cases = [(n, False) for n in ns] + [(ns[min(1, len(ns) - 1)], True)]
        for n, drum in cases:
            preset = dense_case(Path(tmp), n, drum)
            label = f"{'drum' if drum else 'bed'} {n}"
            steps = DENSE_STEPS[n]
            settle = 0 if drum or quick else DENSE_SETTLE.get(n, 0)
            late = []  # the settled bed's rows, printed after the CLI's
            r = measure(dict(kind="dense", preset=str(preset), steps=steps, threads=1, drum=drum, settle=settle,
                             spawned=time.time()), timeout=3600)
            rows.append(dict(case=label, code="taimill", n=n, drum=drum, **r))
            if "settled" in r:
                late.append(dict(rows[-1], **r["settled"], case=f"{label} settled"))
            if have and (n <= LIGGGHTS_MAX_N or liggghts_all):
                r = measure(dict(kind="liggghts", preset=str(preset), dir=str(Path(tmp) / f"lig{n}{drum}"),
                                 steps=steps, drum=drum, settle=settle, timeout=3600), timeout=3700)
                rows.append(dict(case=label, code="LIGGGHTS", n=n, drum=drum, **r))
                if "settled" in r:
                    late.append(dict(rows[-1], **r["settled"], case=f"{label} settled"))
            elif have:
                rows.append(dict(case=label, code="LIGGGHTS", n=n, drum=drum,
                                 error=f"skipped above {LIGGGHTS_MAX_N} balls (--liggghts-all runs it)"))
            if not drum and n == 100_000 or quick and not drum:
                # twice, each in its own worker (peak RSS is per process tree): the first
                # with the kernel cache as it is (a first run of this size compiles its
                # kernels: ≈ 7 s and 100 MB more at 10⁵ balls), the second warm
                for code in ("CLI run", "CLI again"):
                    out = Path(tmp) / f"cli{n}-{len(rows)}.zarr"
                    r = measure(dict(kind="cli", preset=str(preset), out=str(out), timeout=3600), timeout=3700)
                    rows.append(dict(case=label, code=code, n=n, drum=drum, **r))
            rows += late
            for row in rows[-6:]:
                if "printed" not in row:
                    print_dense_row(row)
                    row["printed"] = True
    pairs = {}
    for row in rows:
        if "ns_cpu" in row:
            pairs.setdefault(row["case"], {})[row["code"]] = row["ns_cpu"]
    for case, p in pairs.items():
        if "taimill" in p and "LIGGGHTS" in p:
            print(f"  {case}: taimill / LIGGGHTS CPU per ball-step = {p['taimill'] / p['LIGGGHTS']:.2f}"
                  " (issue 16 target ≤ 0.5)")
    return rows


WORKERS.update(dense=work_dense, liggghts=work_liggghts, cli=work_cli)


def print_dense_row(r: dict):
    if "error" in r:
        print(f"  {r['case']:18} {r['code']:9} {r['error']}", flush=True)
        return
    n = r["n"]
    if r["code"].startswith("CLI"):
        print(f"  {r['case']:18} {r['code']:9} whole process {r['wall']:.1f} s ({r['steps']} steps, store, summary),"
              f" peak RSS {r['rss_mib']:.0f} MiB = 300 MB + {(r['rss_mib'] * 2**20 - 300e6) / n / 1024:.2f} KiB/ball",
              flush=True)
        print(f"  {'':18} {'':9} set-up {r['setup']:.1f} s wall, {r['setup_cpu']:.1f} s CPU (interpreter start to the"
              f" first step done; issue 16: ≤ 10 s at 10⁵ balls); whole process {r['cpu']:.1f} s CPU", flush=True)
        return
    cpu = r["loop_cpu"] if r["code"] == "LIGGGHTS" else r["cpu"]
    wall = r["loop_wall"] if r["code"] == "LIGGGHTS" else r["wall"]
    r["ns_cpu"] = cpu / (r["steps"] * n) * 1e9
    r["ns_wall"] = wall / (r["steps"] * n) * 1e9
    others = f"{r['others']:.2f}" if "others" in r else "-"
    if "busy" in r:
        r.update(load_metrics(r))
        others = f"{r['others']:.2f}"
    print(f"  {r['case']:18} {r['code']:9} {r['threads']:>3} {r['steps']:>5} {r['setup']:>8.1f} {r['ns_cpu']:>16.1f}"
          f" {r['ns_wall']:>17.1f} {r['rss_mib']:>8.0f} {r['rss_mib'] * 1024 / n:>8.2f} {others:>6}", flush=True)


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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short run for CI (< 2 min)")
    ap.add_argument("--only", choices=("reference", "scaling", "recording", "sweep", "dense", "presets", "trajectory"),
                    help="run one section")
    ap.add_argument("--liggghts-all", action="store_true", help="dense beds: also run LIGGGHTS at 10⁶ balls")
    ap.add_argument("--json", type=Path, metavar="FILE", help="write every number to FILE")
    ap.add_argument("--ab", type=Path, metavar="DIR", help="only section 8: this checkout against the one in DIR"
                    " (e.g. `git worktree add DIR HEAD~1`), interleaved")
    ap.add_argument("--ab-rounds", type=int, help=f"rounds of --ab (default {AB_ROUNDS})")
    ap.add_argument("--ab-cases", choices=("both", "cy", "bed"), default="both", help="cases of --ab")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker_main(args.worker)
        return
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
        report["dense"] = dense_section(args.quick, args.liggghts_all)
    if args.only in (None, "presets"):
        report["presets"] = presets_section(QUICK_DURATION if args.quick else FULL_DURATION)
    if args.only in (None, "trajectory"):
        report["trajectory"] = trajectory_section(1.0 if args.quick else QUICK_DURATION)
    report["machine"]["load_end"] = os.getloadavg()
    report["total_wall_seconds"] = time.perf_counter() - t0
    print("\nload: %.2f %.2f %.2f at the end;" % report["machine"]["load_end"],
          f"benchmark took {report['total_wall_seconds']:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(report, indent=2) + "\n")
        print(f"numbers written to {args.json}")


if __name__ == "__main__":
    main()
