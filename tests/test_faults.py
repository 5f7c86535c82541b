"""Faults a hostile user causes, through the real CLI (docs/outputs.md, crash safety):
kill -9 at random times (the store keeps every committed launch, never reads as
complete), SIGTERM (handled like Ctrl-C), a killed sweep (no process left behind,
resumes bit-identical), a full disk, two writers of one output, --overwrite that must
not destroy a good output, and damaged stores through analyse, report and record.

Subprocesses pay Taichi's start-up (a few seconds each): the CI selection kills 3 runs,
`pytest -m full` all 20."""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zarr

from helpers import tmpfs
from inprocess import main
from taimill.analysis.run import analyse
from taimill.errors import StoreError
from taimill.store.output import OutputLock, lock_path
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink
from taimill.store.sweep import open_sweep

ROOT = Path(__file__).resolve().parent.parent
PRESET = "presets/p4-cy-steel.toml"
DURATION = 24.0  # s simulated: a run the kills (≤ 1.5 s after its first commit) fall into even at 6-10× real time (8 s ended first at 5×)
LAUNCH = 1.0  # s simulated per launch (physics.runner.LAUNCH_SECONDS): at most this much is lost
SWEEP = ("sweep", PRESET, "--ratio", "-2,-2.5,-3", "--duration", 0.3, "--workers", 2, "--batch", 1, "--json")
TIMING = {"wall_seconds", "realtime_factor", "batch"}


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run(command(*args), cwd=ROOT, capture_output=True, text=True, timeout=timeout)


