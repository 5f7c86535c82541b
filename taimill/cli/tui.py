"""`taimill tui PRESET [overrides]`: the live terminal UI (taimill.tui)."""

from __future__ import annotations

import sys


def register(subparsers):
    from taimill.cli.common import PRESET_HELP, add_overrides as _add_overrides, number, path_text

    t = subparsers.add_parser("tui", help="live terminal UI: tune Ω, the jar speed and friction of a running mill")
    t.add_argument("preset", type=path_text, help=PRESET_HELP)
    t.add_argument("--out-dir", type=path_text, default=".",
                   help="folder for recordings (.rrd, .zarr) and PNG snapshots, created if needed (default .)")
    t.add_argument("--window", type=number, default=4.0, help="sliding window of the readouts, simulated s (default 4)")
    t.add_argument("--paused", action="store_true", help="start paused")
    _add_overrides(t, live=True)  # the mill runs until quit: no --duration, --analysis-start
    t.set_defaults(fn=cmd_tui)


def cmd_tui(a) -> int:
    from taimill.cli.common import overrides as _overrides
    from taimill.errors import ConfigError
    from taimill.model.preset import load_preset

    if not 0.1 <= a.window <= 600:
        raise ConfigError("command line", "--window", a.window, "allowed range [0.1, 600] s")
    from taimill.model.files import check_output

    out_dir = check_output(a.out_dir, "--out-dir", overwrite=None, folder=True)  # recordings get new names
    overrides = _overrides(a)
    preset = load_preset(a.preset, overrides)
    from taimill.cli.common import print_warnings

    print_warnings(preset)
    print("taimill: compiling the kernels …", file=sys.stderr)
    from taimill.runs.live import LiveMill
    from taimill.tui.app import MillApp

    mill = LiveMill(preset, overrides)  # main thread: ti.init, fields, first kernel call
    MillApp(mill, out_dir=out_dir, window=a.window, paused=a.paused).run()
    return 0
