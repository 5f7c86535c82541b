"""Whole runs: every preset is a test (short, with physical checks), faults keep what was written,
results are deterministic, the time step converges."""

import contextlib
import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from taimill.errors import SimulationUnstable
from taimill.model.preset import load_preset
from taimill.physics import ti as door
from taimill.runs.simulation import run
from taimill.store.sinks import FanOut, MemorySink
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink

PRESETS = sorted(Path(__file__).resolve().parent.parent.glob("presets/*.toml"))
# small-media presets (10⁴ beads, dt ≈ 0.1 µs) would take hours for 1.5 s: a short CLI
# run of each is in tests/test_scale.py, the full length under `-m full` here
MEDIA = [p for p in PRESETS if "-beads-" in p.stem]


def physical_checks(preset, sink, summary):
    """Finite state, every ball inside the jar, energy bookkeeping closed within 1 %."""
    f = sink.frame_table
    x = f["position"]
    assert np.isfinite(x).all() and np.isfinite(f["velocity"]).all()
    r = preset.balls.radius
    rho = np.hypot(x[..., 0], x[..., 1])
    slack = 0.05 * r  # overlap allowed at the walls (Hertz: µm at these loads)
    assert (rho <= preset.jar.radius - r + slack).all()
    assert (x[..., 2] >= r - slack).all() and (x[..., 2] <= preset.jar.height - r + slack).all()
    assert summary["status"] == "complete"
    assert summary["energy_balance_error"] < 0.01
    parts = summary["dissipation_by_mechanism"]
    total = sum(p for kind in parts.values() for cls in kind.values() for p in cls.values())
    assert total == pytest.approx(summary["dissipated_power"], rel=0.01)  # rounding only


@pytest.mark.parametrize("path", [p for p in PRESETS if p not in MEDIA], ids=[p.stem for p in PRESETS if p not in MEDIA])
def test_every_preset_runs_short_and_is_physical(path):
    preset = load_preset(path, {"duration": 1.5})
    sink = MemorySink()
    summary = run(preset, sink)
    physical_checks(preset, sink, summary)
    assert summary["events"] > 0


@pytest.mark.full
@pytest.mark.parametrize("path", PRESETS, ids=[p.stem for p in PRESETS])
def test_every_preset_full_length(path):
    preset = load_preset(path)
    sink = MemorySink()
    summary = run(preset, sink)
    physical_checks(preset, sink, summary)


def test_unstable_run_stops_with_a_message_and_keeps_the_store(tmp_path):
    # A time step far beyond the validated range (only reachable in code) must be
    # caught: non-finite state or tunnelling; the store keeps every committed row.
    preset = load_preset("presets/p4-cy-steel.toml", {"duration": 2.0})
    bad = dataclasses.replace(preset, dt=preset.dt * 400)
    out = tmp_path / "bad.zarr"
    with pytest.raises(SimulationUnstable, match="unstable at t = .* s: ball .*time step"):
        run(bad, ZarrSink(out))
    store = open_run(out)
    assert store.status.startswith("unstable")
    assert len(store.frames["time"]) > 0  # what was computed before the fault is there
    assert store.summary["steps"] > 0


def test_same_seed_gives_bit_identical_events_and_different_seed_does_not():
    p = load_preset("presets/p4-cy-steel.toml", {"duration": 1.5})
    tables = []
    for seed in (7, 7, 8):
        sink = MemorySink()
        run(dataclasses.replace(p, seed=seed), sink)
        tables.append(sink.event_table)
    for k in tables[0]:
        np.testing.assert_array_equal(tables[0][k], tables[1][k])
    assert len(tables[0]["t_start"]) != len(tables[2]["t_start"]) or not np.array_equal(
        tables[0]["t_start"], tables[2]["t_start"])