def start(*args) -> subprocess.Popen:
    return subprocess.Popen(command(*args), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for(condition, timeout=120.0, what="condition"):
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def one_line(stderr: str) -> str:
    """The fault's one line; the preset's warnings and the compile notice said before
    the run started aside."""
    lines = [ln for ln in stderr.splitlines()
             if ln.strip() and not ln.startswith(("[Taichi]", "taimill: warning: ", "taimill: compiling"))]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def committing(path: Path):
    """True once a run writing `path` has committed its first launch."""
    return lambda: (path / "journal").is_dir() or (path / "trajectory" / "time" / "c").is_dir()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted run: what every killed run's rows must be a prefix of."""
    out = tmp_path_factory.mktemp("ref") / "ref.zarr"
    res = taimill("run", PRESET, "--duration", DURATION, "--out", out, "--json")
    assert res.returncode == 0, res.stderr
    return out


def assert_prefix(store, ref):
    """Every table of `store` starts with the rows of the reference's, or is its first
    rows, bit for bit (a seeded run repeats itself)."""
    for table in ("frames", "events", "energy"):
        got, want = getattr(store, table), getattr(ref, table)
        for col in want:
            n = min(len(got[col]), len(want[col]))
            np.testing.assert_array_equal(got[col][:n], want[col][:n], err_msg=f"{table}/{col}")


def assert_killed_store(path: Path, ref):
    store = open_run(path)
    assert store.status == "running" and store.summary is None  # never "complete"
    assert len(store.frames["time"]) <= len(ref.frames["time"])
    assert_prefix(store, ref)
    t = store.frames["time"]
    assert len(t) > 0
    # committed together per launch: events up to the last committed frame are there
    ends = ref.events["t_start"] + ref.events["duration"]
    assert len(store.events["t_start"]) >= np.count_nonzero(ends <= t[-1] - LAUNCH - 0.05)
    assert abs(len(store.energy["time"]) - len(t)) <= 30  # ledger rows follow the frames within a launch
    q = analyse(path).quantities()
    assert q["status"].startswith("incomplete") and q["analysis_window"][1] == t[-1]
    return store


def kill_run(tmp_path: Path, seed: int) -> Path:
    """Start a run, SIGKILL it a seeded random time after its first commit."""
    out = tmp_path / f"killed{seed}.zarr"
    proc = start("run", PRESET, "--duration", DURATION, "--out", out, "--json")
    try:
        wait_for(committing(out), what="the first commit")
        time.sleep(random.Random(seed).uniform(0.0, 1.5))
        assert proc.poll() is None, "the run ended before it was killed"
    finally:
        proc.kill()
        proc.communicate()
    assert proc.returncode == -signal.SIGKILL
    return out


@pytest.mark.parametrize("seed", range(3))
def test_kill_9_keeps_every_committed_launch(reference, tmp_path, seed):
    out = kill_run(tmp_path, seed)
    assert_killed_store(out, open_run(reference))
    assert lock_path(out).exists()  # a stale lock: the next writer takes it
    if seed == 0:
        code, text, _ = main("analyse", out)
        assert code == 0 and text.startswith("status: incomplete")
        # the stale lock is taken over, the killed store replaced by a complete one
        res = taimill("run", PRESET, "--duration", 0.05, "--out", out, "--overwrite", "--json")
        assert res.returncode == 0, res.stderr
        assert open_run(out).status == "complete"
        assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no lock, no partial left


@pytest.mark.full
@pytest.mark.parametrize("seed", range(20))
def test_kill_9_twenty_times(reference, tmp_path, seed):
    assert_killed_store(kill_run(tmp_path, 100 + seed), open_run(reference))


def test_a_second_writer_is_refused_and_sigterm_is_handled_like_ctrl_c(reference, tmp_path):
    out = tmp_path / "term.zarr"
    first = start("run", PRESET, "--duration", DURATION, "--out", out, "--json")
    wait_for(committing(out), what="the first commit")
    second = taimill("run", PRESET, "--duration", 0.1, "--out", out, "--overwrite", "--json")
    line = one_line(second.stderr)
    assert second.returncode == 2 and f"{out}: in use: pid {first.pid} on " in line
    assert f"(taimill run presets/p4-cy-steel.toml --duration {DURATION} --out {out} --json)" in line
    first.send_signal(signal.SIGTERM)
    _, err = first.communicate(timeout=120)
    assert first.returncode == 143, err
    assert one_line(err) == f"taimill: terminated (SIGTERM); the run so far is in {out}"
    store = open_run(out)  # checked: the tables hold every event the summary counts
    assert store.status == "interrupted" and store.summary["events_total"] == len(store.events["t_start"])
    assert store.summary["sim_seconds"] < DURATION and not (out / "journal").exists()
    assert_prefix(store, open_run(reference))
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no lock, no partial left


def test_ctrl_c_between_frames_stops_at_the_next_launch(tmp_path):
    """Launches that take no frame hand the sinks events only; the hold that keeps a
    launch whole once ended with the frames' ledger rows, so such launches kept it from
    one to the next and Ctrl-C waited for the next frame (18 s at 10⁵ balls). Frames
    every 100 s here: the interrupted run must stop within launches of the signal."""
    preset = tmp_path / "sparse.toml"
    preset.write_text((ROOT / PRESET).read_text().replace("trajectory_rate = 100", "trajectory_rate = 0.01")
                      .replace("duration = 24.0", "duration = 200.0"))
    out = tmp_path / "sparse.zarr"
    proc = start("run", preset, "--out", out, "--json")
    wait_for(committing(out), what="the first commit (the frame at t = 0)")
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and one_line(err) == f"taimill: interrupted; the run so far is in {out}"
    store = open_run(out)
    assert store.status == "interrupted" and store.summary["events_total"] == len(store.events["t_start"])
    assert store.summary["sim_seconds"] < 50, store.summary["sim_seconds"]  # the next frame is at 100 s


@pytest.mark.parametrize("events", ["rows", "spectra"])
def test_ctrl_c_before_the_first_frame_leaves_no_store(tmp_path, events):
    """Ctrl-C while the kernels compile (an empty kernel cache: seconds) stops the run
    before its first frame: a store with nothing to read would only block the retry. In
    both event modes (statistics mode is the default above 10⁴ balls)."""
    out = tmp_path / "early.zarr"
    preset = tmp_path / "p.toml"
    preset.write_text((ROOT / PRESET).read_text().replace("trajectory_rate = 100", f'trajectory_rate = 100\nevents = "{events}"'))
    env = os.environ | {"TI_OFFLINE_CACHE_FILE_PATH": str(tmp_path / "cache"), "HOME": str(tmp_path)}
    proc = subprocess.Popen(command("run", preset, "--duration", 2, "--out", out, "--json"), cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    said = []
    for line in proc.stderr:
        said.append(line)
        if line.startswith("taimill: compiling kernels"):
            assert "first run" in line, line
            break
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    err = "".join(said) + err
    assert proc.returncode == 130, err
    assert one_line(err) == f"taimill: interrupted; nothing was written to {out}"
    assert not out.exists() and not lock_path(out).exists()
    retry = taimill("run", preset, "--duration", 0.05, "--out", out, "--json")
    assert retry.returncode == 0, retry.stderr


def test_a_store_stopped_while_its_tables_were_being_made_is_not_kept(tmp_path):
    """holds_a_frame reads the files. The store's start writes its config, then makes its
    tables (seconds for 10⁵ balls); Ctrl-C between the two left a finished store without
    tables, which the reader calls damaged, so it was kept, unreadable (bench.py section
    9: 'trajectory/time: missing' 1 s into a 10⁵-ball run)."""
    from test_store import N_BALLS, energy_block, event_block, frame_block

    from taimill.store.run import holds_a_frame

    early, later = tmp_path / "early.zarr", tmp_path / "later.zarr"
    sink = ZarrSink(early)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    shutil.rmtree(early / "trajectory")  # as if stopped before this table was made
    sink.finish({"sim_seconds": 0.0}, "interrupted")
    with pytest.raises(StoreError, match="trajectory"):
        open_run(early)
    assert not holds_a_frame(early)
    sink = ZarrSink(later)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    frames = frame_block(np.random.default_rng(0), 3)
    sink.events(event_block(np.random.default_rng(1), 5))
    sink.frames(frames)
    sink.energy({**energy_block(np.random.default_rng(2), 3), "time": frames["time"]})
    assert holds_a_frame(later)  # a journal commit
    sink.finish({"sim_seconds": 0.0}, "interrupted")
    assert holds_a_frame(later) and not holds_a_frame(tmp_path / "none.zarr")


def test_an_interrupt_swallowed_on_its_way_out_is_raised_again():
    """Taichi's kernel decorator runs a source lookup under a bare `except:` at every
    import of a module with kernels: a Ctrl-C landing there vanished and a sweep
    interrupted 1 s in ran to its end. signals.check() raises it again."""
    from taimill.runs import signals

    with signals.sigterm_interrupts():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)  # the handler runs here
        except:  # noqa: E722 - what Taichi does
            pass
        with pytest.raises(KeyboardInterrupt):
            signals.check()
    signals.check()  # the block is over: nothing left to raise


def test_an_interrupt_between_a_coroutine_and_its_loop_prints_one_line():
    """zarr's sync calls make a coroutine and then hand it to zarr's event-loop thread:
    a SIGTERM landing between the two left the coroutine unawaited, and Python's
    warning about it ("coroutine ... was never awaited") followed the fault's one line
    at exit (`import liggghts`, one CI run in many)."""
    script = (
        "import asyncio, os, signal, time\n"
        "from taimill.runs import signals\n"
        "async def create_array(): pass\n"
        "left = []\n"
        "try:\n"
        "    with signals.sigterm_interrupts():\n"
        "        left.append(create_array())  # made, never handed to the loop\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        time.sleep(5)\n"
        "except KeyboardInterrupt as err:\n"
        "    print(f'taimill: {err}', file=__import__('sys').stderr)\n"
        "    raise SystemExit(err.exit_code)\n"
    )
    res = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=60,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert res.returncode == 143, res.stderr
    assert res.stderr.strip().splitlines() == ["taimill: terminated (SIGTERM)"], res.stderr


def test_overwrite_keeps_the_old_store_until_the_new_one_is_complete(reference, tmp_path):
    out = tmp_path / "run.zarr"
    shutil.copytree(reference, out)
    proc = start("run", PRESET, "--duration", DURATION, "--seed", 9, "--out", out, "--overwrite", "--json")
    partial = tmp_path / f"run.partial-{proc.pid}.zarr"
    wait_for(committing(partial), what="the partial store")
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    assert one_line(err) == f"taimill: interrupted; {out} is unchanged; the partial run is in {partial}"
    assert open_run(partial).status == "interrupted"
    ref, old = open_run(reference), open_run(out)
    assert old.status == "complete" and old.summary == ref.summary
    np.testing.assert_array_equal(old.events["se_n"], ref.events["se_n"])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, partial.name])


