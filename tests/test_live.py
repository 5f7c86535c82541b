"""LiveMill: live speed ramps keep Ω, w and the jar's angle continuous; a new time step
keeps simulated time continuous; friction changes reach the kernel; rebuilds and resets."""

import math
import threading
import time

import numpy as np
import pytest

from taimill.errors import ConfigError
from taimill.model.drive import RPM
from taimill.model.files import ROOT
from taimill.model.preset import load_preset
from taimill.model.rules import running_dt
from taimill.runs.live import LiveMill
from taimill.store.sinks import MemorySink

P4 = ROOT / "presets" / "p4-cy-steel.toml"


@pytest.fixture
def mill():
    return LiveMill(load_preset(P4, {"ramp_time": 0.2}))


def angle_gap(a, b):
    return abs(math.remainder(a - b, 2 * math.pi))


def test_speed_change_ramps_from_the_current_state(mill):
    mill.advance(steps=100_000)  # mid start-up ramp (0.13 s of 0.2 s)
    t = mill.time
    before = mill.drive(t)
    mill.set_speeds(plate_rpm=300, ratio=-2.0, ramp_time=0.5)
    after = mill.drive(t)
    # continuity at the switch: speeds to rounding, angles mod 2π (phase0 is wrapped)
    assert after["plate"] == pytest.approx(before["plate"], rel=1e-12)
    assert after["jar"] == pytest.approx(before["jar"], rel=1e-12)
    assert angle_gap(after["plate_angle"], before["plate_angle"]) < 1e-9
    assert angle_gap(after["jar_angle"], before["jar_angle"]) < 1e-9
    # the kernel reads the new ramps (field data), and the time did not move
    assert tuple(mill.F.model.plate_ramp[0]) == pytest.approx(mill.plate.as_tuple(), rel=1e-12)
    assert tuple(mill.F.model.jar_ramp[0]) == pytest.approx(mill.jar.as_tuple(), rel=1e-12)
    assert mill.time == pytest.approx(t, rel=1e-12)
    # a real ramp: halfway at half time, target at the end, Euler term nonzero on the way
    mid = mill.drive(t + 0.25)
    assert mid["plate"] == pytest.approx(0.5 * (before["plate"] + 300 * RPM), rel=1e-12)
    assert mid["plate_accel"] > 0
    end = mill.drive(t + 0.6)
    assert end["plate"] == pytest.approx(300 * RPM) and end["jar"] == pytest.approx(-600 * RPM)
    assert (mill.plate_rpm, mill.ratio) == pytest.approx((300, -2.0))
    assert mill.jar_rpm == pytest.approx(-900)
    mill.set_speeds(jar_rpm=-300)
    assert mill.ratio == pytest.approx(0.0) and mill.plate_rpm == pytest.approx(300)


def test_new_time_step_keeps_time_continuous(mill):
    sink = MemorySink()
    mill.add_sink(sink)
    mill.advance(steps=60_000)  # mid start-up ramp (0.08 s of 0.2 s)
    dt0 = mill.dt
    # slowing down keeps the step of the speeds the ramp passes through …
    mill.set_speeds(plate_rpm=30, ratio=-1.0)
    assert mill.dt == pytest.approx(dt0, rel=1e-4)  # rounded to t/n
    # … and a change once the slow speeds are reached takes the step of its own top
    # speeds (the rule book's time-step rule): at 40 rpm the shortest contact is at the top
    # speed, 2.3 m/s, 5.6 % longer than the preset's (its minimum near 6 m/s)
    mill.advance(steps=int(0.25 / mill.dt))
    t = mill.time
    mill.set_speeds(plate_rpm=40, ratio=-1.0)
    want = running_dt(mill.preset, 40 * RPM, -40 * RPM)
    # rounded down to t/n, n = ⌈t/dt⌉: within dt/t (< 1e-4 at t = 0.33 s)
    assert want * (1 - 1e-4) < mill.dt <= want
    assert mill.dt / dt0 - 1 > 0.05
    assert mill.time == pytest.approx(t, rel=1e-12, abs=0)
    mill.advance(steps=60_000)
    times = sink.frame_table["time"]
    # frames stay on the 100 Hz grid on either side of the switches, to within 1e-4 s (a
    # frame interval is a whole number of steps: half a step of rounding per frame); a
    # time base that jumped with dt would move them by 5.6 % of t = 20 ms
    assert np.all(np.diff(times) > 0) and len(times) == int(mill.time / 0.01) + 1
    assert np.abs(times - np.round(times / 0.01) * 0.01).max() < 1e-4
    events = sink.event_table
    assert events["t_start"].min() >= 0 and events["t_start"].max() <= mill.time
    # speeding up to 400 rpm: the step of the shortest contact at any speed up to the
    # new top speed (11.6 m/s), i.e. back to about the preset's, still continuous
    t = mill.time
    mill.set_speeds(plate_rpm=400, ratio=-3.5)
    want = running_dt(mill.preset, 400 * RPM, -1400 * RPM)
    assert want * (1 - 1e-4) < mill.dt <= want and mill.time == pytest.approx(t, rel=1e-12)
    assert mill.dt == pytest.approx(dt0, rel=0.01)


