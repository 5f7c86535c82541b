"""`MillApp`: the live mill in the terminal.

The simulation runs in one thread worker (`simulate`, body in simloop.py) and reports
only through messages (frames, readouts, faults). Changes go the other way through the
LiveMill's locked setters, called from the UI thread; the LiveMill must have been built
(and its kernels compiled) in the main thread before the app starts.

Faults: a file that cannot be written (a recording on a full disk, a PNG) is said in
the message bar, its recording ended, and the app goes on; an error nothing handles
ends the app (recordings closed first). SIGTERM closes the recordings and quits. Each
leaves its cause in `fault`, from which `taimill tui` prints one line and takes its
exit code once the terminal is restored: the app never ends with 0 after an error.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import math
import signal
import time
from pathlib import Path

from textual import work
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import Footer, Header, Static
from textual.worker import WorkerFailed, get_current_worker

from taimill.errors import ConfigError, Interrupted
from taimill.model.preset import KINDS
from taimill.figures.snapshot import save_png
from taimill.tui.controls import Controls
from taimill.tui.help import HelpScreen
from taimill.tui.history import SERIES, History
from taimill.tui.jarview import JarView
from taimill.tui.messages import (FrameReady, FrictionRequested, Notice, ReadoutsReady, RebuildRequested, SimFault,
                                  SpeedsRequested, WriteFailed)
from taimill.tui.readouts import Readouts, text_lines, title
from taimill.tui.recorders import Recorders
from taimill.tui.simloop import SimulationLoop

TEXT_PERIOD = 0.25  # wall s between updates of the time and speed texts
HINT = "Tab moves between fields · Enter applies a field and leaves it · letter keys act outside fields · ? help"


class MillApp(App):
    TITLE = "taimill"
    AUTO_FOCUS = None  # nothing focused at start: the letter keys work at once
    CSS = """
    #main { height: 1fr; }
    #views { width: 1fr; }
    #views .caption { height: 1; color: $text-muted; }
    #top { height: 2fr; }
    #section { height: 1fr; }
    #side { width: 40; padding: 0 1; }
    #message { height: 1; padding: 0 1; }
    #message.error { color: $error; text-style: bold; }
    #status { height: 1; padding: 0 1; background: $boost; }
    """
    BINDINGS = [
        Binding("p,space", "pause", "pause/resume"),
        Binding("s", "step", "step"),
        Binding("r", "reset", "reset"),
        Binding("o", "record('rrd')", "rec .rrd"),
        Binding("z", "record('zarr')", "rec zarr"),
        Binding("g", "snapshot", "PNG"),
        Binding("question_mark,f1", "help", "help"),
        Binding("escape", "leave_field", "leave field", show=False),
        Binding("q", "quit", "quit"),
    ]

    def __init__(self, mill, *, out_dir: Path | str = ".", window: float = 4.0, paused: bool = False):
        super().__init__()
        self.mill = mill
        self.out_dir = Path(out_dir)
        self.window_seconds = window
        self.loop = SimulationLoop(mill, window, paused)
        self.recorders = Recorders(self.out_dir, on_fault=lambda kind, err: self.post_message(WriteFailed(err, kind)))
        self.fault: BaseException | None = None  #: the first error of the session (module doc)
        self.last_frame: FrameReady | None = None
        self.last_values: dict = {}
        self.fps = math.nan  # frames drawn per wall s, measured
        self._texts_at = 0.0

    # ------------------------------------------------------------------ layout
    def compose(self) -> ComposeResult:
        # kept as attributes: the help screen may be on top when a frame arrives
        self.controls = Controls(self.settings(), id="controls")
        self.top_view, self.section_view = JarView("top", id="top"), JarView("section", id="section")
        self.readouts, self.history_plots = Readouts(self.window_seconds, id="readouts"), History(id="history")
        self.message_bar = Static(HINT, id="message", markup=False)
        self.status_bar = Static("", id="status", markup=False)
        yield Header()
        with Horizontal(id="main"):
            yield self.controls
            with Vertical(id="views"):
                yield Static("from above · red: away from plate axis", classes="caption")
                yield self.top_view
                yield Static("section x-z", classes="caption")
                yield self.section_view
            with Vertical(id="side"):
                yield self.readouts
                yield self.history_plots
        yield self.message_bar
        yield self.status_bar
        yield Footer()

    def on_mount(self):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):  # not the main thread, not Unix
            asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, self._terminated)
        self.sub_title = title(self.mill.preset)  # the preset file and the mill's name
        self._set_jar()
        self._show_now()
        self.set_interval(1.0, self._measure_fps)
        self.loop.stopped.clear()  # here, not in the thread: on_unmount may come first
        self.simulate()
        self._import_recorders()

    @work(thread=True, group="files")
    def _import_recorders(self):
        """Import rerun and zarr now (≈ 1 s): a recording then opens in ≈ 0.15 s, which
        the mill waits for (LiveMill.add_sink)."""
        importlib.import_module("taimill.recording.sink")
        importlib.import_module("taimill.store.writer")

    def settings(self) -> dict:
        """The mill's current settings, as the controls show them."""
        m = self.mill
        return {"plate_rpm": m.plate_rpm, "ratio": m.ratio, "jar_rpm": m.jar_rpm, "ramp_time": m.target.ramp_time,
                "mu_s": m.friction.mu_s, "mu_d": m.friction.mu_d, "mu_r": m.friction.mu_r, "balls": m.n_balls,
                "pair": m.preset.pair, "jar": m.preset.jar.name, "limits": {"plate_rpm": m.preset.mill.plate_range.live_bounds},
                "kinds": {k: {"mu_s": f.mu_s, "mu_d": f.mu_d, "mu_r": f.mu_r} for k, f in zip(KINDS, m.frictions)}}

    def _set_jar(self):
        p = self.mill.preset
        for view in (self.top_view, self.section_view):
            view.set_jar(p.jar.profile.outline, p.jar.height, self.mill.radius)
        # the readout window is (re)started before this with the mill's config and radii
        self.readouts.set_targets({"ratio": self.mill.ratio, "critical_ratio": self.loop.window.geom.critical_ratio})

    # ------------------------------------------------------------------ the worker
    @work(thread=True, exclusive=True, group="simulation")
    def simulate(self):
        worker = get_current_worker()
        self.loop.run(self.post_message, lambda: worker.is_cancelled)

    def _show_now(self):
        """Draw the current state at once (start, reset, changes while paused)."""
        self.on_frame_ready(self.loop.frame())
        self.on_readouts_ready(self.loop.readouts())

    # ------------------------------------------------------------------ from the worker
    def on_frame_ready(self, msg: FrameReady):
        self.last_frame = msg
        self.top_view.show(msg.position, msg.psi)
        self.section_view.show(msg.position)
        now = time.perf_counter()
        if self.loop.paused or now - self._texts_at >= TEXT_PERIOD:  # text is dearer to draw than braille
            self._texts_at = now
            self.readouts.set_frame(msg, self.loop.paused)
            self._status()

    def on_readouts_ready(self, msg: ReadoutsReady):
        self.last_values = msg.values
        self.readouts.set_values(msg.values)
        self.history_plots.show(msg.history)

    def on_sim_fault(self, msg: SimFault):
        self._message(f"simulation stopped: {msg.text} — press r to reset", error=True)
        self._status()

    def on_notice(self, msg: Notice):
        self._message(msg.text, msg.error)
        self._status()

    def on_write_failed(self, msg: WriteFailed):
        """A recording or PNG could not be written: say so, end the recording, go on."""
        self.fault = self.fault or msg.error
        ended = ""
        if msg.kind is not None:
            try:
                path = self.recorders.stop(msg.kind, self.mill, f"failed: {msg.error}")
            except (OSError, ConfigError):
                path = None
            ended = f"; {msg.kind} recording ended" + (f": {path}" if path else "")
        self._message(f"write failed: {msg.error}{ended}", error=True)
        self._status()

    # ------------------------------------------------------------------ ends
    def _handle_exception(self, error: Exception) -> None:
        """Textual's hook for an exception nothing handled (in a handler or a worker):
        keep it as the fault, close the recordings and leave; `taimill tui` prints it
        as one line (TAIMILL_DEBUG=1: its traceback first)."""
        if isinstance(error, WorkerFailed):
            error = error.error
        self.fault = self.fault or error
        self._close_recordings("failed: error")
        self.exit(return_code=1)

    def _terminated(self):
        """SIGTERM: close the recordings and quit (Textual restores the terminal); a
        second SIGTERM kills at once."""
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            asyncio.get_running_loop().remove_signal_handler(signal.SIGTERM)
        closed = self._close_recordings("stopped: terminated")
        self.fault = self.fault or Interrupted("terminated (SIGTERM)" + (f"; recordings closed: {', '.join(map(str, closed))}"
                                                                       if closed else ""), 128 + signal.SIGTERM)
        self.exit(return_code=128 + signal.SIGTERM)

    def _close_recordings(self, status: str) -> list[Path]:
        try:
            return self.recorders.stop_all(self.mill, status)
        except Exception:  # noqa: BLE001 (leaving anyway: the first fault is what is reported)
            return []

    def _message(self, text: str, error: bool = False):
        bar = self.message_bar
        bar.update(text, layout=False)
        bar.set_class(error, "error")

    def _measure_fps(self):
        drawn = self.top_view.drawn
        previous, self._drawn = getattr(self, "_drawn", drawn), drawn
        self.fps = drawn - previous
        self._status()

    def _status(self):
        t = self.mill.time
        if self.loop.paused:
            state = f"❚❚ paused   t = {t:.3f} s"
        else:
            rt = self.last_frame.realtime if self.last_frame else math.nan
            rate = f"{rt:.2f}×" if math.isfinite(rt) else "—"
            fps = f"{self.fps:.0f}" if math.isfinite(self.fps) else "—"
            state = f"▶ running   t = {t:.3f} s   {rate} real time   view {fps} frames/s"
        rec = "   ".join(f"● REC {k} {r.path.name}" for k, r in self.recorders.active.items())
        self.status_bar.update(f"{state}   {rec}", layout=False)

    # ------------------------------------------------------------------ from the controls
    def _apply(self, change, describe):
        """Run a LiveMill setter; a refusal (ConfigError) becomes the message and
        nothing changes. The controls then show what the mill really runs."""
        try:
            change()
        except ConfigError as err:
            self._message(f"refused: {err}", error=True)
        else:
            self._message(describe())
        self.controls.show(self.settings())
        self.readouts.set_targets({**self.readouts.targets, "ratio": self.mill.ratio})
        if self.loop.paused:
            self._show_now()

    def on_speeds_requested(self, msg: SpeedsRequested):
        m = self.mill
        self._apply(lambda: m.set_speeds(msg.plate_rpm, ratio=msg.ratio, jar_rpm=msg.jar_rpm, ramp_time=msg.ramp_time),
                    lambda: (f"ramping from t = {m.plate.t0:.3f} s over {m.plate.duration:g} s to Ω = {m.plate_rpm:g} rpm, "
                             f"K = {m.ratio:.4g} (ω = {m.jar_rpm:.4g} rpm); dt = {m.dt * 1e6:.3g} µs"))

    def on_friction_requested(self, msg: FrictionRequested):
        m = self.mill
        which = {None: "", "ball_ball": " of ball-ball contacts", "ball_wall": " of ball-wall contacts"}[msg.kind]
        fr = lambda: m.frictions[1] if msg.kind == "ball_wall" else m.friction  # noqa: E731 (read after the change)
        self._apply(lambda: m.set_friction(msg.mu_s, msg.mu_d, pair=msg.pair, mu_r=msg.mu_r, kind=msg.kind),
                    lambda: (f"friction{which} from t = {m.time:.3f} s: {fr().name}, μ_s = {fr().mu_s:g}, "
                             f"μ_d = {fr().mu_d:g}, μ_r = {fr().mu_r:g}"))

    def on_rebuild_requested(self, msg: RebuildRequested):
        self._message("rebuilding the mill … (more balls than the compiled kernels hold: ≈ 10 s to compile new ones)")
        self.call_after_refresh(self._rebuild, msg.jar, msg.balls)

    def _rebuild(self, jar, balls):
        """In the UI (main) thread: more balls than the engine holds means new fields.
        Recordings end first (their ball count and time base would change)."""
        m, closed = self.mill, []

        def change():
            new = m.rebuilt(jar=jar, balls=balls)
            closed.extend(self.recorders.stop_all(m, "stopped: new jar or ball count"))
            m.restart(new)
            self.loop.new_window()
            self._set_jar()

        self._apply(change, lambda: f"restarted at t = 0: {m.preset.jar.name} jar, {m.n_balls} balls"
                    + (f"; recordings closed: {', '.join(map(str, closed))}" if closed else "")
                    + "".join(f"; {w}" for w in m.preset.warnings if w.startswith("contact set derived")))
        self._show_now()

    # ------------------------------------------------------------------ keys
    def action_pause(self):
        self.loop.paused = not self.loop.paused
        self._status()
        self.readouts.set_frame(self.last_frame, self.loop.paused)

    def action_step(self):
        self.loop.paused = True
        self.loop.steps.append(1)
        self._status()

    def action_reset(self):
        stopped = self.recorders.stop_all(self.mill, "stopped: reset")
        self.mill.reset()
        self.loop.new_window()
        self._show_now()
        self._message("reset to t = 0" + (f"; recordings closed: {', '.join(map(str, stopped))}" if stopped else ""))

    def action_record(self, kind: str):
        self._toggle_recording(kind)

    @work(thread=True, group="files")
    def _toggle_recording(self, kind: str):
        """Opening a recording imports rerun / zarr and writes its header: ≈ 1 s the
        first time, so not in the UI thread."""
        try:
            self.post_message(Notice(self.recorders.toggle(kind, self.mill)))
        except ImportError as err:
            self.post_message(Notice(f"cannot record {kind}: {err}", error=True))
        except (OSError, ValueError) as err:  # StoreWriteError: a ConfigError, a ValueError
            self.post_message(WriteFailed(err))

    def action_snapshot(self):
        """Draw the PNG in a worker (≈ 1-8 s: matplotlib); say so at once, then the path."""
        f = self.last_frame or self.loop.frame()
        p = self.mill.preset
        path = self.out_dir / f"taimill-t{f.sim_time:.3f}s-{time.strftime('%Y%m%d-%H%M%S')}.png"
        heading = (f"{title(p)}: {p.jar.name} jar, {self.mill.n_balls} balls, {p.pair} μ_s {p.friction.mu_s:g} "
                 f"μ_d {p.friction.mu_d:g}, Ω = {self.mill.plate_rpm:g} rpm, K = {self.mill.ratio:.4g}")
        history = {k: list(h) for k, h in self.loop.history.items()}
        self._message(f"writing PNG {path} …")
        self._save_png(path, dict(title=heading, outline=p.jar.profile.outline, height=p.jar.height, position=f.position,
                                  radius=self.mill.radius, psi=f.psi, history=history, series=SERIES,
                                  readouts=text_lines(dict(self.last_values)),
                                  time=f.sim_time, window=self.window_seconds))

    @work(thread=True, group="files")
    def _save_png(self, path: Path, figure: dict):
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            save_png(path, **figure)
        except (OSError, ConfigError) as err:  # whole_file: StoreWriteError
            self.post_message(WriteFailed(err))
            return
        self.post_message(Notice(f"figures saved to {path}"))

    def action_help(self):
        self.push_screen(HelpScreen())

    def action_leave_field(self):
        """Leave the field; text typed but not applied goes back to what the mill runs."""
        self.set_focus(None)
        self.controls.show(self.settings())

    def action_focus_previous(self):
        """Shift+Tab from outside the fields enters them at the first one, as Tab does
        (not at the last, the jar list, whose change restarts the mill)."""
        if self.focused is None and self.screen is self.screen_stack[0]:
            self.controls.query_one("Input").focus()
        else:
            super().action_focus_previous()

    def action_quit(self):
        """Close recordings properly, then leave (on_unmount stops the worker)."""
        self.recorders.stop_all(self.mill, "stopped: quit")
        self.exit()

    async def on_unmount(self):
        """However the app ends, the worker leaves the mill between two launches first
        (a kernel must not run on while the interpreter shuts down)."""
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            asyncio.get_running_loop().remove_signal_handler(signal.SIGTERM)
        self.workers.cancel_group(self, "simulation")
        await asyncio.to_thread(self.loop.stopped.wait, 5.0)
