"""ZarrSink / open_run: round trip, buffering, SIGKILL safety, torn appends, bad blocks."""

import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import zarr

from taimill.schema import DRIVE_FIELDS, ENERGY_COLUMNS, EVENT_COLUMNS, FRAME_FIELDS, MECHANISM_COLUMNS, PER_BALL
from taimill.store.layout import SCHEMA_VERSION
from taimill.store.run import open_run, trim_to_valid
from taimill.store.writer import ZarrSink

N_BALLS = 3
REPO = Path(__file__).resolve().parents[1]


def frame_block(rng, f):
    """`f` random frames: position m, velocity m/s, spin rad/s per ball; time s and the
    frame's drive (rad, rad/s) per frame."""
    return {k: rng.normal(size=(f, N_BALLS, 3)) if k in PER_BALL else rng.uniform(size=f) for k in FRAME_FIELDS}


def event_block(rng, n):
    """`n` random events with every column in its declared dtype."""
    return {
        k: rng.integers(-3, 12, size=n).astype(dtype) if dtype.startswith("i") else rng.normal(size=n)
        for k, (dtype, _, _) in EVENT_COLUMNS.items()
    }


def energy_block(rng, n):
    """`n` random energy rows (J; time in s)."""
    return {k: rng.normal(size=n) for k in ENERGY_COLUMNS}


def cat(blocks):
    return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


CONFIG_IN = {"omega": np.float64(31.4), "n": np.int32(3), "jar": Path("jars/a.toml"),
             "ratio": (1, -2), "r": np.array([0.005, 0.006]), "flag": np.bool_(True)}
CONFIG_OUT = {"omega": 31.4, "n": 3, "jar": "jars/a.toml", "ratio": [1, -2],
              "r": [0.005, 0.006], "flag": True}


def write_run(target, rng, **chunks):
    """Write a run in uneven blocks; return what was written per table."""
    sink = ZarrSink(target, **chunks)
    sink.start(CONFIG_IN, N_BALLS, np.array([0.005, 0.005, 0.006]))
    written = {"frames": [], "events": [], "energy": []}
    for size in (1, 7, 2, 13, 4):
        written["frames"].append(frame_block(rng, size))
        written["energy"].append(energy_block(rng, size))
        written["events"].append(event_block(rng, 3 * size))
        sink.frames(written["frames"][-1])
        sink.energy(written["energy"][-1])
        sink.events(written["events"][-1])
    sink.finish({"events": 81, "mean_se": np.float64(1e-6), "err": float("nan")}, "complete")
    return {k: cat(v) for k, v in written.items()}


def assert_tables_equal(got, expected):
    assert got.keys() == expected.keys()
    for k in expected:
        np.testing.assert_array_equal(got[k], expected[k])


def test_round_trip_open_run(tmp_path):
    written = write_run(tmp_path / "run.zarr", np.random.default_rng(0), frame_chunk=8, event_chunk=32)
    run = open_run(tmp_path / "run.zarr")
    assert (run.schema_version, run.status, run.config) == (SCHEMA_VERSION, "complete", CONFIG_OUT)
    assert run.summary["events"] == 81 and np.isnan(run.summary["err"])
    np.testing.assert_array_equal(run.radii, [0.005, 0.005, 0.006])
    assert_tables_equal(run.frames, written["frames"])
    assert_tables_equal(run.events, written["events"])
    assert_tables_equal(run.energy, written["energy"])
    for k, (dtype, _, _) in EVENT_COLUMNS.items():
        assert run.events[k].dtype == np.dtype(dtype)


