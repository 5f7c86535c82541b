"""The launcher: engines by shape, the compile notice, the launch/drain loop handing
each mill's output to its sink, faults (Taichi's start: the door, physics/ti.py).

    Runner(specs) — advances any batch of MillSpecs (runs, tests, calibration, sweeps).
    compile_plan(specs) — whether a Runner of these mills compiles kernels, and for how long.

A sink here is any object with the `events`, `frames` and `energy` calls of
`taimill.store.sinks.Sink` (and, if it has one, `spectra`: the mill's energy spectra
so far after each drain); the runner never imports a sink.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import math
import time
from pathlib import Path

import numpy as np

from taimill.errors import SimulationUnstable
from taimill.physics import state as S
from taimill.physics.engine import Engine, advance_fused, export_events, export_frames, step_flags, step_parallel
from taimill.physics.mill import write_mill
from taimill.physics.ti import cache_folder, describe, init_taichi, where
from taimill.model.cost import step_seconds
from taimill.model.spec import MillSpec, grid_cells_for
from taimill.model.spectra import Spectra
from taimill.schema import DERIVED_EVENT_COLUMNS, EVENT_COLUMNS

# balls: beyond this one mill runs in parallel mode (parallel_above). Measured crossover on
# the 2-core machine (scripts/bench.py): fused 366 vs parallel 673 µs/step at 10 000
# balls, 5263 vs 4311 at 100 000.
PARALLEL_ABOVE = 50_000
# ... on 4 threads or more: parallel mode costs ≈ 1.45× the fused mode per ball on one
# thread (it computes each contact from both balls; at 10⁵ balls 52.6 ns a ball-step
# fused, ≈ 76 parallel: 4311 µs a step on 2 threads at an efficiency of 0.88) and
# ≈ 50 µs a step of launch; measured on a 16-core machine (H100 host, before launches of
# two steps) 4 threads ran 2.7× one, so parallel mode is ahead from ≈ 50 µs / (52.6 −
# 76 / 2.7) ns ≈ 2000 balls. 10 000 leaves room for a slower machine's launches.
PARALLEL_ABOVE_MANY_THREADS = 10_000
# ... on a GPU, where the fused mode runs a mill on one GPU thread: a mill of more than a
# few hundred balls is better spread over the device whatever its launches cost. Not
# yet measured (scripts/device_check.sh shows both modes' figures on a lent machine).
PARALLEL_ABOVE_ON_GPU = 1000
# balls: up to this many a mill's neighbour lists are built from all pairs, not the
# spatial hash (identical lists, so identical results). Measured per step, one thread,
# 4 s runs, Xeon machine: CY steel 12 balls 0.239 vs 0.222 µs (-7 %), CY fluorite 1.14
# vs 1.10, EFV zirconia 20 balls 0.483 vs 0.469, graphite 24 balls 2.65 vs 2.59.
ALL_PAIRS_UP_TO = 32
# simulated seconds per fused launch (≥ 10⁴ steps). Each launch is followed by a drain
# into the sinks, whose NumPy work has a fixed cost per call (≈ 4 ms with the summary
# sink): at 0.05 s that was 17 % of a 12-ball run, at 0.25 s ≈ 6 %, at 1 s ≈ 2 % (CPU
# time of run() and of its drains, CY steel). A run killed mid-launch loses at most
# this much; a launch with more events than its buffer holds ends early anyway.
LAUNCH_SECONDS = 1.0
# frames buffered per mill between drains (fewer for huge mills): enough for a launch
# of LAUNCH_SECONDS at the mill's frame rate, within these bounds. Dense trajectories
# (10⁵ frames/s) otherwise cut launches to 2000 steps, each paying a drain.
FRAME_CAPACITY = (256, 32768)
# CPU seconds a fused launch may take at the high end of the measured cost per step
# (step_cost): the longest wait for an interrupt between launches.
LAUNCH_WALL_SECONDS = 0.5


def step_cost(specs) -> float:
    """CPU seconds of one step of the fused launch of `specs`, every mill at the high end
    of the measured cost per step (taimill.model.cost)."""
    return sum(step_seconds(s.n)[1] for s in specs)
_engines: dict = {}


def _engine_key(batch, balls, mode, use_grid, cells, frames=FRAME_CAPACITY[0], pool=None, reorder=None,
                models=None) -> tuple:
    """What an engine's fields and kernels depend on: ball counts with the same padded
    row length (Engine.BALL_PAD) share fields, as do frame capacities up to one of an
    engine already made (the last entry, compared as "at least")."""
    balls = -(-balls // Engine.BALL_PAD) * Engine.BALL_PAD
    return batch, balls, mode, use_grid, cells, pool, reorder, models, frames if mode == "fused" else 8


def _existing(key) -> Engine | None:
    for k, engine in _engines.items():
        if k[:-1] == key[:-1] and k[-1] >= key[-1]:
            return engine
    return None


def _engine(key: tuple) -> Engine:
    """Engines are reused within a process: new fields mean new kernel instances, and
    compiling those costs ≈ 1.3 s each. The contact models (per contact type, compiled
    into the kernels) must be the same. key: _engine_key's."""
    engine = _existing(key)
    if engine is None:
        batch, balls, mode, use_grid, cells, pool, reorder, models, frames = key
        engine = _engines[key] = Engine(batch, balls, mode=mode, use_grid=use_grid, grid_cells=cells,
                                        frame_capacity=frames, pool=pool, reorder=reorder, models=models)
    return engine


