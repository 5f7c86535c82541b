"""The Textual app driven by Pilot: fields change the running LiveMill (speeds ramp),
bad values are refused with a message and change nothing, pause/resume, recordings to
.rrd and zarr appear and read back, quit; snapshots of the main and help screens."""

import subprocess
import sys
import threading

import numpy as np
import pytest
import rerun as rr
from helpers import numbers_without_unit

from taimill.analysis.run import analyse
from taimill.recording import scene
from taimill.model.drive import RPM
from taimill.model.files import ROOT
from taimill.model.preset import load_preset
from taimill.runs.live import LiveMill
from taimill.store.run import open_run
from taimill.tui import app as app_module
from taimill.tui.app import MillApp
from taimill.tui.help import FIELDS_TEXT, KEYS

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
        assert mill.plate.duration == 1.0 and tuple(mill.F.model.plate_ramp[0]) == pytest.approx(mill.plate.as_tuple())
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


async def test_a_click_into_a_field_selects_it_so_the_first_edit_counts(mill, tmp_path):
    """A click put the cursor where it landed, so "300" typed into a field showing 200
    became "300200" and was refused: the user's first edit was lost. The click that
    gives a field focus selects its text, as Tab does; a second click places the cursor."""
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.click("#plate-rpm")
        await pilot.press(*"300", "enter")
        await pilot.pause()
        assert mill.plate_rpm == pytest.approx(300) and value(app, "plate-rpm") == "300", (message(app), value(app, "plate-rpm"), app.focused)
        await pilot.click("#ratio")
        await pilot.click("#ratio", offset=(0, 0))  # in the field now: the cursor goes to its start
        await pilot.press("-", "enter")
        await pilot.pause()
        assert "refused" in message(app) and mill.ratio == pytest.approx(-2.6)  # "--2.6": not a number


