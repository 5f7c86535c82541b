"""Section 11 of scripts/bench.py: where a large mill's step goes, kernel by kernel.

One mill of 10⁵ balls in parallel mode on ONE thread (the bench's simple-cubic dense bed,
static and as a drum turning at 30 rpm, frames every FRAME_EVERY steps), every Taichi
kernel of the step wrapped in a timer (a CPU kernel returns when it is done, so a call's
wall time is its work plus its launch). The serial share is what more threads cannot
shorten: the kernels that run on one thread whatever the thread count (SERIAL_KERNELS of
the build in use, named in each row), the host's time between kernels, and the launch
of every other kernel (its calls × the mean time of the cheapest kernel, a launch with
almost nothing to do). Amdahl: with serial share s, n threads give at most
1 / (s + (1 − s) / n); 2 threads reach efficiency 0.85 only if s ≤ 0.18, 16 threads 0.7
only if s ≤ 0.029.
"""

from __future__ import annotations

import collections
import statistics
import time

N_BALLS = 100_000
QUICK_BALLS = 10_000
WARM_STEPS = 200  # untimed: compiles every kernel of the step (a drum also rebuilds its lists)
TIMED_STEPS = 600
FRAME_EVERY = 100  # steps between frames: a frame every 0.1 ms at dt = 1 µs
SERIAL_LIMIT = 0.02  # issue 49: the serial share of a step at 10⁵ balls on one thread


def _kernel_modules():
    from taimill.physics import engine, grid, neighbours, reorder

    return engine, grid, neighbours, reorder


def serial_kernels() -> set[str]:
    """Names of the step's kernels that run on one thread: a kernel whose only
    top-level loop is serialised (`serial_kernel = True` on the module's kernel
    wrapper is how the engine marks them)."""
    names = set()
    for mod in _kernel_modules():
        for name, obj in vars(mod).items():
            if getattr(obj, "serial_kernel", False):
                names.add(name)
    return names


def _time_kernels(times: dict) -> list:
    """Wrap every Taichi kernel of the step's modules in a timer; returns the undo list."""
    undo = []
    for mod in _kernel_modules():
        for name, obj in list(vars(mod).items()):
            if not hasattr(obj, "_primal"):  # not a @ti.kernel
                continue

            def timed(*a, _k=obj, _n=name, **kw):
                t0 = time.perf_counter()
                try:
                    return _k(*a, **kw)
                finally:
                    rec = times[_n]
                    rec[0] += 1
                    rec[1] += time.perf_counter() - t0

            setattr(mod, name, timed)
            undo.append((mod, name, obj))
    return undo


def work_kernels(task: dict) -> dict:
    """The step's kernels of one large mill, timed on task["threads"] threads."""
    import bench
    from taimill.model.frame import Ramp
    from taimill.model.preset import load_preset
    from taimill.model.spec import from_preset
    from taimill.physics.runner import Runner

    threads = bench.start_taichi(task["threads"])
    spec = from_preset(load_preset(task["preset"])).replace(frame_every=task["frame_every"])
    if not task["drum"]:
        spec = spec.replace(plate=Ramp(0.0, 0.0, 0.0, 1.0), jar=Ramp(0.0, 0.0, 0.0, 1.0))
    runner = Runner([spec], mode="parallel")  # (the Runner picks it above 10⁴ balls)
    engine = runner.engine
    bench.compile_event_export(engine)
    bench.advance(engine, task["warm"], 1000)
    times = collections.defaultdict(lambda: [0, 0.0])
    undo = _time_kernels(times)
    try:
        (wall, cpu, _), steps = bench.advance(engine, task["steps"], 1000)
    finally:
        for mod, name, obj in undo:
            setattr(mod, name, obj)
    noop = _noop_step(engine)
    kernels = {k: dict(calls=c, seconds=s) for k, (c, s) in sorted(times.items(), key=lambda kv: -kv[1][1])}
    return dict(threads=threads, mode=engine.mode, steps=steps, wall=wall, cpu=cpu, kernels=kernels,
                serial=sorted(serial_kernels()), noop_seconds=noop)


