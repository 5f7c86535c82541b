"""The Textual app driven by Pilot: fields change the running LiveMill (speeds ramp),
bad values are refused with a message and change nothing, pause/resume, recordings to
.rrd and zarr appear and read back, quit; snapshots of the main and help screens."""

import subprocess
import sys

import numpy as np
import pytest
import rerun as rr
from helpers import numbers_without_unit

from taimill.analysis.run import analyse
from taimill.recording import scene
from taimill.model.drive import RPM
from taimill.model.params import ROOT, load_preset
from taimill.runs.live import LiveMill
from taimill.store.run import open_run
from taimill.tui.app import MillApp

P4 = ROOT / "presets" / "p4-cy-steel.toml"
SIZE = (120, 40)
STEPS = 230_000  # ≈ 0.3 s into the 1 s start-up ramp


@pytest.fixture
def mill():
    m = LiveMill(load_preset(P4))
    m.advance(steps=STEPS)
    return m


async def enter(pilot, field: str, text: str):
    """Focus a field as Tab does (its text gets selected), type over it, press Enter."""
    pilot.app.query_one(f"#{field}").focus()
    await pilot.pause()
    await pilot.press(*text, "enter")
    await pilot.pause()


def message(app) -> str:
    return str(app.query_one("#message").render())


def value(app, field: str) -> str:
    return app.query_one(f"#{field}").value


async def wait_until(pilot, condition, timeout=20.0):
    for _ in range(int(timeout / 0.05)):
        if condition():
            return
        await pilot.pause(0.05)
    raise AssertionError("condition not reached in time")


