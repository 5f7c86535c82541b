"""Rerun recordings (issue 6): a real run through the real CLI writes a zarr store and a
recording of the same stream; rerun's own reader reads the recording back.

One 0.5 s run of the reference preset (≈ 50 frames, ≈ 500 events) serves every test."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.recording import scene
from taimill.recording.sink import RerunSink
from taimill.recording.stats import hist_edges, onset_histogram, window_sums
from taimill.store.run import open_run

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "presets" / "p4-cy-steel.toml"
DURATION = 0.5
# Positions are stored as float32 in rerun (Points3D): 2^-24 relative, ≤ 3e-9 m in a
# 32.5 mm jar; rtol 1e-7 / atol 1e-8 m admits exactly that rounding.
F32 = dict(rtol=1e-7, atol=1e-8)
NS = 1e-9  # rerun's duration timelines count integer nanoseconds


def cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "taimill.cli", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300, env=env)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """(store, live recording path, converted recording path) of one short run."""
    d = tmp_path_factory.mktemp("rec")
    live, converted = d / "run.rrd", d / "converted.rrd"
    p = cli("run", PRESET, "--duration", DURATION, "--out", d / "run.zarr", "--rrd", live, "--json")
    assert p.returncode == 0, p.stderr
    p = cli("record", d / "run.zarr", "--rrd", converted, "--lab-frame")
    assert p.returncode == 0, p.stderr
    return open_run(d / "run.zarr"), live, converted


def table(path: Path, entity: str, index: str = scene.TIME) -> dict:
    """Columns of one entity (arrow → Python lists), rows in index order."""
    store = rr.chunk.RrdReader(path).stream().collect()
    t = store.reader(index=index, contents=entity).to_arrow_table()
    t = t.sort_by(index) if index else t
    return {name.split(":")[-1] if ":" in name else name: t[name].to_pylist() for name in t.column_names}


def seconds(column) -> np.ndarray:
    return np.array([x.total_seconds() if hasattr(x, "total_seconds") else x / 1e9 for x in column])


def series(path: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    t = table(path, f"/stats/{name}")
    return seconds(t[scene.TIME]), np.array([v[0] for v in t["scalars"]])


def test_entity_paths(run):
    _, live, _ = run
    paths = set(rr.chunk.RrdReader(live).stream().collect().schema().entity_paths())
    expected = {scene.WALL, scene.FLOOR, scene.BALLS, *scene.IMPACTS.values(), scene.CONTACT_MAP,
                *scene.HISTOGRAMS.values(), scene.INFO, *(f"/stats/{k}" for k in scene.SERIES)}
    assert expected <= paths, expected - paths


def test_ball_frames_equal_the_store(run):
    store, live, _ = run
    t = table(live, scene.BALLS)
    frames = store.frames
    assert len(t["positions"]) == len(frames["time"]) == round(DURATION * 100) + 1  # 100 Hz, both ends
    np.testing.assert_allclose(seconds(t[scene.TIME]), frames["time"], rtol=0, atol=NS)
    dt = store.config["dt"]
    np.testing.assert_array_equal(t[scene.STEP], np.rint(frames["time"] / dt))
    np.testing.assert_allclose(np.array(t["positions"]), frames["position"], **F32)
    np.testing.assert_allclose(table(live, scene.BALLS, index=None)["radii"][0], store.radii, rtol=1e-7)


def test_impacts_and_contact_map_are_the_store_events(run):
    store, live, _ = run
    e = store.events
    assert len(e["t_start"]) > 100  # a 0.5 s run of 12 balls has hundreds of contacts
    for path in scene.IMPACTS.values():
        t = table(live, path)
        at = np.array([p[0] for p in t["positions"]])
        order = np.lexsort((e["x"], e["t_start"]))
        got = np.lexsort((at[:, 0], seconds(t[scene.TIME])))
        np.testing.assert_allclose(at[got], np.column_stack([e["x"], e["y"], e["z"]])[order], **F32)
    wall = table(live, scene.CONTACT_MAP)
    assert len(wall["positions"]) == int(np.sum(e["kind"] == 1))


def test_sliding_window_series_follow_the_events(run):
    """At the last frame T the window is (T - min(1 s, T), T]: impact power and stress-event
    rate recomputed from the stored stress events (onset u̇n ≥ STRESS_MIN_UN; float64 sums
    in another order: 1e-9 relative)."""
    store, live, _ = run
    e = store.events
    t, normal = series(live, "impact_power/normal")
    np.testing.assert_allclose(t, store.frames["time"][1:], rtol=0, atol=NS)
    T = store.frames["time"][-1]  # exact, not rounded to ns
    length = min(1.0, T - store.frames["time"][0])
    inside = (e["t_start"] > T - length) & (e["t_start"] <= T) & (e["un"] >= STRESS_MIN_UN)
    assert normal[-1] == pytest.approx(e["se_n"][inside].sum() / length, rel=1e-9)
    _, rate = series(live, "collision_rate")
    assert rate[-1] == pytest.approx(inside.sum() / length, rel=1e-9)
    _, tangential = series(live, "impact_power/tangential")
    assert tangential[-1] == pytest.approx(e["se_t"][inside].sum() / length, rel=1e-9)
    _, kinetic = series(live, "kinetic_energy")
    np.testing.assert_allclose(kinetic, store.energy["kinetic"][1:], rtol=1e-12)


def test_stress_energy_series_are_in_mj_as_in_the_reports(run):
    """The mean stress energy over the last window, read back from the .rrd, in mJ (the
    reports', summary's and TUI's unit; it was J), the unit in the entity path and in
    the colour-scale line of the run's info."""
    store, live, _ = run
    e = store.events
    T = store.frames["time"][-1]
    length = min(1.0, T - store.frames["time"][0])
    inside = (e["t_start"] > T - length) & (e["t_start"] <= T) & (e["un"] >= STRESS_MIN_UN)
    expected_mj = 1e3 * (e["se_n"][inside] + e["se_t"][inside]).sum() / inside.sum()
    _, total = series(live, "mean_se_mJ/total")
    assert total[-1] == pytest.approx(expected_mj, rel=1e-9)
    assert 0.01 < total[-1] < 100  # mJ: a 6 mm steel ball's stress energies are 0.1 … 10 mJ
    _, normal = series(live, "mean_se_mJ/normal")
    assert normal[-1] == pytest.approx(1e3 * e["se_n"][inside].sum() / inside.sum(), rel=1e-9)
    paths = set(rr.chunk.RrdReader(live).stream().collect().schema().entity_paths())
    assert "/stats/mean_se/total" not in paths and "/stats/mean_se_mJ/total" in paths
    info = table(live, scene.INFO, index=None)["text"][-1][0]
    assert " mJ)" in info and "up to" in info


def test_energy_balance_series_closes(run):
    """The ledger closes to ≈ 1e-4 of the energy turned over (summary of the same run);
    1 % would flag a broken ledger or a wrong sign in the series."""
    _, live, _ = run
    _, err = series(live, "energy_balance_error")
    assert np.isfinite(err[1:]).all() and err[1:].max() < 0.01  # row 0 is t = 0: nothing to compare yet


def test_histogram_of_the_whole_short_run(run):
    """0.5 s < histogram_every: one partial histogram at the end with every event."""
    store, live, _ = run
    h = table(live, scene.HISTOGRAMS["normal"])
    assert len(h["values"]) == 1
    shares = np.array(h["values"][0][0]["buffer"])
    np.testing.assert_allclose(shares, onset_histogram(store.events["un"]), rtol=1e-12)
    assert shares.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(h["abscissa"][0][0]["buffer"], 0.5 * (hist_edges()[1:] + hist_edges()[:-1]) + 3.0)  # log10 mm/s


def test_blueprint_saved_with_the_file(run):
    _, live, _ = run
    reader = rr.chunk.RrdReader(live)
    assert len(reader.blueprints()) == 1
    bp = reader.stream(store=reader.blueprints()[0]).collect().reader(index="blueprint").to_arrow_table()
    values = {name: [x for x in bp[name].to_pylist() if x is not None] for name in bp.column_names}
    kinds = sorted(v[0][0] for k, v in values.items() if k.endswith("ViewBlueprint:class_identifier"))
    assert kinds.count("3D") == 2 and kinds.count("TimeSeries") == 6 and kinds.count("BarChart") == 2
    impacts = [v[0][0] for k, v in values.items() if "overrides/jar/impacts" in k and k.endswith("ranges")]
    assert [r["range"]["start"] for r in impacts] == [-round(scene.IMPACT_LIFE * 1e9)] * 2
    # the jar view's camera looks at the jar's centre from far enough for the whole jar
    # (its bounding sphere) to fit a 45° field of view: the viewer's own choice cropped it
    radius, height = scene.extent_of(run[0].config)
    eye = {k.rpartition(":")[2]: np.array(v[0][0]) for k, v in values.items() if "EyeControls3D:" in k}
    np.testing.assert_allclose(eye["look_target"], [0.0, 0.0, height / 2], atol=1e-6)
    rho = np.hypot(radius, height / 2)
    assert np.linalg.norm(eye["position"] - eye["look_target"]) >= rho / np.sin(np.radians(22.5))
    assert scene.recorded_extent(live) == pytest.approx((radius, height), rel=1e-6)  # float32 in the file


def test_record_of_the_store_equals_the_live_recording(run):
    _, live, converted = run
    a, b = table(live, scene.BALLS), table(converted, scene.BALLS)
    assert a[scene.TIME] == b[scene.TIME]
    np.testing.assert_array_equal(np.array(a["positions"]), np.array(b["positions"]))
    np.testing.assert_array_equal(np.array(a["colors"]), np.array(b["colors"]))
    for name in ("impact_power/normal", "collision_rate", "energy_balance_error"):
        np.testing.assert_array_equal(series(live, name)[1], series(converted, name)[1])


def test_lab_frame_pose_follows_the_ramp(run):
    """Jar axis on the plate circle at φ_p(t) = Ω T (s³ - s⁴/2), s = t/T during the
    start-up ramp (taimill.model.frame.Ramp), turned by φ_jar = w T (s³ - s⁴/2)."""
    store, _, converted = run
    c = store.config
    t = table(converted, scene.JAR)
    time = seconds(t[scene.TIME])
    s = time / c["ramp_time"]
    phase = c["ramp_time"] * (s**3 - s**4 / 2)
    xyz = np.array([v[0] for v in t["translation"]])  # float32 in rerun: 1e-8 m at 0.125 m
    np.testing.assert_allclose(xyz[:, 0], c["plate_radius"] * np.cos(c["plate_omega"] * phase), rtol=0, atol=1e-8)
    np.testing.assert_allclose(xyz[:, 1], c["plate_radius"] * np.sin(c["plate_omega"] * phase), rtol=0, atol=1e-8)
    q = np.array([v[0] for v in t["quaternion"]])  # xyzw, float32: angles to ≈ 1e-7 rad
    turned = 2 * np.arctan2(q[:, 2], q[:, 3])
    np.testing.assert_allclose(np.angle(np.exp(1j * (turned - c["jar_spin"] * phase))), 0.0, atol=1e-6)


def test_sink_started_mid_run(run, tmp_path):
    """The TUI starts a recording at t > 0: windows start at the first recorded frame."""
    store, _, _ = run
    f, e, g = store.frames, store.events, store.energy
    k = 20
    sink = RerunSink(tmp_path / "mid.rrd")
    sink.start(store.config, store.n_balls, store.radii)
    late = e["t_start"] + e["duration"] > f["time"][k]
    sink.events({name: v[late] for name, v in e.items()})
    sink.frames({name: v[k:] for name, v in f.items()})
    sink.energy({name: v[k:] for name, v in g.items()})
    sink.finish({}, "complete")
    assert len(table(tmp_path / "mid.rrd", scene.BALLS)["positions"]) == len(f["time"]) - k
    t, normal = series(tmp_path / "mid.rrd", "impact_power/normal")
    np.testing.assert_allclose(t, f["time"][k + 1:], rtol=0, atol=NS)  # windows need a length > 0
    T, t0 = f["time"][-1], f["time"][k]
    inside = late & (e["t_start"] > t0) & (e["t_start"] <= T) & (e["un"] >= STRESS_MIN_UN)
    assert normal[-1] == pytest.approx(e["se_n"][inside].sum() / min(1.0, T - t0), rel=1e-9)
    _, err = series(tmp_path / "mid.rrd", "energy_balance_error")
    assert err[0] == 0.0 and err.max() < 0.01


def test_window_sums_against_a_loop():
    rng = np.random.default_rng(0)
    t = rng.uniform(0, 3, 500)
    v = rng.uniform(0, 1, 500)
    times = np.linspace(0.1, 3, 30)
    lengths = np.minimum(1.0, times)
    got = window_sums(t, {"v": v}, times, lengths)
    for i, (T, L) in enumerate(zip(times, lengths)):
        inside = (t > T - L) & (t <= T)
        assert got["count"][i] == inside.sum()
        assert got["v"][i] == pytest.approx(v[inside].sum(), rel=1e-12, abs=1e-12)


def test_view_without_display_says_so(run):
    _, live, _ = run
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    p = cli("view", live, env=env)
    assert p.returncode == 4
    assert "no display" in p.stderr and "Traceback" not in p.stderr
    missing = cli("view", live.with_name("missing.rrd"), env=env)
    assert missing.returncode == 2 and "no such file" in missing.stderr and "Traceback" not in missing.stderr


def test_record_refuses_bad_input(run, tmp_path):
    _, live, _ = run
    p = cli("record", tmp_path / "none.zarr", "--rrd", tmp_path / "x.rrd")
    assert p.returncode == 2 and "RUN.zarr" in p.stderr and "no such file" in p.stderr
    p = cli("record", tmp_path, "--rrd", live)
    assert p.returncode == 2 and "--rrd" in p.stderr and "exists" in p.stderr
    p = cli("record", tmp_path, "--rrd", tmp_path / "x.rrd")
    assert p.returncode == 2 and "not a taimill run store" in p.stderr and not (tmp_path / "x.rrd").exists()


class _StuckWriter:
    """A recording whose flush never completes (rerun's file writer on a full disk once
    never answered), or one that completes after `after` waits while the file grows."""

    def __init__(self, path: Path, after: int | None = None):
        self.path, self.after, self.waits = path, after, 0

    def flush(self, timeout_sec):
        self.waits += 1
        if self.after is not None and self.waits > self.after:
            return
        if self.after is not None:  # a slow disk: the file grows while we wait
            with open(self.path, "ab") as f:
                f.write(b"x" * 10)
        raise RuntimeError("Flush timed out - not all log messages were sent")


def test_a_flush_that_never_ends_is_an_error_once_the_file_stops_growing(tmp_path):
    from taimill.errors import StoreWriteError
    from taimill.recording.sink import flush_while_growing

    path = tmp_path / "x.rrd"
    path.write_bytes(b"rrd")
    slow = _StuckWriter(path, after=3)
    flush_while_growing(slow, path, stall=0.01)  # it grew at each wait: waited on, no error
    assert slow.waits == 4
    stuck = _StuckWriter(path)
    with pytest.raises(RuntimeError, match="did not grow for 0.01 s"):
        flush_while_growing(stuck, path, stall=0.01)
    assert stuck.waits == 1
    sink = RerunSink(path)  # and the sink says so as a write that failed, naming the file
    sink.rec, sink.frame_blocks, sink.event_blocks, sink.ledger_blocks = stuck, [], [], []
    sink.flush = lambda final=False: None
    sink._log_info = lambda *a: None
    with pytest.raises(StoreWriteError, match="x.rrd"):
        sink.finish({}, "finished")
    assert sink.failed and sink.rec is None
