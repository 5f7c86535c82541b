"""The control panel: plate speed Ω, jar speed as K or ω (the other one shown), ramp
time, friction (μ_s, μ_d, rolling resistance μ_r or a material pair) of both contact
kinds or of ball-ball or ball-wall contacts alone, jar and ball count.

A field takes effect on Enter, which also leaves it (so letter keys act again); Tab and
Shift+Tab move between fields, as the panel's hint says. It only parses the number:
the ranges live in `taimill.runs.live.LIMITS` (the plate speed's: the mill's, given as
`limits` with the settings), checked by the LiveMill (ConfigError naming the field and
its range); the input's red border while typing uses the same limits. When Ω changes, the jar speed last entered (K or ω) is the one held. μ_s and
μ_d are applied as a pair (Enter in either sends both fields as typed), so a lower μ_s
with a lower μ_d is one change, not one refused for μ_d > μ_s. The `contact` choice
says which contacts the friction fields and the pair apply to; the fields show that
kind's values ("both" shows ball-ball's).

Which field has focus and which speed is held are shown without colour, so that a
monochrome terminal shows them too: the focused field's row is marked FOCUS_MARK in a
gutter left of its label; the held speed's label is bold and underlined, and a line
under the speed fields names it.
"""

from __future__ import annotations

import math
from pathlib import Path

from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.validation import Integer, Number
from textual.widgets import Input, Label, Select, Static
from textual.widgets.input import Selection

from taimill.model.materials import pairs_sharing
from taimill.model.jars import jar_names
from taimill.runs.live import LIMITS
from taimill.tui.messages import FrictionRequested, Notice, RebuildRequested, SpeedsRequested

# input id -> (label, key of LIMITS)
FIELDS = {
    "plate-rpm": ("Ω plate rpm", "plate_rpm"),
    "ratio": ("K = ω/Ω + 1", "ratio"),
    "jar-rpm": ("ω jar rpm", "jar_rpm"),
    "ramp-time": ("ramp s", "ramp_time"),
    "mu-s": ("μ_s static", "mu_s"),
    "mu-d": ("μ_d dynamic", "mu_d"),
    "mu-r": ("μ_r rolling", "mu_r"),
    "balls": ("balls", "balls"),
}


def pair_options(pair: str) -> list[tuple[str, str]]:
    """(label, value) of the pair menu: the pairs the running mill may switch to, a pair
    file shown by its file name."""
    return [(Path(p).name if p.endswith(".toml") else p, p) for p in pairs_sharing(pair)]


def shown(key: str, value) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return ""
    return f"{value:d}" if isinstance(value, int) else f"{value:.5g}"


FOCUS_MARK = "▶"  #: in the gutter of the row whose field has focus
HELD = {"ratio": "K", "jar_rpm": "ω"}  #: the held speed as the line under the speed fields names it


def held_text(hold: str) -> str:
    """The line naming the speed kept when Ω changes."""
    return f"held: {HELD[hold]} (kept when Ω changes)"



class Field(Input):
    """A number field whose text is selected when a click gives it focus, as when Tab
    does: Input puts the cursor where the click lands, so the number typed next joined
    the one shown (200 → "300200", refused) and the first edit of a session was lost."""

    _focus_click = False  # focus just came; a mouse press now is the click that gave it

    def _on_focus(self, event):
        self._focus_click = True

    def _on_key(self, event):
        self._focus_click = False

    def _on_mouse_up(self, event):
        if self._focus_click and self.select_on_focus:
            self.selection = Selection(0, len(self.value))
        self._focus_click = False