def test_stored_run_equals_the_streamed_one(tmp_path):
    p = load_preset("presets/p4-cy-steel.toml", {"duration": 1.0})
    mem = MemorySink()
    run(p, FanOut(mem, ZarrSink(tmp_path / "r.zarr")))
    store = open_run(tmp_path / "r.zarr")
    for k, v in mem.event_table.items():
        np.testing.assert_array_equal(store.events[k], v)
    np.testing.assert_array_equal(store.frames["position"], mem.frame_table["position"])
    np.testing.assert_array_equal(store.energy["drive_work"], mem.energy_table["drive_work"])
    assert store.config["balls"]["count"] == 12 and store.config["ratio"] == pytest.approx(-2.6)


def _mean_se_at(dt_factor, seeds, duration):
    base = load_preset("presets/p4-cy-steel.toml")
    vals = []
    for seed in seeds:
        p = load_preset("presets/p4-cy-steel.toml", {"seed": seed, "duration": duration, "analysis_start": 2.0,
                                                     "dt": base.dt * dt_factor})
        vals.append(run(p)["mean_se"])
    return float(np.mean(vals))


def test_mean_stress_energy_converges_in_dt_short():
    # CI form of the dt-convergence check: one seed, a 2 s window. Single 2 s windows scatter
    # by ≈ 4 % seed to seed (6 s windows: 2 %), so the bound is 12 % (3σ); the full
    # test below is the sharp one.
    a, b = _mean_se_at(1.0, (1,), 4.0), _mean_se_at(0.5, (1,), 4.0)
    assert abs(a - b) < 0.12 * a


@pytest.mark.full
def test_mean_stress_energy_converges_in_dt():
    # Halving dt changes the mean SE by less than its seed-to-seed scatter.
    # Four seeds × 6 s windows at dt and dt/2: the difference of the means was 0.3-1.4 %
    # for 20-40 steps per contact, standard error 1.1 %; bound 4 % (≈ 3 standard errors).
    a, b = _mean_se_at(1.0, (1, 2, 3, 4), 8.0), _mean_se_at(0.5, (1, 2, 3, 4), 8.0)
    assert abs(a - b) < 0.04 * a


@pytest.mark.parametrize("implementation", [i.name for i in door.IMPLEMENTATIONS])
def test_a_stale_taichi_cache_lock_is_removed_and_a_fresh_one_kept(tmp_path, monkeypatch, implementation):
    """A lock left by a killed process made every later run print Taichi's lock
    warnings on stderr (whose error output is one line, tests/test_bad_input.py).
    taichi-forge's locks are flock(2)s on files that stay: never removed, old or not."""
    import os

    impl = next(i for i in door.IMPLEMENTATIONS if i.name == implementation)
    monkeypatch.setattr(door, "IMPLEMENTATION", impl)
    lock = tmp_path / (impl.stale_lock or "ticache_x64_s91.lock")
    lock.touch()
    t = os.stat(lock).st_mtime
    assert not door.clear_stale_cache_lock(tmp_path, now=t + 1.0) and lock.exists()  # being used: kept
    old = door.clear_stale_cache_lock(tmp_path, now=t + door.STALE_LOCK_SECONDS + 1.0)
    assert (old, lock.exists()) == ((True, False) if impl.stale_lock else (False, True))
    assert not door.clear_stale_cache_lock(tmp_path)  # none left (or not ours to remove): nothing to do


_TINY_TAICHI_PROGRAM = """
from taimill.physics.ti import init_taichi, ti
init_taichi()
x = ti.field(ti.f64, shape=4)
@ti.kernel
def fill():
    for i in x:
        x[i] = i * 0.5
fill()
print(x.to_numpy().sum())
"""


def _tiny_taichi_run(cache_dir, **env):
    import os
    import subprocess
    import sys

    env = {**{k: v for k, v in os.environ.items() if k != "TAIMILL_TI_LOG"},
           "TI_OFFLINE_CACHE_FILE_PATH": str(cache_dir), **env}
    script = cache_dir.parent / f"{cache_dir.name}-tiny.py"  # Taichi reads a kernel's source file
    script.write_text(_TINY_TAICHI_PROGRAM)
    return subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=300)


