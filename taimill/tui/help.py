"""The help screen: every key and what the fields mean."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import Static

KEYS = (
    ("p / space", "pause or resume the simulation"),
    ("s", "step: advance one output frame (1/100 s by default) and pause"),
    ("r", "reset: back to t = 0, balls re-placed, speeds ramp up from rest"),
    ("o", "start / stop recording to a rerun file (.rrd, open it with `taimill view FILE`)"),
    ("z", "start / stop recording to a zarr store (read with taimill.store.run.open_run)"),
    ("g", "save the current figures (views, history, readouts) as a PNG"),
    ("? / f1", "this help"),
    ("tab", "next field (shift+tab: previous); Enter applies a field and leaves it"),
    ("escape", "leave a field without applying it, so that the letter keys act again"),
    ("q", "quit (recordings are closed properly)"),
)

FIELDS_TEXT = """\
Fields take effect on Enter; a value outside its range is refused with a message,
and the simulation keeps running with the old one. ▶ marks the field being edited.
  Ω          plate speed (rpm)
  K          ω/Ω + 1 (= w/Ω, the jar's absolute spin w over Ω); K < 0: counter-rotation
  ω          jar speed relative to the plate (rpm); entering K or ω shows the other,
             and the last one entered is held when Ω changes ("held:" under them)
  ramp       time (s) a speed change takes (smooth ramp, so the Euler terms stay right)
  μ_s, μ_d   static and dynamic friction (eq 3.7), μ_d ≤ μ_s, applied as a pair: Enter in
             either applies both as typed; or pick a material pair
  μ_r        rolling resistance: a torque μ_r R F_n against rolling (0: off)
  contact    which contacts the friction fields and the pair change: both kinds,
             ball-ball only (coated balls) or ball-wall only (a coated jar)
  jar, balls a new jar or ball count restarts the mill at t = 0
Readouts are over a sliding window of simulated time; K_c is the single-ball critical
ratio (docs/model.md). Views: jar frame, from above (red mark: direction away from the plate
axis) and in section x-z."""


class HelpScreen(ModalScreen):
    BINDINGS = [("escape,q,question_mark,f1", "dismiss", "close")]
    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > Vertical { width: 100; height: auto; border: thick $accent; padding: 1 2; background: $surface; }
    """

    def compose(self) -> ComposeResult:
        keys = "\n".join(f"  {k:<10} {what}" for k, what in KEYS)
        with Vertical():
            yield Static("[b]taimill tui — keys[/b]\n" + keys + "\n\n" + FIELDS_TEXT, markup=True)