class Controls(Vertical):
    DEFAULT_CSS = """
    Controls { width: 34; padding: 0 1; }
    Controls .row { height: 1; margin: 0 0 1 0; }
    Controls .row .mark { width: 2; }
    Controls .row Label { width: 12; }
    Controls .row Label.held { text-style: bold underline; color: $accent; }
    Controls #held { margin: 0 0 1 0; }
    Controls .row Input, Controls .row Select { width: 1fr; }
    Controls .title { text-style: bold; }
    Controls .hint { color: $text-muted; margin: 0 0 1 0; }
    """
    HINT = ("Tab / Shift+Tab: next / previous\n"
            "Enter: apply and leave the field\n"
            "Esc: leave, keep what runs\n"
            "μ_s and μ_d apply as a pair\n"
            "contact: which contacts μ applies to")
    KINDS = (("both", "both"), ("ball-ball", "ball_ball"), ("ball-wall", "ball_wall"))

    def __init__(self, values: dict, **kw):
        super().__init__(**kw)
        self.values = values
        self.hold = "ratio" if math.isfinite(values["ratio"]) else "jar_rpm"
        self.kind = "both"

    def _shown_values(self, values: dict) -> dict:
        """values with the friction of the chosen contact kind (both: ball-ball's)."""
        return values | values.get("kinds", {}).get("ball_ball" if self.kind == "both" else self.kind, {})

    def compose(self) -> ComposeResult:
        yield Static("Controls", classes="title")
        yield Static(self.HINT, id="hint", classes="hint", markup=False)
        values = self._shown_values(self.values)
        for fid, (label, key) in FIELDS.items():
            lo, hi = self.values.get("limits", {}).get(key) or LIMITS[key]
            check = Integer(lo, hi) if key == "balls" else Number(lo, hi)
            if fid == "mu-s":
                with Horizontal(classes="row"):
                    yield from self._gutter("kind")
                    yield Label("contact")
                    yield Select(self.KINDS, value=self.kind, allow_blank=False, id="kind", compact=True)
            with Horizontal(classes="row"):
                yield from self._gutter(fid)
                yield Label(label, id=f"label-{fid}")
                yield Field(shown(key, values[key]), id=fid, validators=[check], select_on_focus=True, compact=True)
            if fid == "jar-rpm":
                yield Static(held_text(self.hold), id="held", markup=False)
        with Horizontal(classes="row"):
            yield from self._gutter("pair")
            yield Label("pair")
            yield Select(pair_options(self.values["pair"]), value=self.values["pair"], allow_blank=False, id="pair", compact=True)
        with Horizontal(classes="row"):
            yield from self._gutter("jar")
            yield Label("jar")
            jars = dict.fromkeys([*jar_names(), self.values["jar"]])  # also a jar file or a mill's bowl in use
            yield Select([(j, j) for j in jars], value=self.values["jar"], allow_blank=False, id="jar", compact=True)

    @staticmethod
    def _gutter(fid: str):
        yield Static("", id=f"mark-{fid}", classes="mark", markup=False)

    def _mark_focus(self, widget, focused: bool):
        """FOCUS_MARK beside the row of `widget` (a field, or the list a Select opens)
        while it has focus."""
        while widget is not None and widget is not self and not widget.id:
            widget = widget.parent
        if widget is None or widget is self:
            return
        marks = self.query(f"#mark-{widget.id}")
        if marks:
            marks.first(Static).update(FOCUS_MARK if focused else "")

    def on_descendant_focus(self, event):
        self._mark_focus(event.widget, True)

    def on_descendant_blur(self, event):
        self._mark_focus(event.widget, False)

    def on_mount(self):
        self._mark_held()

    def show(self, values: dict):
        """Display the mill's current settings (after every change, accepted or not)."""
        self.values = values
        if self.hold == "ratio" and not math.isfinite(values["ratio"]):
            self.hold = "jar_rpm"
        shown_values = self._shown_values(values)
        for fid, (_, key) in FIELDS.items():
            self.query_one(f"#{fid}", Input).value = shown(key, shown_values[key])
        with self.prevent(Select.Changed):
            self.query_one("#pair", Select).value = values["pair"]
            self.query_one("#jar", Select).value = values["jar"]
        self._mark_held()

    def _mark_held(self):
        for fid, key in (("ratio", "ratio"), ("jar-rpm", "jar_rpm")):
            self.query_one(f"#label-{fid}", Label).set_class(self.hold == key, "held")
        self.query_one("#held", Static).update(held_text(self.hold))

    def on_input_submitted(self, event: Input.Submitted):
        """Apply the field (μ_s and μ_d together), then leave it."""
        event.stop()
        try:
            self._submit(event.input.id, event.value)
        finally:
            self.screen.set_focus(None)

    def _number(self, fid: str, text: str):
        """The field's number, or None after a refusal naming the field and its range."""
        label, key = FIELDS[fid]
        text = text.strip()
        try:
            return int(text) if key == "balls" else float(text)
        except ValueError:
            lo, hi = self.values.get("limits", {}).get(key) or LIMITS[key]
            self.post_message(Notice(f"refused {key} = {text!r} ({label}): not a number; allowed range [{lo:g}, {hi:g}]", error=True))
            self.show(self.values)
            return None

    def _submit(self, fid: str, text: str):
        key = FIELDS[fid][1]
        value = self._number(fid, text)
        if value is None:
            return
        v = self.values
        if key == "plate_rpm":
            held = {self.hold: v[self.hold]}
            self.post_message(SpeedsRequested(value, **held))
        elif key in ("ratio", "jar_rpm"):
            self.hold = key
            self.post_message(SpeedsRequested(v["plate_rpm"], **{key: value}))
        elif key == "ramp_time":
            self.post_message(SpeedsRequested(v["plate_rpm"], **{self.hold: v[self.hold]}, ramp_time=value))
        elif key in ("mu_s", "mu_d"):
            other = "mu-d" if key == "mu_s" else "mu-s"
            pair = self._number(other, self.query_one(f"#{other}", Input).value)
            if pair is not None:
                self.post_message(FrictionRequested(**{key: value, FIELDS[other][1]: pair}, kind=self._kind()))
        elif key == "mu_r":
            self.post_message(FrictionRequested(mu_r=value, kind=self._kind()))
        else:
            self.post_message(RebuildRequested(balls=value))

    def _kind(self) -> str | None:
        return None if self.kind == "both" else self.kind

    def on_select_changed(self, event: Select.Changed):
        event.stop()
        if event.select.id == "kind":
            self.kind = event.value
            self.show(self.values)
        elif event.select.id == "pair" and event.value != self.values["pair"]:
            self.post_message(FrictionRequested(pair=event.value, kind=self._kind()))
        elif event.select.id == "jar" and event.value != self.values["jar"]:
            self.post_message(RebuildRequested(jar=event.value))