# ---------------------------------------------------------------- locks in-process
LOCK_HOLDER = """
import sys, time
from taimill.store.output import OutputLock
OutputLock(sys.argv[1]).acquire()
print("locked", flush=True)
time.sleep(600)
"""


def test_a_lock_names_its_holder_and_a_dead_holder_releases_it(tmp_path):
    target = tmp_path / "x.zarr"
    holder = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(target)], stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(StoreError, match=rf"x.zarr: in use: pid {holder.pid} on .* since .* \(python -c "):
            OutputLock(target).acquire()
    finally:
        holder.kill()
        holder.wait()
    with OutputLock(target):  # the kernel released the dead holder's lock: no stale lock
        assert json.loads(lock_path(target).read_text())["pid"] == os.getpid()
    assert not lock_path(target).exists()


@pytest.mark.parametrize("atomic", [True, False], ids=["renameat2", "two renames"])
def test_a_finished_output_replaces_the_old_one(tmp_path, monkeypatch, atomic):
    from taimill.store import output

    if not atomic:
        monkeypatch.setattr(output, "_exchange", lambda a, b: False)
    for name, make in (("run.zarr", lambda p, text: (p.mkdir(), (p / "zarr.json").write_text(text))),
                       ("run.rrd", lambda p, text: p.write_text(text))):
        target = tmp_path / name
        make(target, "old")
        with output.Output(target, overwrite=True, ours=lambda p: True) as out:
            assert out.build == tmp_path / name.replace(".", f".partial-{os.getpid()}.")
            make(out.build, "new")
            assert (target / "zarr.json" if target.is_dir() else target).read_text() == "old"
            out.commit()
        assert (target / "zarr.json" if target.is_dir() else target).read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.rrd", "run.zarr"]