def models_of(specs: list[MillSpec]) -> tuple:
    """Per contact type, the distinct ContactModels of a batch in first-use order."""
    return tuple(tuple(dict.fromkeys(s.contact_models[ct] for s in specs)) for ct in range(S.CONTACT_TYPES))


def frame_capacity(specs: list[MillSpec]) -> int:
    """Frames a launch of LAUNCH_SECONDS of the densest mill needs (a power of two,
    within FRAME_CAPACITY, the upper bound shared by the batch's mills)."""
    lo, hi = FRAME_CAPACITY
    need = max(LAUNCH_SECONDS / (s.dt * s.frame_every) for s in specs) + 2
    return int(min(max(lo, hi // len(specs)), max(lo, 1 << math.ceil(math.log2(need)))))




# s, compiling the kernels of one engine (Runner.setup_seconds: Taichi's start, fields,
# kernels), fused mode, 12 balls, measured on the 2-core AMD EPYC machine the project is
# developed on with `taimill run p4-cy-steel` and a fresh TI_OFFLINE_CACHE_FILE_PATH:
# 3.6 s the first time, 0.87 s from Taichi's cache (CFG_OPTIMIZATION off; 19.7 and 2.0 s
# with it). Used until this machine has measured its own (the markers).
FIRST_COMPILE_SECONDS = 3.6
CACHED_COMPILE_SECONDS = 0.9
# CPU s of a set-up above which its kernels were compiled, not read from Taichi's cache:
# a Runner of those 12 balls took 3.66 s CPU the first time and 0.89 s from the cache; a
# parallel-mode Runner of 10⁵ balls (which compiles a step's first kernel up front) 1.54
# and 0.50 s (Runner.setup_seconds, the same machine). CPU time, not wall time: other
# processes on the cores stretch the wall time but hardly the CPU time.
FIRST_COMPILE_CPU_SECONDS = 1.2


@dataclasses.dataclass(frozen=True)
class CompilePlan:
    """Whether a Runner of some mills compiles kernels in this process, and for how long."""

    balls: int  #: the largest mill's ball count
    needed: bool  #: no engine of this shape in this process yet: kernels are compiled
    first: bool  #: no earlier run of this shape on this machine (as far as the markers tell)
    seconds: float  #: expected compile time: this shape's last measured one, or a first compile's
    marker: str  #: the marker file recording this shape's compiles

    def text(self) -> str:
        """"compiling kernels for 12 balls (first run of this size, ≈ 3.6 s)"."""
        why = "first run of this size" if self.first else "from the kernel cache"
        return (f"compiling kernels for {self.balls} ball{'s' if self.balls != 1 else ''} "
                f"({why}, ≈ {self.seconds:.2g} s)")


_listener = None  # told of every compile a Runner without its own on_compile does (announcing)


@contextlib.contextmanager
def announcing(on_compile):
    """Within: every Runner made without an `on_compile` of its own calls this one (a
    command whose simulations are made deep inside, as calibration's, says it compiles)."""
    global _listener
    before, _listener = _listener, on_compile
    try:
        yield
    finally:
        _listener = before


@functools.lru_cache(maxsize=1)
def _source_digest() -> str:
    """Of every file whose code the kernels are compiled from (physics and model), so
    that changed kernels count as a new shape."""
    h = hashlib.sha256(describe().encode())  # another Taichi compiles its own kernels
    root = Path(__file__).resolve().parent.parent
    for path in sorted([*root.glob("physics/*.py"), *root.glob("model/**/*.py")]):
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def parallel_above(arch: str, threads: int) -> int:
    """Balls beyond which one mill runs in parallel mode on `arch` with `threads` CPU threads."""
    if arch == "cuda":
        return PARALLEL_ABOVE_ON_GPU
    return PARALLEL_ABOVE if threads < 4 else PARALLEL_ABOVE_MANY_THREADS


def _runner_shape(specs, mode=None, use_grid=None, pool=None, reorder=None) -> tuple:
    """The engine key (_engine_key) a Runner of `specs` uses."""
    n = max(s.n for s in specs)
    use_grid = n > ALL_PAIRS_UP_TO if use_grid is None else use_grid
    mode = mode or ("parallel" if len(specs) == 1 and n > parallel_above(*where()) else "fused")
    cells = 1 << max(grid_cells_for(s) for s in specs).bit_length()
    return _engine_key(len(specs), n, mode, use_grid, cells, frame_capacity(specs), pool, reorder, models_of(specs))


def _markers() -> Path:
    """Where taimill notes which engine shapes were compiled on this machine: beside
    Taichi's cache folder (whose own index says nothing a caller could read)."""
    return Path(cache_folder()).parent / "taimill-kernels"


def _read(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def compile_plan(specs: list[MillSpec], **options) -> CompilePlan:
    """What Runner(specs, **options) will compile. A shape (padded ball count, batch,
    grid, contact models, …) counts as compiled before when its marker file exists:
    written after each compile with its measured time. The expected time is this
    shape's last compile from the cache, else this machine's last first or cached
    compile (machine.json), else FIRST_ or CACHED_COMPILE_SECONDS. Taichi's cache drops
    its least recently used kernels beyond 100 MB: a shape compiled long ago may
    compile anew while called cached."""
    key = _runner_shape(specs, **options)
    models = tuple(tuple(m.name for m in ms) for ms in key[-2])
    name = hashlib.sha256(repr((_source_digest(), key[:-2], models, key[-1])).encode()).hexdigest()[:24]
    marker = _markers() / f"{name}.json"
    mine, machine = _read(marker), _read(_markers() / "machine.json")
    first = "seconds" not in mine
    if first:
        seconds = machine.get("first_seconds", FIRST_COMPILE_SECONDS)
    else:
        seconds = mine["seconds"] if not mine.get("first") else machine.get("cached_seconds", CACHED_COMPILE_SECONDS)
    return CompilePlan(max(s.n for s in specs), _existing(key) is None, first, float(seconds), str(marker))


def _record_compile(plan: CompilePlan, seconds: float, cpu_seconds: float) -> None:
    """Note this shape as compiled, with its time (wall s), and the time as this
    machine's latest first or cached compile: a first compile if it took more than
    FIRST_COMPILE_CPU_SECONDS of CPU (a shape without a marker may find Taichi's cache
    filled by a run before the markers). Best effort: a folder that cannot be written
    only loses the note."""
    first = cpu_seconds > FIRST_COMPILE_CPU_SECONDS
    try:
        _markers().mkdir(parents=True, exist_ok=True)
        Path(plan.marker).write_text(json.dumps({"seconds": round(seconds, 3), "first": first, "balls": plan.balls}))
        machine = _read(_markers() / "machine.json")
        machine["first_seconds" if first else "cached_seconds"] = round(seconds, 3)
        (_markers() / "machine.json").write_text(json.dumps(machine))
    except OSError:
        pass


def events_table(raw: np.ndarray) -> dict[str, np.ndarray]:
    """Raw event rows (engine order) → typed columns of sinks.EVENT_COLUMNS, sorted by
    end time, then bodies, so every launch mode gives the same table."""
    cols = dict(zip(S.EVENT_FIELDS, raw.T))
    order = np.lexsort((cols["body_j"], cols["body_i"], cols["t_start"] + cols["duration"]))
    cols = {name: c[order] for name, c in cols.items()}
    return {name: DERIVED_EVENT_COLUMNS[name](cols) if name in DERIVED_EVENT_COLUMNS else cols[name].astype(dtype)
            for name, (dtype, _, _) in EVENT_COLUMNS.items()}


def status_message(code: int, ball: int, t: float, dt: float, pool: int | None = None) -> str:
    what = {
        S.NONFINITE: f"ball {ball} reached a non-finite or runaway state",
        S.ESCAPED: f"ball {ball} left the jar through a wall",
        S.SLOTS_FULL: f"ball {ball} has more than {S.PARTNER_SLOTS} simultaneous contacts",
        S.LIST_FULL: f"ball {ball} has more than {S.NEIGHBOURS} neighbours within the skin",
        S.POOL_FULL: f"ball {ball} opened a contact beyond the mill's open-contact pool"
                     f"{f' of {pool} rows' if pool else ''}",
    }[code]
    return f"unstable at t = {t:.6f} s: {what}; the time step dt = {dt:.3g} s is too large for the contact stiffness, or the input is unphysical"


class Runner:
    """Advances a batch of mills to their step targets, streaming to one sink each."""

    def __init__(self, specs: list[MillSpec], *, mode: str | None = None, use_grid: bool | None = None,
                 pool: int | None = None, reorder: bool | None = None, on_compile=None):
        """`use_grid`: neighbour lists from the spatial hash (default above
        ALL_PAIRS_UP_TO balls) or from all pairs (the same lists); `pool`: rows of each
        mill's open-contact pool (tests; default state.pool_rows); `reorder`: ball rows
        in grid order (tests; default: in parallel mode, Engine); `on_compile(plan)`:
        called with the CompilePlan before kernels are compiled (not when this
        process has them). `setup_seconds`: wall time of this set-up (Taichi's start,
        fields, loading the mills, compiling), which a run's speed leaves out."""
        t0, cpu0 = time.perf_counter(), time.process_time()
        plan = compile_plan(specs, mode=mode, use_grid=use_grid, pool=pool, reorder=reorder)
        on_compile = on_compile or _listener
        if plan.needed and on_compile:
            on_compile(plan)
        init_taichi()
        self.specs = specs
        self.engine = _engine(_runner_shape(specs, mode, use_grid, pool, reorder))
        mode = self.engine.mode
        every = min(s.frame_every for s in specs)
        # a launch of `room` steps from a frame step takes exactly frame_capacity frames
        # (engine.can_step): a power of two, so that a dense trajectory's chunks (at most
        # FRAME_CAPACITY[1] rows, store.layout.frame_chunk_rows) end where launches end and
        # the sink's commits find no rows outside whole chunks to journal
        room = self.engine.F.frame_capacity * every
        if mode == "fused":
            steps = max(10_000, int(LAUNCH_SECONDS / min(s.dt for s in specs)))
            # and at most ≈ LAUNCH_WALL_SECONDS of CPU: Ctrl-C and SIGTERM are seen between
            # launches, and a launch of one simulated second of 7200 beads took minutes
            steps = min(steps, max(1000, int(LAUNCH_WALL_SECONDS / step_cost(specs))))
            self.steps_per_launch = max(1, min(steps, room))
        else:  # a launch also ends at a full frame buffer (Engine: a byte budget, ≥ 1 frame)
            self.steps_per_launch = 1000
        for b, spec in enumerate(specs):
            write_mill(self.engine.F, b, spec)
        if plan.needed:
            self._compile()
        self.setup_seconds = time.perf_counter() - t0
        if plan.needed:
            _record_compile(plan, self.setup_seconds, time.process_time() - cpu0)

    def _compile(self):
        """Compile the launch and drain kernels now, by calling them with nothing to do
        (no steps, no rows), so that a run's first launch is simulation only. In
        parallel mode the step is called to stop at step 0 (so it does nothing); the
        list build compiles at the first step, whose time the run's speed then includes."""
        F, e = self.engine.F, self.engine
        if e.mode == "fused":
            advance_fused(F, 0, e.margin, e.use_grid)
        else:
            step_flags(F, e.margin, 0)
            step_parallel(F, e.margin, 0, e.steps_per_kernel, False)
            step_parallel(F, e.margin, 0, 1, True)
        nb = int(F.model.n_balls[0])
        export_events(F, 0, 0, np.zeros((1, S.NCOL)))
        export_frames(F, 0, 0, nb, *e._frame_arrays(0, 1, nb))
        e._spare.clear()  # the drain's own arrays, sized for its frames
        e.spectra()  # the copies a drain to a sink with spectra makes (reads only)

    def done(self) -> bool:
        F = self.engine.F
        return all(int(F.state.step[b]) >= int(F.model.target[b]) or int(F.state.status[b]) != S.OK for b in range(self.engine.B))

    def time(self, b: int) -> float:
        return int(self.engine.F.state.step[b]) * self.specs[b].dt

    def launch(self, sinks) -> list[str | None]:
        """One launch and drain; returns per mill None or the fault message."""
        self.engine.advance(self.steps_per_launch)
        return self.drain(sinks)

    def drain(self, sinks) -> list[str | None]:
        """Stream what the launches since the last drain buffered; per mill None or the
        fault message. (The live mill drains every few launches: a drain costs ≈ 1 ms.)"""
        faults = []
        spectra = self.spectra() if any(hasattr(sink, "spectra") for sink in sinks) else None
        for b, sink in enumerate(sinks):
            frames, raw, ledger = self.engine.drain(b)
            if len(raw):
                sink.events(events_table(raw))
            if spectra is not None and hasattr(sink, "spectra"):
                sink.spectra(spectra[b])
            if len(frames["time"]):
                sink.frames(frames)
                sink.energy({"time": frames["time"], **{k: ledger[:, c] for c, k in enumerate(S.LEDGER_FIELDS)}})
            code = int(self.engine.F.state.status[b])
            faults.append(None if code == S.OK else status_message(code, int(self.engine.F.state.bad_ball[b]), self.time(b), self.specs[b].dt,
                                                                     self.engine.F.pool_capacity))
        return faults

    def spectra(self) -> list[Spectra]:
        """Each mill's energy spectra of the events closed so far, over its window
        (spectra_from … now)."""
        count, fixed = self.engine.spectra()
        return [Spectra(s.spectra_from, max(s.spectra_from, self.time(b)), s.stress_min_un, count[b], fixed[b])
                for b, s in enumerate(self.specs)]

    def run(self, sinks, progress=None):
        """Run every mill to its target; raises SimulationUnstable for the first fault
        after every sink has received what was computed up to it."""
        while not self.done():
            faults = self.launch(sinks)
            if progress:
                progress(min(self.time(b) for b in range(self.engine.B)))
            bad = [f for f in faults if f]
            if bad:
                raise SimulationUnstable(bad[0])

    def final_state(self, b: int):
        n = self.specs[b].n
        return {k: self.engine.ball_rows(b, k)[:n] for k in ("x", "v", "s")}