def test_round_trip_plain_zarr(tmp_path):
    written = write_run(tmp_path / "run.zarr", np.random.default_rng(1), frame_chunk=8, event_chunk=32)
    g = zarr.open_group(tmp_path / "run.zarr", mode="r")
    assert g.attrs["schema_version"] == SCHEMA_VERSION and g.attrs["status"] == "complete"
    assert g.attrs["config"] == CONFIG_OUT and g.attrs["n_balls"] == N_BALLS
    for table, columns in (("events", EVENT_COLUMNS), ("energy", ENERGY_COLUMNS)):
        assert g[table].attrs["n_valid"] == len(written[table][next(iter(columns))])
        for k, (dtype, unit, text) in columns.items():
            arr = g[table][k]
            assert (arr.dtype, arr.attrs["units"], arr.attrs["description"]) == (dtype, unit, text)
            np.testing.assert_array_equal(arr[: g[table].attrs["n_valid"]], written[table][k])
    pos = g["trajectory/position"]
    assert pos.metadata.dimension_names == ("frame", "ball", "xyz") and pos.attrs["units"] == "m"
    assert g["trajectory/spin"].attrs["units"] == "rad/s"
    np.testing.assert_array_equal(pos[:], written["frames"]["position"])


def test_dask_reads_store(tmp_path):
    da = pytest.importorskip("dask.array")
    written = write_run(tmp_path / "run.zarr", np.random.default_rng(2), frame_chunk=8, event_chunk=32)
    events = zarr.open_group(tmp_path / "run.zarr", mode="r")["events"]
    lazy = da.from_zarr(events["un"])[: events.attrs["n_valid"]]
    np.testing.assert_array_equal(lazy.compute(), written["events"]["un"])


def test_sweep_subgroups(tmp_path):
    root = zarr.open_group(tmp_path / "sweep.zarr", mode="w")
    a = write_run(root.create_group("p0"), np.random.default_rng(3))
    b = write_run(root.create_group("p1"), np.random.default_rng(4))
    assert_tables_equal(open_run(root["p0"]).events, a["events"])
    reopened = zarr.open_group(tmp_path / "sweep.zarr", mode="r")
    assert_tables_equal(open_run(reopened["p1"]).frames, b["frames"])


def test_small_blocks_buffered_until_chunk_full(tmp_path):
    sink = ZarrSink(tmp_path / "run.zarr", frame_chunk=4)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    rng = np.random.default_rng(5)
    for _ in range(10):
        sink.energy(energy_block(rng, 1))
    assert sink.group["energy"].attrs["n_valid"] == 8
    assert sink.group["energy/time"].shape == (8,)
    sink.flush()
    assert sink.group["energy"].attrs["n_valid"] == 10
    assert open_run(tmp_path / "run.zarr").status == "running"


WRITER = textwrap.dedent(
    """
    import numpy as np
    from taimill.schema import DRIVE_FIELDS, ENERGY_COLUMNS, EVENT_COLUMNS
    from taimill.store.writer import ZarrSink

    def rows(k0, n, dtype):
        k = np.arange(k0, k0 + n)
        return k % 100 if dtype.startswith("i") else k.astype(float)

    sink = ZarrSink({path!r}, frame_chunk=8, event_chunk=16)
    sink.start({{}}, {n}, np.full({n}, 0.005))
    f = e = 0
    for block in range(10**6):
        nf, ne = block % 5 + 1, 2 * (block % 7) + 1
        t = rows(f, nf, "f8")
        v = np.broadcast_to(t[:, None, None], (nf, {n}, 3))
        sink.frames({{"time": t, "position": v, "velocity": -v, "spin": 2 * v, **{{k: t for k in DRIVE_FIELDS}}}})
        sink.energy({{k: rows(f, nf, d) for k, (d, _, _) in ENERGY_COLUMNS.items()}})
        sink.events({{k: rows(e, ne, d) for k, (d, _, _) in EVENT_COLUMNS.items()}})
        f, e = f + nf, e + ne
        if block % 2:
            sink.flush()
            print(f, e, flush=True)
    """
)


def expected_rows(n, dtype):
    k = np.arange(n)
    return k % 100 if dtype.startswith("i") else k.astype(float)