# ---------------------------------------------------------------- sweeps
def _proc_children(pid: int) -> set[int]:
    """Every living descendant of `pid`, from /proc."""
    parents = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2:].split()
            if fields[0] != "Z":
                parents[int(d.name)] = int(fields[1])
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        kids = {c for c, pp in parents.items() if pp == p}
        todo += kids - out
        out |= kids
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def _same_sweep(a: Path, b: Path):
    ta, tb = open_sweep(a).table(), open_sweep(b).table()
    assert set(ta) == set(tb)
    for col in set(ta) - TIMING:
        assert list(ta[col]) == list(tb[col]) or np.array_equal(ta[col], tb[col], equal_nan=True), col
    for i in ta["point"]:
        pa, pb = open_sweep(a).point(int(i)), open_sweep(b).point(int(i))
        for col in pb.events:
            np.testing.assert_array_equal(pa.events[col], pb.events[col], err_msg=col)
        np.testing.assert_array_equal(pa.frames["position"], pb.frames["position"])


@pytest.fixture(scope="module")
def whole_sweep(tmp_path_factory):
    """An uninterrupted sweep; a second identical sweep started meanwhile is refused."""
    out = tmp_path_factory.mktemp("sweep") / "whole.zarr"
    first = start(*SWEEP, "--out", out)
    wait_for(lambda: lock_path(out).exists() and lock_path(out).stat().st_size > 0, what="the sweep's lock")
    second = taimill(*SWEEP, "--out", out)
    _, err = first.communicate(timeout=600)
    assert first.returncode == 0, err
    return out, second


def test_a_second_identical_sweep_is_refused(whole_sweep):
    out, second = whole_sweep
    assert second.returncode == 2 and f"{out}: in use: pid " in one_line(second.stderr)
    assert len(open_sweep(out).table()["point"]) == 3


def test_killed_sweep_leaves_no_process_and_resumes_bit_identical(whole_sweep, tmp_path):
    out = tmp_path / "killed.zarr"
    proc = start(*SWEEP, "--out", out)
    kids: set[int] = set()

    def workers_started():
        kids.update(_proc_children(proc.pid))
        return len(kids) >= 3 and (out / "points").is_dir()  # two workers and the resource tracker

    wait_for(workers_started, what="the sweep's workers")
    time.sleep(2.0)
    kids.update(_proc_children(proc.pid))
    proc.kill()
    proc.communicate()
    assert proc.returncode == -signal.SIGKILL
    wait_for(lambda: not any(map(_alive, kids)), timeout=30, what=f"the workers {sorted(kids)} to die")
    res = taimill(*SWEEP, "--out", out)  # the same command resumes
    assert res.returncode == 0, res.stderr
    _same_sweep(out, whole_sweep[0])


