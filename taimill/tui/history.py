"""Small history plots (sparklines) of the main window figures, one value per readout:
a caption with the latest value, the sparkline, and under it the range it spans (on a
line of its own: beside the caption it did not fit the 38 columns of the side panel)."""

from __future__ import annotations

import math

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import Label, Sparkline

from taimill.tui.readouts import number

# history key -> (label, unit, scale)
SERIES = {
    "impact_power": ("impact power", "W", 1),
    "mean_se": ("mean SE", "mJ", 1e3),
    "dissipated_power": ("dissipated power", "W", 1),
    "collision_rate": ("stress-event rate", "1/s", 1),
}


class History(Vertical):
    DEFAULT_CSS = """
    History { height: auto; }
    History Label { height: 1; width: 1fr; }
    History Sparkline { height: 1; }
    History Label { color: $text-muted; }
    History Label.range { text-style: italic; }
    """

    def compose(self) -> ComposeResult:
        self.labels = {k: Label(f"{label} ({unit})") for k, (label, unit, _) in SERIES.items()}
        self.lines = {k: Sparkline([]) for k in SERIES}
        self.ranges = {k: Label("", classes="range") for k in SERIES}
        for key in SERIES:
            yield self.labels[key]
            yield self.lines[key]
            yield self.ranges[key]

    def show(self, history: dict):
        for key, (label, unit, scale) in SERIES.items():
            data = [x * scale for x in history.get(key, []) if math.isfinite(x)]
            self.lines[key].data = data
            last = number(data[-1]) if data else "—"
            lo, hi = (number(min(data)), number(max(data))) if data else ("—", "—")
            self.labels[key].update(f"{label} {last} {unit}", layout=False)
            self.ranges[key].update(f"  {lo} … {hi} {unit}", layout=False)