@contextlib.contextmanager
def _held_cache_lock(cache_dir):
    """The offline cache's lock as another process holds it, in the implementation in
    use's way: taichi's a fresh lock file; taichi-forge's an flock(2) on its lock file
    (which a first run creates). Yields the lock file's name."""
    import fcntl

    if door.IMPLEMENTATION.stale_lock:
        (cache_dir / door.IMPLEMENTATION.stale_lock).touch()
        yield door.IMPLEMENTATION.stale_lock
        return
    assert _tiny_taichi_run(cache_dir).returncode == 0
    lock = next(cache_dir.glob("ticache*.lock"))
    with open(lock, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        yield lock.name


def test_a_held_taichi_cache_lock_leaves_stderr_clean(tmp_path):
    """A lock another process holds (sweep workers starting together, or a run killed
    minutes ago) made Taichi print warnings on stderr, which breaks taimill's one-line
    error messages (CI failed on it): Taichi's warnings are hidden unless
    TAIMILL_TI_LOG=warn asks for them. The cache folder's lock file is where Taichi
    looks for it: with TAIMILL_TI_LOG=warn the warning does appear. On both Taichis."""
    with _held_cache_lock(tmp_path) as lock:
        quiet = _tiny_taichi_run(tmp_path)
        assert quiet.returncode == 0 and quiet.stdout.strip() == "3.0", quiet.stderr
        assert quiet.stderr.strip() == "", quiet.stderr
        loud = _tiny_taichi_run(tmp_path, TAIMILL_TI_LOG="warn")
        assert loud.returncode == 0 and lock in loud.stderr, loud.stderr


def test_init_taichi_removes_an_old_lock_in_the_cache_folder_it_uses(tmp_path):
    """TI_OFFLINE_CACHE_FILE_PATH names the folder holding the lock (not its parent):
    an hour-old lock there is removed and the cache is written again. taichi-forge's
    lock file is kept (an flock, which no dead process holds) and its cache written."""
    import os
    import time

    lock = tmp_path / (door.IMPLEMENTATION.stale_lock or "ticache_x64_s91.lock")
    lock.touch()
    old = time.time() - 3600
    os.utime(lock, (old, old))
    res = _tiny_taichi_run(tmp_path)
    assert res.returncode == 0, res.stderr
    assert list(tmp_path.glob("ticache*.tcb"))  # Taichi could take the lock and write its cache
    assert lock.exists() != bool(door.IMPLEMENTATION.stale_lock)


def test_the_door_passes_taichis_variables_and_settings_through(tmp_path):
    """What taimill sets for Taichi reaches the implementation in use: the cache folder
    (TI_OFFLINE_CACHE_FILE_PATH), the thread count (TI_CPU_MAX_NUM_THREADS, as
    init_taichi(threads) sets it), the cache size, f64 and the compile settings."""
    script = tmp_path / "settings.py"
    script.write_text(
        "import json\nfrom taimill.physics import ti as door\ndoor.init_taichi(threads=1)\n"
        "cfg = door.internal('lang.impl').current_cfg()\nx = door.ti.field(door.ti.f64, shape=2)\n"
        "@door.ti.kernel\ndef fill():\n    for i in x:\n        x[i] = 1.0 / 3.0\nfill()\n"
        "print(json.dumps(dict(name=door.IMPLEMENTATION.name, threads=cfg.cpu_max_num_threads, "
        "cache=cfg.offline_cache_file_path, size=cfg.offline_cache_max_size_of_files, cfg_opt=cfg.cfg_optimization, "
        "fast_math=cfg.fast_math, x=float(x.to_numpy()[0]), **{k: getattr(cfg, k) for k, _ in door.IMPLEMENTATION.init_options "
        "if hasattr(cfg, k)})))\n")
    cache = tmp_path / "cache"
    env = {k: v for k, v in os.environ.items() if k != "TI_CPU_MAX_NUM_THREADS"}
    res = subprocess.run([sys.executable, str(script)], env={**env, "TI_OFFLINE_CACHE_FILE_PATH": str(cache)},
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and res.stderr.strip() == "", res.stderr
    got = json.loads(res.stdout)
    assert got["name"] == door.IMPLEMENTATION.name
    assert (got["threads"], got["cache"], got["size"]) == (1, str(cache), door.OFFLINE_CACHE_BYTES)
    assert (got["cfg_opt"], got["fast_math"], got["x"]) == (door.CFG_OPTIMIZATION, False, 1.0 / 3.0)  # f64: 1/3 exactly
    assert all(got[k] == v for k, v in door.IMPLEMENTATION.init_options if k in got)
    assert list(cache.glob("ticache*.tcb"))


def test_drained_frames_are_reused_only_when_nothing_else_holds_them(tmp_path):
    from taimill.model.spec import from_preset
    from taimill.physics.runner import Runner

    p = dataclasses.replace(load_preset("presets/p4-cy-steel.toml"), trajectory_rate=1e4)
    engine = Runner([from_preset(p, 0.2)]).engine
    engine.advance(20000)
    first, _, _ = engine.drain(0)
    kept, copy = first["spin"][:, 0], first["spin"].copy()  # a sink keeping a view of a block
    del first
    engine.advance(20000)
    second, _, ledger = engine.drain(0)
    assert second["spin"].base is not kept.base  # new arrays: the kept block is intact
    np.testing.assert_array_equal(kept, copy[:, 0])
    base = id(second["spin"].base)
    del second, ledger, kept
    engine.advance(20000)
    third, _, _ = engine.drain(0)
    assert id(third["spin"].base) == base  # nothing held them: reused
    # a stream whose arrays are reused (the zarr sink copies what it keeps) stores what a
    # memory sink, which keeps every block, receives
    q = dataclasses.replace(p, duration=0.6)
    run(q, ZarrSink(tmp_path / "alone.zarr"))
    mem = MemorySink()
    run(q, mem)
    store = open_run(tmp_path / "alone.zarr")
    for k, v in mem.frame_table.items():
        np.testing.assert_array_equal(store.frames[k], v)
    for k, v in mem.energy_table.items():
        np.testing.assert_array_equal(store.energy[k], v)


def test_a_dense_trajectory_commits_whole_chunks_and_journals_no_frames(tmp_path, monkeypatch):
    # At 10⁵ frames/s a launch fills the runner's frame buffer exactly (32768 frames,
    # engine.can_step) and a trajectory chunk is that long (store.layout.FRAME_CHUNK_ROWS):
    # each commit finds the launch's frames and ledger rows in whole chunks, so the
    # journal, written uncompressed, holds only events. (With a frame buffer that ends
    # two frames short, or 65536-row chunks, every launch's frames went to the journal:
    # 0.5 of 2.3 s CPU for 3 s simulated.)
    import taimill.store.writer as store_writer

    segments = []
    put_npz = store_writer.put_npz

    def spy(store, key, arrays):
        segments.append({k: len(v) for k, v in arrays.items() if not k.endswith("/start")})
        put_npz(store, key, arrays)

    monkeypatch.setattr(store_writer, "put_npz", spy)
    p = dataclasses.replace(load_preset("presets/p4-cy-steel.toml"), trajectory_rate=1e5, duration=1.2)
    mem = MemorySink()
    run(p, FanOut(mem, ZarrSink(tmp_path / "dense.zarr")))
    whole = segments[:-1]  # commits after launches of 0.34 s; the last may end inside a chunk
    assert len(whole) >= 2
    for seg in whole:
        assert {k: n for k, n in seg.items() if not k.startswith("events/")} == {k: 0 for k in seg if not k.startswith("events/")}
        assert seg["events/t_start"] > 0
    store = open_run(tmp_path / "dense.zarr")
    assert store.group["trajectory/position"].chunks[0] == 32768
    assert len(store.frames["time"]) > 2 * 32768
    for k in ("time", "position", "spin", "jar_angle"):
        np.testing.assert_array_equal(store.frames[k], mem.frame_table[k])
    np.testing.assert_array_equal(store.energy["kinetic"], mem.energy_table["kinetic"])
