"""Running chunks of sweep points: each chunk of B points is ONE `Runner(specs)` (B mills
in one fused kernel) on a worker process, and the results travel back to the process
that writes the sweep store (so workers need no shared file system).

Backends:
- local: `ProcessPoolExecutor` with the **spawn** start method (fork after `ti.init`
  hangs); every worker calls `init_taichi(threads=1)` once (on the parent's
  backend: the workers inherit TAIMILL_BACKEND) and keeps its
  engine between chunks (simulation._engines); progress comes back over a queue after
  every kernel launch, with the worker's pid (so the parent knows which chunk runs
  where). Workers die with the parent, even a parent killed with SIGKILL
  (taimill.runs.signals.die_with_parent), and ignore Ctrl-C: the parent stops them
  when it is interrupted or its consumer stops (no chunk runs on unseen). A worker
  that dies (killed: out of memory, SIGKILL) breaks the pool: the chunks that finished
  are still handed over, then `PoolBroken` names the dead worker and the chunks that
  were running.
- dask: `distributed.Client(address).submit` per chunk; a dask worker process starts
  Taichi lazily on its first chunk and reuses it. Workers must run one thread each
  (`dask worker ADDRESS --nthreads 1`; `processes=False` or several threads break
  Taichi). Progress advances per finished chunk.
"""

from __future__ import annotations

import multiprocessing
import os
import queue as queue_mod
import signal
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field

import numpy as np

from taimill.runs import signals
from taimill.store.sinks import MemorySink, NullSink


@dataclass(frozen=True)
class Job:
    """One sweep point to simulate: its index in the sweep plan and its resolved preset."""

    index: int
    preset: object  #: taimill.model.preset.Preset


@dataclass
class PointResult:
    """What a worker sends back for one point: the run's summary (docs/outputs.md), its status,
    and (when a store is written) the whole stream, concatenated per table."""

    index: int
    summary: dict
    status: str
    config: dict
    n_balls: int
    radii: np.ndarray
    tables: dict | None  #: {"frames": …, "events": …, "energy": …} (MemorySink tables)
    spectra: object = None  #: the point's energy spectra (taimill.model.spectra.Spectra)


@dataclass
class PoolBroken(Exception):
    """A worker process died and took the pool with it. `dead`: (pid, how it ended,
    e.g. "killed by SIGKILL") of each worker that died by itself; `lost`: the indices
    of the points of each chunk that was running, by the pid of its worker (0: unknown)."""

    dead: list = field(default_factory=list)
    lost: dict = field(default_factory=dict)


def chunk_seconds(jobs: list[Job]) -> float:
    """Simulated mill-seconds in a chunk (the progress unit)."""
    return float(sum(j.preset.duration for j in jobs))


# ---------------------------------------------------------------- worker side
_progress = None  # the local backend's queue, set in each worker process


def _init_local_worker(progress_queue, parent: int, workers: int = 1):
    from taimill.physics.ti import init_taichi
    from taimill.runs.signals import die_with_parent

    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent is interrupted and stops the workers
    global _progress
    _progress = progress_queue
    # in the worker's main thread, where its kernels run; on the backend the parent was
    # told (TAIMILL_BACKEND, which the command line sets), a CUDA device shared by all
    init_taichi(threads=1, share=workers)