def test_overwrite_with_an_unreachable_scheduler_keeps_the_sweep(whole_sweep, tmp_path):
    out = tmp_path / "keep.zarr"
    shutil.copytree(whole_sweep[0], out)
    res = taimill("sweep", PRESET, "--ratio", "-1", "--duration", 0.1, "--scheduler", "tcp://127.0.0.1:9",
                  "--out", out, "--overwrite", "--json")
    assert res.returncode == 2 and "--scheduler" in one_line(res.stderr)
    _same_sweep(out, whole_sweep[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.zarr"]  # no partial, no lock


# ---------------------------------------------------------------- full disk
@pytest.fixture
def small_disk(tmp_path):
    with tmpfs(tmp_path / "disk", "size=2m") as mnt:
        yield mnt


def test_a_full_disk_gives_one_line_and_a_readable_partial_store(reference, small_disk):
    out = small_disk / "run.zarr"
    res = taimill("run", PRESET, "--duration", 30, "--out", out, "--json")
    line = one_line(res.stderr)
    assert res.returncode == 5, res.stderr
    assert line.startswith(f"taimill: error: {out}: ") and "No space left on device" in line
    store = open_run(out)
    assert store.status == "running" or (store.status.startswith("failed: ") and "No space left" in store.status)
    assert len(store.frames["time"]) > 0
    assert_prefix(store, open_run(reference))


# ---------------------------------------------------------------- damaged stores
def _garbage_attr(path: Path, node: str, **attrs):
    meta = path / node / "zarr.json"
    doc = json.loads(meta.read_text())
    doc["attributes"].update(attrs)
    meta.write_text(json.dumps(doc))


DAMAGE = {
    "deleted chunk": (lambda p: (p / "events" / "un" / "c" / "0").unlink(), "events/un: chunk 0 missing"),
    "truncated chunk": (lambda p: (p / "trajectory" / "position" / "c" / "0" / "0" / "0").write_bytes(b"\x28\xb5"),
                        "trajectory/position: chunk 0 fails its checksum"),  # a truncated chunk fails the CRC before Blosc
    "garbage zarr.json": (lambda p: (p / "energy" / "kinetic" / "zarr.json").write_text("{not json"),
                          "energy/kinetic: metadata unreadable"),
    "garbage root zarr.json": (lambda p: (p / "zarr.json").write_text("\x00garbage"), "zarr.json: not a taimill run store"),
    "deleted table": (lambda p: shutil.rmtree(p / "events"), "events: missing"),
    "deleted array": (lambda p: shutil.rmtree(p / "energy" / "dissipated"), "energy/dissipated: missing"),
    "garbage n_valid": (lambda p: _garbage_attr(p, "events", n_valid="many"), "events/n_valid: 'many' is not a row count"),
    "lowered n_valid": (lambda p: _garbage_attr(p, "events", n_valid=0), "events: 0 committed rows, but the summary counts"),
    "garbage status": (lambda p: _garbage_attr(p, ".", status=["complete"]), "attrs.status: ['complete'] is not a str"),
    "garbage config": (lambda p: _garbage_attr(p, ".", config={"jar": 1}), "attrs.config: not the config of a taimill run"),
}


@pytest.mark.parametrize("name", sorted(DAMAGE))
def test_a_damaged_store_is_named_never_complete(reference, tmp_path, name):
    damage, words = DAMAGE[name]
    path = tmp_path / "run.zarr"
    shutil.copytree(reference, path)
    damage(path)
    for args in (["analyse", path], ["report", path, "--out", tmp_path / "fig"],
                 ["record", path, "--rrd", tmp_path / "x.rrd"]):
        code, _, err = main(*args)
        line = one_line(err)
        assert code == 2, (args, err)
        assert line.startswith(f"taimill: error: {path}") and words in line, line
        assert not (tmp_path / "x.rrd").exists()
    with pytest.raises(StoreError, match=re.escape(words)):
        analyse(path)


def test_a_damaged_journal_of_a_killed_run_is_named(tmp_path):
    # a writer that committed twice and never finished (killed): its rows are in the journal
    from test_store import N_BALLS, energy_block, event_block, frame_block

    path = tmp_path / "run.zarr"
    sink = ZarrSink(path)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    rng = np.random.default_rng(0)
    for t in (0.0, 1.0):
        frames = frame_block(rng, 3)
        frames["time"] = t + np.arange(3) * 0.1
        sink.events(event_block(rng, 5))
        sink.frames(frames)
        sink.energy({**energy_block(rng, 3), "time": frames["time"]})
    segments = sorted((path / "journal").glob("*.npz"))
    assert len(segments) == 2
    store = open_run(path)
    assert store.status == "running" and store.rows == {"trajectory": 6, "events": 10, "energy": 6}
    np.testing.assert_array_equal(store.frames["time"], [0.0, 0.1, 0.2, 1.0, 1.1, 1.2])
    segments[0].write_bytes(segments[0].read_bytes()[:100])
    with pytest.raises(StoreError, match="run.zarr: journal/00000001.npz: unreadable"):
        open_run(path)


def test_a_damaged_sweep_table_is_named(whole_sweep, tmp_path):
    path = tmp_path / "sweep.zarr"
    shutil.copytree(whole_sweep[0], path)
    (path / "table" / "mean_se" / "c" / "0").write_bytes(b"junk")
    code, _, err = main("report", path, "--out", tmp_path / "fig")
    assert code == 2 and "table/mean_se: chunk 0 fails its checksum" in one_line(err)
    shutil.rmtree(path / "points" / "p00001")
    with pytest.raises(StoreError, match="points/p00001: missing"):
        open_sweep(path).point(1)
    assert zarr.open_group(path, mode="r").attrs["kind"] == "sweep"


def test_an_interrupt_waits_until_the_launch_reached_every_sink():
    # SIGTERM arriving while the summary took a launch's events but the store had not
    # yet: the store then held fewer events than its summary counted and read as
    # damaged (seen once in the SIGTERM test above). The launch now reaches both, and
    # the interrupt is raised once its drain is over (launch_done), between launches.
    from taimill.errors import Interrupted
    from taimill.runs.signals import sigterm_interrupts
    from taimill.runs.simulation import WholeLaunches
    from taimill.store.sinks import FanOut, MemorySink

    class SignalledOnEvents(MemorySink):
        def events(self, block):
            super().events(block)
            os.kill(os.getpid(), signal.SIGTERM)  # handled at the next bytecode, here

    first, second = SignalledOnEvents(), MemorySink()
    out = WholeLaunches(FanOut(first, second))
    block = {"t": np.zeros(3)}
    raised = []  # Interrupted is a KeyboardInterrupt: caught here, not left to end pytest
    with sigterm_interrupts():
        for name in ("events", "frames", "energy", "launch_done"):
            try:
                getattr(out, name)(*([block] if name != "launch_done" else []))
            except Interrupted:
                raised.append(name)
    assert raised == ["launch_done"]
    for sink in (first, second):
        assert [len(b) for b in (sink._events, sink._frames, sink._energy)] == [1, 1, 1]


@pytest.mark.full
@pytest.mark.parametrize("seed", range(3))
def test_kill_9_of_a_dense_trajectory_reads_whole_frames(tmp_path, seed):
    # At 10⁵ frames/s every launch lands a chunk of frames, then one of ledger rows,
    # each table committing on its own, and the journal holds only events. A killed
    # dense run reads as whole frames, each with its ledger row. (A kill between the
    # two chunks, a few ms of a 0.1 s launch, is rarely hit here: test_store.py's
    # abandoned writer is that case, deterministically.)
    preset = tmp_path / "dense.toml"
    preset.write_text((ROOT / PRESET).read_text().replace("trajectory_rate = 100\n", "trajectory_rate = 100000\n"))
    out = tmp_path / "dense.zarr"
    proc = start("run", preset, "--duration", DURATION, "--out", out, "--json")
    try:
        wait_for(lambda: (out / "trajectory" / "time" / "c").is_dir(), what="the first chunk")
        time.sleep(random.Random(seed).uniform(0.0, 3.0))
        assert proc.poll() is None, "the run ended before it was killed"
    finally:
        proc.kill()
        proc.communicate()
    store = open_run(out)
    assert store.status == "running" and store.summary is None
    t = store.frames["time"]
    assert len(t) >= 32768 and len(store.energy["time"]) == len(t) == len(store.frames["position"])
    np.testing.assert_array_equal(store.energy["time"], t)
    assert (np.diff(t) > 0).all()
    q = analyse(out).quantities()
    assert q["status"].startswith("incomplete") and q["analysis_window"][1] == t[-1]