def test_friction_change_reaches_the_kernel(mill):
    sink = MemorySink()
    mill.add_sink(sink)
    mill.advance(steps=100_000)
    t_off = mill.time
    mill.set_friction(mu_s=0.0, mu_d=0.0)
    assert (mill.F.model.mu_s[0, 0], mill.F.model.mu_d[0, 0]) == (0.0, 0.0)
    mill.advance(steps=150_000)
    t_on = mill.time
    mill.set_friction(pair="steel-steel")
    mill.advance(steps=150_000)
    ev = sink.event_table
    off = (ev["t_start"] > t_off) & (ev["t_start"] + ev["duration"] < t_on)
    on = ev["t_start"] > t_on
    assert off.sum() > 20 and on.sum() > 20
    # μ = 0: the friction force is identically zero, so no event does friction work
    assert np.all(ev["dissipated_friction"][off] == 0.0)
    assert ev["dissipated_friction"][on].sum() > 0.0
    assert mill.friction.mu_s == 1.0 and mill.friction.mu_d == 0.8


def test_bad_live_values_are_refused_and_change_nothing(mill):
    ramps = (mill.plate, mill.jar, mill.friction, mill.dt)
    with pytest.raises(ConfigError, match=r"plate_rpm = 5000.*\[0, 1000\] rpm"):
        mill.set_speeds(plate_rpm=5000)
    with pytest.raises(ConfigError, match=r"ratio = -12.*\[-10, 10\]"):
        mill.set_speeds(ratio=-12)
    with pytest.raises(ConfigError, match=r"mu_d = 0.9.*must not exceed static mu_s = 0.5"):
        mill.set_friction(mu_s=0.5, mu_d=0.9)
    with pytest.raises(ConfigError, match="zirconia"):
        mill.set_friction(pair="zirconia-zirconia")
    with pytest.raises(ConfigError, match=r"TUI: balls.count = 200: balls fill"):
        mill.rebuild(balls=200)
    with pytest.raises(ConfigError, match="known jars"):  # (a jar of other walls is taken: its contact set is derived)
        mill.rebuild(jar="NOPE")
    assert (mill.plate, mill.jar, mill.friction, mill.dt) == ramps
    assert mill.n_balls == 12 and mill.preset.jar.name == "CY"


def test_rebuild_and_reset(mill):
    x0 = mill.state()["position"]
    engine = mill.runner.engine
    mill.set_speeds(plate_rpm=250, ratio=-2.2)
    mill.set_friction(mu_s=0.3, mu_d=0.2)
    mill.advance(steps=20_000)
    mill.reset()
    s = mill.state()
    assert s["time"] == 0 and np.array_equal(s["position"], x0)  # seeded placement
    assert (mill.plate_rpm, mill.ratio, mill.friction.mu_d) == pytest.approx((250, -2.2, 0.2))
    assert mill.drive(0.0)["plate"] == 0.0  # ramps up from rest again
    mill.rebuild(balls=14, jar="HM")
    assert mill.runner.engine is engine  # 14 balls fit the 16-ball padded rows
    assert mill.n_balls == 14 and mill.preset.jar.name == "HM" and mill.time == 0
    assert (mill.plate_rpm, mill.ratio, mill.friction.mu_s) == pytest.approx((250, -2.2, 0.3))
    mill.advance(steps=10_000)
    assert mill.state()["position"].shape == (14, 3)


def test_setter_gets_in_while_a_worker_advances(mill):
    """The UI thread's setter waits at most about one chunk for the lock."""
    stop = threading.Event()

    def work():
        while not stop.is_set():
            mill.advance(wall_budget=0.05)

    worker = threading.Thread(target=work)
    worker.start()
    try:
        time.sleep(0.2)
        waits = []
        for mu in (0.5, 0.6, 0.7, 0.8):
            t0 = time.perf_counter()
            mill.set_friction(mu_s=mu, mu_d=0.8 * mu)
            waits.append(time.perf_counter() - t0)
            time.sleep(0.05)
    finally:
        stop.set()
        worker.join()
    # chunks are 10 ms of wall time; 0.25 s allows for the other agents on this machine
    assert max(waits) < 0.25, waits