async def test_friction_fields_and_pair(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await enter(pilot, "mu-d", "0.2")
        await enter(pilot, "mu-s", "0.3")
        assert (mill.friction.mu_s, mill.friction.mu_d) == (0.3, 0.2)
        assert (mill.F.model.mu_s[0, 0], mill.F.model.mu_d[0, 0]) == (0.3, 0.2)  # the kernel's data
        app.query_one("#pair").value = "steel-graphite"
        await pilot.pause()
        assert (mill.F.model.mu_s[0, 0], mill.F.model.mu_d[0, 0]) == (0.1, 0.08) and value(app, "mu-s") == "0.1"
        assert "steel-graphite" in message(app)


async def test_a_preset_with_a_pair_file_offers_it_beside_the_pairs_of_its_contact_set(tmp_path):
    # the menu once looked the running pair up among the built-in ones: a pair file (its
    # path) ended the TUI with a KeyError before its screen opened
    (tmp_path / "my-pair.toml").write_text('[pair.my-steel]\ncontact = "steel"\nmu_s = 0.5\nmu_d = 0.4\n'
                                           'v_s_mm_s = 1\nv_d_mm_s = 10\n')
    preset = tmp_path / "p.toml"
    preset.write_text(P4.read_text().replace('pair = "steel-steel"', 'pair = "my-pair.toml"'))
    mill = LiveMill(load_preset(preset))
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        menu = app.query_one("#pair")
        mine = str(tmp_path / "my-pair.toml")
        assert menu.value == mine and menu._options[0] == ("my-pair.toml", mine)
        assert {"steel-steel", "steel-graphite", "dry-ceramic-powder"} <= {v for _, v in menu._options}
        assert "zirconia-zirconia" not in {v for _, v in menu._options}  # another contact set
        assert (mill.F.model.mu_s[0, 0], mill.F.model.mu_d[0, 0]) == (0.5, 0.4)
        menu.value = "steel-graphite"
        await pilot.pause()
        assert (mill.F.model.mu_s[0, 0], mill.F.model.mu_d[0, 0]) == (0.1, 0.08)


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
        app.query_one("#jar").value = "EFV45"  # zirconia walls: steel balls on them get a derived contact set
        await wait_until(pilot, lambda: mill.preset.jar.name == "EFV45", timeout=120)
        assert "contact set derived for steel-c1020 balls" in message(app) and "zirconia walls" in message(app)
        await pilot.press("g")
        await wait_until(pilot, lambda: list(tmp_path.glob("*.png")))
        await wait_until(pilot, lambda: "figures saved" in message(app))
    png, = tmp_path.glob("*.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


async def test_unstable_run_stops_with_a_message_and_reset_recovers(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path)
    async with app.run_test(size=SIZE) as pilot:
        mill.F.state.bad_ball[0], mill.F.state.status[0] = 3, 2  # as the kernel flags a ball through the wall
        await wait_until(pilot, lambda: "simulation stopped" in message(app))
        assert "ball 3 left the jar through a wall" in message(app) and app.loop.paused
        await pilot.press("r", "p")
        await wait_until(pilot, lambda: mill.time > 0.01)
        assert not app.loop.paused


async def test_tab_hint_is_visible_and_shift_tab_enters_the_fields_at_the_first(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        hint = app.query_one("#hint")
        assert "Tab / Shift+Tab: next / previous" in str(hint.render())
        assert hint.region.height >= 4 and app.screen.region.contains_region(hint.region)  # on screen
        assert "Tab moves between fields" in message(app)
        await pilot.press("shift+tab")
        assert app.focused.id == "plate-rpm"  # not the jar list at the end of the chain
        await pilot.press("shift+tab")
        assert app.focused.id == "jar"  # from the first field it goes round, as Tab does the other way
        await pilot.press("escape", "tab")
        assert app.focused.id == "plate-rpm"
        await pilot.press("tab")
        assert app.focused.id == "ratio"


async def test_enter_applies_and_leaves_the_field_escape_drops_what_was_typed(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await enter(pilot, "plate-rpm", "250")
        assert mill.plate_rpm == 250 and app.focused is None
        await pilot.press("p")  # a letter acts again instead of typing into the field
        assert value(app, "plate-rpm") == "250" and not app.loop.paused
        await pilot.press("p")
        app.query_one("#ramp-time").focus()
        await pilot.pause()
        await pilot.press("5", "escape")
        assert app.focused is None and value(app, "ramp-time") == "1" and mill.target.ramp_time == 1


async def test_mu_s_and_mu_d_are_applied_as_a_pair(mill, tmp_path):
    # from the preset's (1, 0.8): μ_s = 0.3 alone would put μ_d above μ_s
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await enter(pilot, "mu-s", "0.3")
        assert "mu_d = 0.8: dynamic friction must not exceed static mu_s = 0.3" in message(app)
        assert (mill.friction.mu_s, mill.friction.mu_d) == (1, 0.8) and value(app, "mu-s") == "1"
        app.query_one("#mu-s").focus()
        await pilot.pause()
        await pilot.press("0", ".", "3", "tab", "0", ".", "2", "enter")  # typed in both, one Enter
        await pilot.pause()
        assert (mill.friction.mu_s, mill.friction.mu_d) == (0.3, 0.2) and (mill.F.model.mu_s[0, 0], mill.F.model.mu_d[0, 0]) == (0.3, 0.2)
        assert "μ_s = 0.3, μ_d = 0.2" in message(app)
        app.query_one("#mu-d").focus()
        await pilot.pause()
        await pilot.press("0", ".", "5", "shift+tab", "0", ".", "6", "enter")  # both raised, Enter in μ_s
        await pilot.pause()
        assert (mill.friction.mu_s, mill.friction.mu_d) == (0.6, 0.5)
        assert [(c["mu_s"], c["mu_d"]) for c in mill.changes] == [(0.3, 0.2), (0.6, 0.5)]  # one change each


async def test_k_label_help_and_readme_define_k_alike(mill, tmp_path):
    readme = (ROOT / "README.md").read_text()
    assert "K = ω/Ω + 1" in readme and "taimill view" in readme
    help_text = FIELDS_TEXT + "".join(what for _, what in KEYS)
    assert "ω/Ω + 1" in help_text and "taimill view FILE" in help_text and "`rerun FILE`" not in help_text
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE):
        assert str(app.query_one("#label-ratio").render()) == "K = ω/Ω + 1"


def marks(app) -> dict:
    """The focus gutter of every control row that shows a mark."""
    return {w.id.removeprefix("mark-"): str(w.render()) for w in app.query(".mark") if str(w.render()).strip()}


async def test_focus_is_marked_without_colour_and_the_held_speed_otherwise(mill, tmp_path):
    # a monochrome terminal shows both: focus as ▶ beside the field's label, the held
    # speed by name under the speed fields and as a bold, underlined label (not ▶)
    from taimill.tui.controls import FOCUS_MARK

    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        assert marks(app) == {}
        await pilot.press("tab")
        assert app.focused.id == "plate-rpm" and marks(app) == {"plate-rpm": FOCUS_MARK}
        await pilot.press("tab")
        assert marks(app) == {"ratio": FOCUS_MARK}
        for _ in range(3):  # ω, ramp, then the contact list
            await pilot.press("tab")
        assert app.focused.id == "kind" and marks(app) == {"kind": FOCUS_MARK}
        await pilot.press("escape")
        await pilot.pause()
        assert app.focused is None and marks(app) == {}
        held = app.query_one("#held")
        assert str(held.render()) == "held: K (kept when Ω changes)"
        label = app.query_one("#label-ratio")
        assert label.has_class("held") and label.rich_style.underline and label.rich_style.bold
        assert not app.query_one("#label-jar-rpm").rich_style.underline
        await enter(pilot, "jar-rpm", "-500")  # the jar speed entered as ω: ω is held now
        assert str(held.render()) == "held: ω (kept when Ω changes)" and marks(app) == {}
        assert app.query_one("#label-jar-rpm").rich_style.underline and not label.rich_style.underline


async def test_side_panel_fits_120_columns(mill, tmp_path):
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        lines = str(app.readouts.render()).splitlines()
        assert lines[-2].startswith("regime") and lines[-1].startswith("  class")  # the regime-map class under it
        assert len(lines) <= app.readouts.size.height  # no row cut off
        assert max(map(len, lines)) <= app.readouts.size.width
        # long numbers in the history captions: the range gets fewer digits, never cut
        app.history_plots.show({"impact_power": [0.1189, 15.05], "mean_se": [3.396e-4, 4.452e-3],
                                "dissipated_power": [0.0171234, 4.06912], "collision_rate": [350.0, 3388.0]})
        await pilot.pause()
        h = app.history_plots
        for key in h.labels:
            caption, span = str(h.labels[key].render()), str(h.ranges[key].render())
            assert len(caption) <= h.labels[key].size.width and len(span) <= h.ranges[key].size.width
        assert str(h.labels["dissipated_power"].render()) == "dissipated power 4.069 W"
        assert str(h.ranges["dissipated_power"].render()).split() == ["0.01712", "…", "4.069", "W"]
        assert app.screen.region.contains_region(h.ranges["collision_rate"].region)  # the last line on screen


async def test_png_key_says_at_once_that_it_writes(mill, tmp_path, monkeypatch):
    gate = threading.Event()
    real = app_module.save_png

    def slow(path, **figure):  # as matplotlib on a busy machine
        gate.wait(30)
        real(path, **figure)

    monkeypatch.setattr(app_module, "save_png", slow)
    app = MillApp(mill, out_dir=tmp_path, paused=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("g")
        assert message(app).startswith("writing PNG") and str(tmp_path) in message(app)
        gate.set()
        await wait_until(pilot, lambda: "figures saved" in message(app))
        png, = tmp_path.glob("*.png")
        assert str(png) in message(app)


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


def test_pacing_gives_the_simulation_the_rest_of_each_frame_interval():
    # a cycle = the stretch of simulation + a drawing/readout overhead: the pacing finds
    # the stretch whose cycle is 1/FRAMES_PER_S, whatever the overhead
    from taimill.tui.simloop import FIRST_STRETCH, FRAMES_PER_S, STRETCH_BOUNDS, pace

    for overhead in (0.010, 0.017, 0.030):
        stretch, mean = FIRST_STRETCH, None
        for _ in range(200):
            stretch, mean = pace(stretch, stretch + overhead, mean)
        assert stretch + overhead == pytest.approx(1.0 / FRAMES_PER_S, rel=1e-3)
    # one slow readout cycle (+60 ms) moves the next stretch by less than 2 ms
    steady = 1.0 / FRAMES_PER_S - 0.017
    nxt, _ = pace(steady, steady + 0.017 + 0.060, 1.0 / FRAMES_PER_S)
    assert abs(nxt - steady) < 0.002
    # bounds: a huge overhead cannot starve the simulation, nor a tiny one stall frames
    assert pace(0.03, 1.0, 1.0)[0] == STRETCH_BOUNDS[0]
    assert pace(0.19, 0.0, 0.0)[0] == STRETCH_BOUNDS[1]
    assert pace(0.05, None, None) == (0.05, None)  # nothing measured yet: unchanged


def test_the_header_names_the_mill_when_the_preset_has_one():
    from types import SimpleNamespace

    from taimill.tui.readouts import mill_name, title

    def preset(config):
        return SimpleNamespace(source="presets/p4-cy-steel.toml", as_dict=lambda: config)

    assert title(preset({"mill": {"name": "Pulverisette 4", "stations": 2}})) == "p4-cy-steel.toml · Pulverisette 4"
    assert title(preset({})) == "p4-cy-steel.toml" and mill_name(preset({"mill": {"stations": 2}})) is None
