"""`taimill tui PRESET [overrides]`: the live terminal UI (taimill.tui)."""

from __future__ import annotations

import sys
from pathlib import Path


def register(subparsers):
    from taimill.cli.common import add_overrides as _add_overrides

    t = subparsers.add_parser("tui", help="live terminal UI: tune Ω, the jar speed and friction of a running mill")
    t.add_argument("preset", help="preset TOML file, e.g. presets/p4-cy-steel.toml")
    t.add_argument("--out-dir", default=".", help="folder for recordings (.rrd, .zarr) and PNG snapshots (default .)")
    t.add_argument("--window", type=float, default=4.0, help="sliding window of the readouts, simulated s (default 4)")
    t.add_argument("--paused", action="store_true", help="start paused")
    _add_overrides(t)
    t.set_defaults(fn=cmd_tui)


def cmd_tui(a) -> int:
    from taimill.cli.common import overrides as _overrides
    from taimill.errors import ConfigError
    from taimill.model.params import load_preset

    if not 0.1 <= a.window <= 600:
        raise ConfigError("command line", "--window", a.window, "allowed range [0.1, 600] s")
    out_dir = Path(a.out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ConfigError("command line", "--out-dir", a.out_dir, "must be a folder")
    overrides = _overrides(a)
    preset = load_preset(a.preset, overrides)
    print("taimill: compiling the kernels …", file=sys.stderr)
    from taimill.runs.live import LiveMill
    from taimill.tui.app import MillApp

    mill = LiveMill(preset, overrides)  # main thread: ti.init, fields, first kernel call
    MillApp(mill, out_dir=out_dir, window=a.window, paused=a.paused).run()
    return 0