def kill_writer(path, seed):
    """Run WRITER, SIGKILL it a seeded 0-30 ms after its 2nd to 5th flush; return the
    last printed (frames, events) counts, which are committed."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    code = WRITER.format(path=str(path), n=N_BALLS)
    rng = random.Random(seed)
    with subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env
    ) as proc:
        try:
            for _ in range(rng.randint(2, 5)):
                line = proc.stdout.readline()
            assert line, "writer died before it was killed"
            time.sleep(rng.uniform(0, 0.03))
        finally:
            proc.send_signal(signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    return tuple(map(int, line.split()))


def assert_committed_rows_match(path, frames, events):
    g = zarr.open_group(path, mode="r")
    run = open_run(path)
    assert g["trajectory"].attrs["n_valid"] >= frames and g["events"].attrs["n_valid"] >= events
    for table in ("trajectory", "events", "energy"):
        n = g[table].attrs["n_valid"]
        assert all(arr.shape[0] >= n for _, arr in g[table].arrays())
    t = expected_rows(len(run.frames["time"]), "f8")
    np.testing.assert_array_equal(run.frames["time"], t)
    np.testing.assert_array_equal(run.frames["spin"][:, 2, 1], 2 * t)
    np.testing.assert_array_equal(run.energy["kinetic"], expected_rows(len(run.energy["time"]), "f8"))
    for k, (dtype, _, _) in EVENT_COLUMNS.items():
        np.testing.assert_array_equal(run.events[k], expected_rows(len(run.events["un"]), dtype))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sigkill_leaves_readable_store(tmp_path, seed):
    path = tmp_path / "run.zarr"
    frames, events = kill_writer(path, seed)
    assert open_run(path).status == "running"
    assert_committed_rows_match(path, frames, events)
    trim_to_valid(path)
    assert_committed_rows_match(path, frames, events)


def test_torn_append_ignored_and_trimmed(tmp_path):
    path = tmp_path / "run.zarr"
    written = write_run(path, np.random.default_rng(6), frame_chunk=8, event_chunk=32)
    g = zarr.open_group(path, mode="r+")
    g["events/x"].append(np.ones(5))
    g["trajectory/position"].append(np.ones((2, N_BALLS, 3)))
    n_events = g["events"].attrs["n_valid"]
    assert g["events/x"].shape == (n_events + 5,)
    run = open_run(path)
    assert_tables_equal(run.events, written["events"])
    assert_tables_equal(run.frames, written["frames"])
    trim_to_valid(path)
    g = zarr.open_group(path, mode="r")
    assert g["events/x"].shape == (n_events,)
    assert g["trajectory/position"].shape == (len(written["frames"]["time"]), N_BALLS, 3)
    assert_tables_equal(open_run(path).events, written["events"])


def test_column_mismatch_names_columns(tmp_path):
    sink = ZarrSink(tmp_path / "run.zarr")
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    block = event_block(np.random.default_rng(7), 2)
    del block["peak_force"]
    block["colour"] = np.zeros(2)
    with pytest.raises(ValueError, match=r"missing columns \['peak_force'\].*\['colour'\]"):
        sink.events(block)
    frames = frame_block(np.random.default_rng(8), 2)
    del frames["spin"]
    with pytest.raises(ValueError, match="spin"):
        sink.frames(frames)


def test_bad_shapes_and_dtypes_rejected(tmp_path):
    sink = ZarrSink(tmp_path / "run.zarr")
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    rng = np.random.default_rng(9)
    with pytest.raises(ValueError, match="position"):
        sink.frames({**frame_block(rng, 2), "position": np.zeros((2, N_BALLS + 1, 3))})
    with pytest.raises(ValueError, match="kind"):
        sink.events({**event_block(rng, 2), "kind": np.zeros(2)})
    with pytest.raises(ValueError, match="differ in length"):
        sink.energy({**energy_block(rng, 2), "time": np.zeros(3)})
    sink.finish({}, "complete")
    assert len(open_run(tmp_path / "run.zarr").events["kind"]) == 0


def test_a_version_1_store_still_reads(tmp_path):
    # Version-1 stores have no per-frame drive and no mechanism columns: readers skip them.
    path = tmp_path / "v1.zarr"
    written = write_run(path, np.random.default_rng(8))
    g = zarr.open_group(path, mode="r+")
    for name in DRIVE_FIELDS:
        del g["trajectory"][name]
    for name in MECHANISM_COLUMNS:
        del g["energy"][name]
    g.attrs["schema_version"] = 1
    run = open_run(path)
    assert set(run.frames) == set(FRAME_FIELDS) - set(DRIVE_FIELDS)
    np.testing.assert_array_equal(run.frames["position"], written["frames"]["position"])
    assert "dissipated" in run.energy and not set(MECHANISM_COLUMNS) & set(run.energy)


@pytest.mark.parametrize("rows, chunk", [(13, 8), (70000, 65536)])  # large chunks: Blosc could use threads
def test_chunks_are_the_bytes_zarr_writes(tmp_path, rows, chunk):
    # the sink encodes and stores whole chunks itself (store.chunks._ChunkWriter): a chunk
    # must be byte for byte what zarr stores for the same rows, full or partial
    rng = np.random.default_rng(11)
    sink = ZarrSink(tmp_path / "run.zarr", frame_chunk=chunk, event_chunk=2 * chunk)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    frames = {k: np.cumsum(v, axis=0) for k, v in frame_block(rng, rows).items()}  # smooth, as a run's: compressible
    events = event_block(rng, rows + rows // 2)
    sink.frames(frames)
    sink.events(events)
    sink.finish({}, "complete")
    ref = zarr.open_group(tmp_path / "ref.zarr", mode="w")
    compared = 0
    for table, block in (("trajectory", frames), ("events", events)):
        for k, v in block.items():
            ours = zarr.open_array(tmp_path / "run.zarr" / table / k, mode="r")
            theirs = ref.create_array(f"{table}/{k}", shape=v.shape, chunks=ours.chunks, dtype=ours.dtype,
                                      fill_value=ours.fill_value, compressors=ours.compressors,
                                      config={"write_empty_chunks": True})
            theirs[:] = v
            for ref_file in (tmp_path / "ref.zarr" / table / k / "c").rglob("*"):
                if ref_file.is_file():
                    mine = tmp_path / "run.zarr" / ref_file.relative_to(tmp_path / "ref.zarr")
                    assert mine.read_bytes() == ref_file.read_bytes(), (table, k, ref_file.name)
                    compared += 1
    n_events = len(events["t_start"])
    assert compared == len(frames) * -(-rows // chunk) + len(events) * -(-n_events // (2 * chunk))


@pytest.mark.parametrize("n_balls, frames", [(12, 32768), (1000, 699), (43690, 16), (43691, 1), (100_000, 1)])
def test_trajectory_chunks_are_bounded_in_bytes_and_one_frame_for_large_mills(tmp_path, n_balls, frames):
    # the sink holds one chunk of rows per array: up to 16 MiB per array, and only one
    # frame above 1 MiB per frame (≈ 44 000 balls), where 6 frames cost ≈ 430 B a ball;
    # a small mill's chunk is at most a dense launch (32768 frames, not 16 MiB's 58254)
    sink = ZarrSink(tmp_path / "run.zarr")
    sink.start({"trajectory_rate": 1e5}, n_balls, np.full(n_balls, 0.001))
    assert sink.group["trajectory/position"].chunks == (frames, n_balls, 3)


def test_arrays_are_sized_for_the_expected_frames_and_resized_only_at_the_end(tmp_path, monkeypatch):
    # growing an array rewrites its metadata (≈ 12 ms a table): the sink creates the
    # frame tables as long as duration × trajectory_rate, in whole chunks, and a run
    # that delivers them resizes each table once, at flush, to its rows exactly
    from taimill.store.chunks import _TableWriter
    from taimill.store.layout import expected_frames

    resized = []
    real = _TableWriter._resize
    monkeypatch.setattr(_TableWriter, "_resize", lambda self, rows: (resized.append((self.name, rows)), real(self, rows)))
    sink = ZarrSink(tmp_path / "run.zarr", frame_chunk=8)
    sink.start({"trajectory_rate": 100.0, "duration": 0.3}, N_BALLS, np.full(N_BALLS, 0.005))
    assert sink.group["trajectory/position"].shape[0] == 32 and sink.group["energy/kinetic"].shape[0] == 32
    assert sink.group["events/x"].shape[0] == 0  # events: not known ahead
    rng = np.random.default_rng(12)
    for size in (7, 9, 10, 6):  # 32 frames, as 0.3 s at 100 frames/s (+ the first and a spare)
        sink.frames(frame_block(rng, size))
        sink.energy(energy_block(rng, size))
    sink.finish({}, "complete")
    assert [r for r in resized if r[0] != "events"] == []  # exactly as long as expected: never resized
    assert len(open_run(tmp_path / "run.zarr").frames["time"]) == 32
    # a run that stops early (interrupted) shrinks each frame table once, at flush
    sink = ZarrSink(tmp_path / "short.zarr", frame_chunk=8)
    sink.start({"trajectory_rate": 100.0, "duration": 0.3}, N_BALLS, np.full(N_BALLS, 0.005))
    sink.frames(frame_block(rng, 11))
    sink.energy(energy_block(rng, 11))
    resized.clear()
    sink.finish({}, "interrupted")
    assert sorted(r for r in resized if r[0] != "events") == [("energy", 11), ("trajectory", 11)]
    assert zarr.open_array(tmp_path / "short.zarr" / "trajectory" / "spin", mode="r").shape == (11, N_BALLS, 3)
    # no duration or no rate, or nonsense: nothing expected
    assert [expected_frames(c) for c in ({}, {"trajectory_rate": 100.0}, {"duration": 1.0, "trajectory_rate": -1},
                                          {"duration": float("nan"), "trajectory_rate": 5.0})] == [0, 0, 0, 0]
    assert expected_frames({"duration": 0.3, "trajectory_rate": 100}) == 32


def test_a_writer_killed_between_a_frame_and_its_ledger_row_reads_the_frames_both_hold(tmp_path):
    # Each table commits through its own n_valid when a chunk lands. A dense
    # trajectory lands a chunk of frames, then one of ledger rows, at every launch: a
    # writer killed between the two (simulated: abandoned) has frames one launch ahead
    # of the ledger. Readers take the frames both tables hold, from the arrays and the
    # journal alike; a finished writer's tables must agree anyway (checked).
    rng = np.random.default_rng(13)
    sink = ZarrSink(tmp_path / "run.zarr", frame_chunk=8)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    frames, energy = [], []
    for size in (8, 5, 3, 4):  # chunk, then rows left to the journal by the commits
        frames.append(frame_block(rng, size))
        end = sum(len(f["time"]) for f in frames)
        energy.append(energy_block(rng, size) | {"time": np.arange(end - size, end, dtype=float)})  # commits every block
        sink.frames(frames[-1])
        sink.energy(energy[-1])
    sink.frames(frame_block(rng, 12))  # two chunks land (n_valid 32), the ledger's rows never come
    g = zarr.open_group(tmp_path / "run.zarr", mode="r")
    assert (g["trajectory"].attrs["n_valid"], g["energy"].attrs["n_valid"]) == (32, 16)
    run = open_run(tmp_path / "run.zarr")
    assert run.status == "running"
    assert_tables_equal(run.frames, cat(frames))  # 20 frames: 16 in chunks, 4 from the journal
    assert_tables_equal(run.energy, cat(energy))