def _noop_step(engine, samples: int = 20) -> float | None:
    """Mean wall time of a step launch that does nothing (a margin no event buffer has),
    each right after a real step (the caches as a launch finds them): the launch and
    the step's scalar work on one thread. None where the step is several kernels."""
    from taimill.physics import engine as E

    step = getattr(E, "step_parallel", None)
    if step is None:
        return None
    F, times = engine.F, []
    k = engine.steps_per_kernel
    for _ in range(samples):
        step(F, engine.launch_margin, int(F.state.step[0]) + k, k, False)
        t0 = time.perf_counter()
        step(F, engine.launch_margin, 0, k, False)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def shares(r: dict) -> dict:
    """The serial share of a work_kernels result and its parts (fractions of the wall)."""
    k = r["kernels"]
    in_kernels = sum(v["seconds"] for v in k.values())
    host = max(0.0, r["wall"] - in_kernels)  # drains, the launch loop, the timers
    serial = sum(v["seconds"] for n, v in k.items() if n in r["serial"])
    # a launch: the mean of the serial flag kernel (a launch with nothing to do), the
    # step's own launch and scalars where the step is one kernel (noop_seconds)
    launch = min(v["seconds"] / v["calls"] for n, v in k.items() if n in r["serial"])
    per_call = {n: r["noop_seconds"] if n == "step_parallel" and r.get("noop_seconds") else launch for n in k}
    launches = sum(per_call[n] * v["calls"] for n, v in k.items() if n not in r["serial"])
    total = r["wall"]
    return dict(serial_kernels=serial / total, host=host / total, launches=launches / total,
                serial_share=(serial + host + launches) / total, launch_us=launch * 1e6,
                step_ms=total / r["steps"] * 1e3)


def kernels_section(quick: bool, measure, dense_case, tmp, threads: int = 2) -> list[dict]:
    """The rows at 1 thread (static bed and drum), then the static bed's parallel
    efficiency on `threads` threads (the same steps)."""
    n = QUICK_BALLS if quick else N_BALLS
    print(f"\n11. The step's kernels, one mill of {n} balls, one thread (frames every {FRAME_EVERY} steps;"
          f" {TIMED_STEPS} steps after {WARM_STEPS}); serial share target ≤ {SERIAL_LIMIT:.0%} at 10⁵")
    rows = []
    for drum in (False, True):
        case = dense_case(tmp, n, drum=drum, lattice="sc")
        r = measure(dict(kind="kernels", preset=str(case), drum=drum, threads=1, warm=WARM_STEPS, steps=TIMED_STEPS,
                         frame_every=FRAME_EVERY), timeout=3600)
        label = f"{'drum' if drum else 'sc bed'} {n}"
        if "error" in r:
            print(f"  {label}: {r['error']}")
            rows.append(dict(case=label, **r))
            continue
        s = shares(r)
        rows.append(dict(case=label, **r, **s))
        print(f"  {label}: {s['step_ms']:.2f} ms a step; serial share {s['serial_share']:.2%} = serial kernels "
              f"{s['serial_kernels']:.2%} + host between kernels {s['host']:.2%} + launches {s['launches']:.2%}"
              f" (≈ {s['launch_us']:.0f} µs each)")
        for name, v in r["kernels"].items():
            share = v["seconds"] / r["wall"]
            if share >= 0.001 or name in r["serial"]:
                tag = "serial" if name in r["serial"] else ""
                print(f"    {name:22s} {v['calls']:6d} calls {1e6 * v['seconds'] / v['calls']:10.1f} µs each"
                      f" {share:7.2%}  {tag}")
    one = next((r for r in rows if r["case"].startswith("sc") and "error" not in r), None)
    if one and threads > 1:
        case = dense_case(tmp, n, drum=False, lattice="sc")
        r = measure(dict(kind="kernels", preset=str(case), drum=False, threads=threads, warm=WARM_STEPS,
                         steps=TIMED_STEPS, frame_every=FRAME_EVERY), timeout=3600)
        if "error" not in r:
            eff = (one["wall"] / one["steps"]) / (r["threads"] * r["wall"] / r["steps"])
            rows.append(dict(case=f"sc bed {n}, {r['threads']} threads", efficiency=eff, **r))
            print(f"  sc bed {n} on {r['threads']} threads: {1e3 * r['wall'] / r['steps']:.2f} ms a step, parallel"
                  f" efficiency {eff:.2f} (wall on 1 thread / ({r['threads']} × wall on {r['threads']}))")
    return rows