async def test_speed_fields_ramp_the_running_mill(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        t = mill.time
        om_before = mill.drive(t)["plate"]
        await enter(pilot, "plate-rpm", "300")
        # K held (-2.6), ω follows; a ramp from the current speed at the current time
        assert (mill.plate_rpm, mill.ratio) == pytest.approx((300, -2.6))
        assert value(app, "jar-rpm") == "-1080"
        assert mill.plate.t0 == t and mill.plate.start == pytest.approx(om_before, rel=1e-12)
        assert mill.plate.duration == 1.0 and tuple(mill.F.plate_ramp[0]) == pytest.approx(mill.plate.as_tuple())
        await pilot.press("escape", "s", "s", "s")  # leave the field; three frames of 10 ms
        await wait_until(pilot, lambda: mill.time > t + 0.029)
        now = mill.drive()["plate"]
        assert om_before < now < 300 * RPM  # ramping, not jumped
        assert "ramping" in message(app)

        await enter(pilot, "ratio", "-3")
        assert mill.ratio == pytest.approx(-3) and value(app, "jar-rpm") == "-1200"
        assert mill.jar.end == pytest.approx(-900 * RPM) and mill.jar.t0 == pytest.approx(mill.time)
        await enter(pilot, "jar-rpm", "-600")
        assert mill.jar_rpm == pytest.approx(-600) and value(app, "ratio") == "-1"
        await enter(pilot, "plate-rpm", "200")  # ω now held
        assert mill.jar_rpm == pytest.approx(-600) and value(app, "ratio") == "-2"


async def test_friction_fields_and_pair(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await enter(pilot, "mu-d", "0.2")
        await enter(pilot, "mu-s", "0.3")
        assert (mill.friction.mu_s, mill.friction.mu_d) == (0.3, 0.2)
        assert (mill.F.mu_s[0], mill.F.mu_d[0]) == (0.3, 0.2)  # the kernel's data
        app.query_one("#pair").value = "steel-graphite"
        await pilot.pause()
        assert (mill.F.mu_s[0], mill.F.mu_d[0]) == (0.1, 0.08) and value(app, "mu-s") == "0.1"
        assert "steel-graphite" in message(app)


async def test_bad_values_are_refused_and_change_nothing(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        before = (mill.plate, mill.jar, mill.friction, mill.dt, mill.n_balls)
        for field, text, expected in (
            ("plate-rpm", "5000", "plate_rpm = 5000.0: allowed range [0, 1000] rpm"),
            ("ratio", "-12", "ratio = -12.0: allowed range [-10, 10]"),
            ("jar-rpm", "abc", "jar_rpm = 'abc'"),
            ("mu-d", "1.5", "mu_d = 1.5: dynamic friction must not exceed static mu_s = 1"),
            ("ramp-time", "0", "ramp_time = 0.0: allowed range [0.01, 60] s"),
        ):
            await enter(pilot, field, text)
            assert expected in message(app), message(app)
            assert app.query_one("#message").has_class("error")
            assert (mill.plate, mill.jar, mill.friction, mill.dt, mill.n_balls) == before
        assert value(app, "plate-rpm") == "200" and value(app, "mu-d") == "0.8"  # fields show what runs
        await enter(pilot, "balls", "200")
        await wait_until(pilot, lambda: "balls.count = 200" in message(app))
        assert "balls fill" in message(app) and mill.n_balls == 12 and mill.time > 0.29


async def test_pause_resume_and_step(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path)
    async with app.run_test(size=SIZE) as pilot:
        t0 = mill.time
        await wait_until(pilot, lambda: mill.time > t0 + 0.01)
        await pilot.press("p")
        await pilot.pause(0.1)
        t_paused = mill.time
        await pilot.pause(0.3)
        assert mill.time == t_paused and "paused" in str(app.query_one("#status").render())
        await pilot.press("s")
        await wait_until(pilot, lambda: mill.time > t_paused)
        assert mill.time == pytest.approx(t_paused + 0.01, abs=2 * mill.dt)  # one frame interval
        await pilot.press("p")
        await wait_until(pilot, lambda: mill.time > t_paused + 0.05)
        assert "running" in str(app.query_one("#status").render())


async def test_record_rrd_and_zarr_mid_run(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("o", "z")
        await wait_until(pilot, lambda: len(app.recorders.active) == 2)
        t_start = app.recorders.active["zarr"].t_start
        assert t_start >= STEPS * mill.dt * 0.99  # starts at the current sim time
        await wait_until(pilot, lambda: mill.time > t_start + 0.05)
        await enter(pilot, "mu-s", "0.9")
        await pilot.press("escape")
        await wait_until(pilot, lambda: mill.time > t_start + 0.1)
        await pilot.press("o", "z")
        await wait_until(pilot, lambda: not app.recorders.active)
    rrd, = tmp_path.glob("*.rrd")
    zarr, = tmp_path.glob("*.zarr")
    run = open_run(zarr)
    frames = run.frames["time"]
    assert run.status == "stopped" and len(frames) >= 10
    assert t_start <= frames[0] < t_start + 0.011 and np.all(np.diff(frames) > 0)  # from the key on
    assert run.summary["recorded"][0] == t_start and run.summary["events"] > 0
    assert [c["mu_s"] for c in run.summary["live_changes"]] == [0.9]
    assert numbers_without_unit(run.summary) == [] and run.summary["units"]["recorded"] == "s"
    ev = run.events  # events are streamed when they end: a contact open at the key press counts
    assert len(ev["t_start"]) > 0 and (ev["t_start"] + ev["duration"]).min() >= t_start
    balls = rr.chunk.RrdReader(rrd).stream().collect().reader(index=scene.TIME, contents=scene.BALLS).to_arrow_table()
    times = np.sort([x.total_seconds() for x in balls[scene.TIME].to_pylist()])
    # the two recordings overlap (keys pressed one after the other): the same frames there
    lo, hi = max(times[0], frames[0]) - 1e-6, min(times[-1], frames[-1]) + 1e-6  # rerun keeps ns
    assert hi - lo >= 0.05
    np.testing.assert_allclose(times[(times >= lo) & (times <= hi)], frames[(frames >= lo) & (frames <= hi)], atol=1e-9)


async def test_zarr_recording_is_analysed_over_its_own_window(tmp_path):
    # Past the preset's analysis_start (4 s): the recording's window starts where the
    # key was pressed. dt twice the automatic one (12 steps per contact) halves the
    # 20 s of simulation before it.
    mill = LiveMill(load_preset(P4, {"dt": 2 * load_preset(P4).dt}))
    mill.advance(steps=int(20.01 / mill.dt))
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("z")
        await wait_until(pilot, lambda: app.recorders.active)
        t_start = app.recorders.active["zarr"].t_start
        await pilot.press("p")
        await wait_until(pilot, lambda: mill.time > t_start + 0.3)
        await pilot.press("z")
        await wait_until(pilot, lambda: not app.recorders.active)
    zarr, = tmp_path.glob("*.zarr")
    a = analyse(zarr)
    q, own = a.quantities(), a.store.summary
    assert t_start >= 20.0 and q["analysis_window"][0] == own["analysis_window"][0] == t_start
    assert q["event_estimator"]["collision_rate"] == pytest.approx(own["collision_rate"], rel=0.2)
    # The ledger is cumulative from t = 0; both balance it from the recording's first row
    # (before, analyse reported the 20 s of dissipation before the recording as an error).
    assert q["energy_balance_error"] < 0.01 and own["energy_balance_error"] < 0.01
    assert q["drive_work"] == pytest.approx(own["drive_work"], rel=1e-9)  # the work done while it recorded
    shown = (a.store.frames["time"] >= a.t0) & (a.store.frames["time"] < a.t0 + 0.5)  # the report's trajectory panels
    assert shown.sum() >= 20


async def test_quit_closes_recordings_and_stops_the_worker(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("z")
        await wait_until(pilot, lambda: app.recorders.active)
        await pilot.press("q")
        await wait_until(pilot, lambda: not app.is_running)
    assert app.loop.stopped.is_set() and app.return_code in (0, None)
    zarr, = tmp_path.glob("*.zarr")
    assert open_run(zarr).status == "stopped: quit"


async def test_reset_new_jar_and_png(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await enter(pilot, "plate-rpm", "250")
        await pilot.press("escape", "r")
        await pilot.pause()
        assert mill.time == 0 and mill.plate_rpm == 250 and "reset" in message(app)
        app.query_one("#jar").value = "HM"
        await wait_until(pilot, lambda: mill.preset.jar.name == "HM")
        assert mill.time == 0 and mill.plate_rpm == 250 and "HM jar, 12 balls" in message(app)
        np.testing.assert_array_equal(app.top_view.outline, mill.preset.jar.profile.outline)
        app.query_one("#jar").value = "EFV45"  # zirconia walls: not for steel balls
        await wait_until(pilot, lambda: "refused" in message(app))
        assert "wall material zirconia" in message(app) and value(app, "jar") == "HM"
        await pilot.press("g")
        await wait_until(pilot, lambda: list(tmp_path.glob("*.png")))
        await wait_until(pilot, lambda: "figures saved" in message(app))
    png, = tmp_path.glob("*.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


async def test_unstable_run_stops_with_a_message_and_reset_recovers(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path)
    async with app.run_test(size=SIZE) as pilot:
        mill.F.bad_ball[0], mill.F.status[0] = 3, 2  # as the kernel flags a ball through the wall
        await wait_until(pilot, lambda: "simulation stopped" in message(app))
        assert "ball 3 left the jar through a wall" in message(app) and app.loop.paused
        await pilot.press("r", "p")
        await wait_until(pilot, lambda: mill.time > 0.01)
        assert not app.loop.paused


def test_cli_refuses_bad_input_before_any_kernel(tmp_path):
    for args, expected in ((["--window", "0"], "--window = 0.0: allowed range [0.1, 600] s"),
                           (["--plate-rpm", "5000"], "plate_rpm = 5000.0: allowed range [-1000, 1000]")):
        p = subprocess.run([sys.executable, "-m", "taimill.cli", "tui", str(P4), *args], capture_output=True, text=True, timeout=120)
        assert p.returncode == 2 and expected in p.stderr, p.stderr


def frozen_app(mill, tmp_path):
    """Paused at a fixed state (serial kernels are bit-stable) with 0.2 s in the readout
    window: nothing in the picture depends on timing."""
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    mill.advance(steps=150_000)
    return app


def test_main_screen_snapshot(mill, tmp_path, snap_compare):
    assert snap_compare(frozen_app(mill, tmp_path), terminal_size=SIZE)


def test_help_screen_snapshot(mill, tmp_path, snap_compare):
    assert snap_compare(frozen_app(mill, tmp_path), press=["question_mark"], terminal_size=SIZE)
