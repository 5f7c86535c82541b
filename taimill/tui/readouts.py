"""Live figures: simulated time and speed, the drive now, and the sliding-window
summary (stress events: impact power normal/tangential, mean SE, rate; dissipated
power and its persistent part, energy-balance error, regime and its regime-map class
with the critical ratio K_c; docs/outputs.md); the mill's name for the header."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from textual.widgets import Static

from taimill.schema import SUMMARY_ROWS
from taimill.model.drive import RPM

# (summary key, label, unit, scale): the run summary's figures that fit the panel, with
# short labels; units and scales are those `taimill run` prints (taimill.schema.SUMMARY_ROWS)
_UNITS = {key: (unit, scale) for key, _, unit, scale in SUMMARY_ROWS}
ROWS = tuple((key, label, *_UNITS[key]) for key, label in (
    ("impact_power", "impact power"),
    ("impact_power_normal", "  normal"),
    ("impact_power_tangential", "  tangential"),
    ("mean_se", "mean SE"),
    ("collision_rate", "stress events"),
    ("dissipated_power", "dissipated power"),
    ("dissipated_power_persistent", "  persistent"),
    ("energy_balance_error", "energy balance err"),
))


def mill_name(preset) -> str | None:
    """The name of the mill the preset's jar turns on (its resolved config's `mill`
    table), None when it names none."""
    mill = preset.as_dict().get("mill")
    name = mill.get("name") if isinstance(mill, dict) else None
    return str(name) if name else None


def title(preset) -> str:
    """The header's subtitle: the preset file, and the mill's name when it names one."""
    name, mill = Path(preset.source).name, mill_name(preset)
    return f"{name} · {mill}" if mill else name


def number(value, scale=1.0) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return f"{value * scale:.4g}"


def text_lines(values: dict) -> list[str]:
    """The readouts as plain text lines (for the PNG snapshot)."""
    lines = [f"{label.strip():<22} {number(values.get(key), scale):>10} {unit}" for key, label, unit, scale in ROWS]
    return lines + [f"{'regime':<22} {values.get('regime', '—'):>10}",
                    f"{'  class (regime map)':<22} {values.get('regime_class', '—'):>10}"]


class Readouts(Static):
    DEFAULT_CSS = """
    Readouts { height: 17; }
    """

    def __init__(self, window: float, **kw):
        super().__init__(markup=False, **kw)
        self.window = window
        self.frame = None
        self.values: dict = {}
        self.targets: dict = {}
        self.paused = False

    def on_mount(self):
        self._redraw()

    def set_frame(self, frame, paused: bool):
        self.frame, self.paused = frame, paused
        self._redraw()

    def set_values(self, values: dict | None):
        self.values = values or {}
        self._redraw()

    def set_targets(self, targets: dict):
        """plate_rpm, ratio, jar_rpm targets and the critical ratio."""
        self.targets = targets
        self._redraw()

    def _redraw(self):
        """Fixed-width lines, updated without a layout pass (this runs 20 times a second)."""
        rows = []
        f, v, g = self.frame, self.values, self.targets
        rows.append(("sim time", "—" if f is None else f"{f.sim_time:.3f}", "s"))
        if self.paused:
            speed = ("paused", "")
        else:
            speed = (f"{f.realtime:.2f}", "×") if f is not None and math.isfinite(f.realtime) else ("—", "")
        rows.append(("sim / real time", *speed))
        rows.append(("Ω now", "—" if f is None else f"{f.plate / RPM:.1f}", "rpm"))
        rows.append(("w = KΩ now", "—" if f is None else f"{f.jar / RPM:.1f}", "rpm"))
        rows.append(("K target", number(g.get("ratio")), ""))
        rows.append(("K_c single ball", f"{g['critical_ratio']:.3g}" if g else "—", ""))
        span = np.diff(v.get("analysis_window", [0.0, 0.0]))[0]
        part = f" ({span:.2g} s so far)" if 0 < span < 0.99 * self.window else ""
        rows.append((f"— last {self.window:g} s{part} —", "", ""))
        for key, label, unit, scale in ROWS:
            rows.append((label, number(v.get(key), scale), unit))
        rows.append(("regime", str(v.get("regime", "—")), ""))
        rows.append(("  class", str(v.get("regime_class", "—")), ""))  # the regime map's five classes
        self.update("\n".join(f"{a:<18} {b:>11} {c}" for a, b, c in rows), layout=False)