def _check_dask_worker():
    """Taichi needs one thread per process: refuse multi-threaded dask workers."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return
    nthreads = worker.state.nthreads
    if nthreads > 1:
        raise RuntimeError(f"dask worker {worker.address} runs {nthreads} threads; taimill needs one thread "
                           "per worker process (start workers with --nthreads 1, LocalCluster(threads_per_worker=1))")


def run_chunk(chunk_id: int, jobs: list[Job], keep_streams: bool) -> list[PointResult]:
    """Simulate the chunk's points as one batch of mills; a point that goes unstable
    keeps what it computed (status "unstable: …") and the others run on. Each point's
    wall_seconds is the batch's wall time, set-up and compiling left out, shared in
    proportion to its ball-steps (the mills of a batch advance one after another on the
    worker's one thread)."""
    from taimill.model.spec import from_preset
    from taimill.physics.runner import Runner
    from taimill.physics.ti import init_taichi
    from taimill.runs.simulation import point_result
    from taimill.runs.simulation import start_point

    _check_dask_worker()
    if _progress is not None:
        _progress.put((chunk_id, 0.0, os.getpid()))  # the parent learns where the chunk runs
    init_taichi(threads=1)
    specs = [from_preset(j.preset) for j in jobs]
    mems = [MemorySink() if keep_streams else NullSink() for _ in jobs]
    started = [start_point(j.preset, s, m) for j, s, m in zip(jobs, specs, mems)]
    outs = [out for _, out in started]
    status = ["complete"] * len(jobs)
    runner = Runner(specs)
    t0 = time.perf_counter()  # the speed leaves set-up and compiling out (Runner.setup_seconds)
    while not runner.done():
        for b, fault in enumerate(runner.launch(outs)):
            if fault and status[b] == "complete":
                status[b] = f"unstable: {fault}"
        if _progress is not None:
            done = sum(min(runner.time(b), s.steps * s.dt) for b, s in enumerate(specs))
            _progress.put((chunk_id, done, os.getpid()))
    wall = time.perf_counter() - t0
    work = np.array([int(runner.engine.F.state.step[b]) * s.n for b, s in enumerate(specs)], dtype=float)
    share = work / work.sum() if work.sum() > 0 else np.full(len(jobs), 1.0 / len(jobs))
    results = []
    spectra = runner.spectra()
    for b, (job, spec, mem, (summary, out)) in enumerate(zip(jobs, specs, mems, started)):
        result = point_result(job.preset, spec, summary, runner, b, wall * share[b], status[b])
        result["batch"] = len(jobs)
        out.finish(result, status[b])
        tables = None
        if keep_streams:
            tables = {"frames": mem.frame_table, "events": mem.event_table, "energy": mem.energy_table}
        results.append(PointResult(job.index, result, status[b], mem.config if keep_streams else {}, spec.n,
                                   np.asarray(spec.radius), tables, spectra[b]))
    return results


# ---------------------------------------------------------------- parent side
def run_local(chunks: list[list[Job]], workers: int, keep_streams: bool, on_progress):
    """Yield each chunk's results as it finishes, from `workers` spawned processes.
    on_progress(chunk_id, simulated seconds done in that chunk) after every launch."""
    ctx = multiprocessing.get_context("spawn")
    progress_queue = ctx.Queue()
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_local_worker,
                               initargs=(progress_queue, os.getpid(), workers))
    running: dict[int, int | None] = {}  # chunk id -> pid of the worker running it (None: finished)
    try:
        futures = {pool.submit(run_chunk, cid, chunk, keep_streams): cid for cid, chunk in enumerate(chunks)}
        pending = set(futures)
        workers_seen: dict = {}  # every worker process ever seen: a broken pool may have dropped the dead one already
        while pending:
            signals.check()  # a Ctrl-C that an import swallowed (runs.signals)
            workers_seen |= dict(getattr(pool, "_processes", None) or {})
            done, pending = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
            workers_seen |= dict(getattr(pool, "_processes", None) or {})
            _drain(progress_queue, on_progress, running)
            broken = [f for f in done if isinstance(f.exception(), BrokenProcessPool)]
            if broken:  # every future left fails at once: take those that finished first
                done |= wait(pending, timeout=10)[0]
            for fut in done:
                if isinstance(fut.exception(), BrokenProcessPool):
                    continue
                results = fut.result()
                running[futures[fut]] = None
                on_progress(futures[fut], chunk_seconds(chunks[futures[fut]]))
                yield results
            if broken:
                _drain(progress_queue, on_progress, running)
                raise _broken(workers_seen | dict(getattr(pool, "_processes", None) or {}), running, chunks)
    except BaseException:  # interrupted, or the consumer failed or stopped: stop the chunks under way
        _stop_workers(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's worker processes (the executor has no public call for it
    before Python 3.14's terminate_workers)."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            process.kill()
        except (OSError, ValueError, AttributeError):
            pass


def _broken(processes: dict, running: dict[int, int], chunks) -> PoolBroken:
    """What a broken pool lost: its workers that died by themselves (the pool then
    ends the others with SIGTERM) and the chunks running at the time."""
    dead = []
    deadline = time.monotonic() + 5
    for pid, process in processes.items():
        code = _exit_code(process, deadline)
        if code not in (None, 0, -signal.SIGTERM):
            how = f"killed by {_signal_name(-code)}" if code < 0 else f"exit code {code}"
            how += " (out of memory?)" if code == -signal.SIGKILL else ""  # what the kernel's OOM killer sends
            dead.append((pid, how))
    lost: dict[int, list[int]] = {}
    for cid, pid in running.items():
        if pid is not None:
            lost.setdefault(pid, []).extend(j.index for j in chunks[cid])
    return PoolBroken(dead, lost)


def _exit_code(process, deadline: float) -> int | None:
    """The worker's exit code, waiting until `deadline` for it. The pool's own thread
    reaps its workers at the same time: a wait that loses that race reads no code
    (None) before the winner has stored it, so ask again until it is there."""
    while True:
        process.join(timeout=max(0.0, min(0.1, deadline - time.monotonic())))
        code = process.exitcode
        if code is not None or time.monotonic() >= deadline:
            return code


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _drain(q, on_progress, running=None):
    while True:
        try:
            cid, seconds, pid = q.get_nowait()
        except queue_mod.Empty:
            return
        except (OSError, ValueError, EOFError):  # a worker killed mid-message: what came before counts
            return
        if running is not None and running.get(cid, 0) is not None:  # a late report of a finished chunk
            running[cid] = pid
        on_progress(cid, seconds)


def run_dask(chunks: list[list[Job]], address: str, keep_streams: bool, on_progress):
    """Yield each chunk's results as it finishes on the dask cluster at `address`."""
    from distributed import Client, KilledWorker, as_completed

    from taimill.errors import ConfigError

    try:
        client = Client(address, timeout=10)
    except (OSError, TimeoutError, ValueError) as err:
        raise ConfigError("command line", "--scheduler", address, f"no dask scheduler answered there ({err})") from None
    with client:
        try:
            client.wait_for_workers(1, timeout=30)
        except TimeoutError:
            pass  # reported below
        threads = client.nthreads()
        bad = {w: n for w, n in threads.items() if n > 1}
        if bad or not threads:
            why = (f"its workers run {sorted(set(bad.values()))} threads each; taimill needs one thread per worker process"
                   " (dask worker ADDRESS --nthreads 1)") if bad else "no worker joined it within 30 s"
            raise ConfigError("command line", "--scheduler", address, why)
        futures = {client.submit(run_chunk, cid, chunk, keep_streams, pure=False): cid
                   for cid, chunk in enumerate(chunks)}
        for fut in as_completed(futures):
            cid = futures[fut]
            try:
                results = fut.result()
            except KilledWorker:  # dask retried the chunk on other workers and they died too
                raise PoolBroken([(0, "died (dask KilledWorker)")], {0: [j.index for j in chunks[cid]]}) from None
            on_progress(cid, chunk_seconds(chunks[cid]))
            yield results
