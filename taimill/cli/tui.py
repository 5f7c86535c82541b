"""`taimill tui PRESET [overrides]`: the live terminal UI (taimill.tui)."""

from __future__ import annotations

import os
import sys
import traceback


def register(subparsers):
    from taimill.cli.common import DEFAULT_PRESET, PRESET_HELP, add_backend, add_overrides as _add_overrides, number, path_text

    t = subparsers.add_parser("tui", help="live terminal UI: tune Ω, the jar speed and friction of a running mill")
    t.add_argument("preset", type=path_text, nargs="?", default=DEFAULT_PRESET, help=PRESET_HELP)
    t.add_argument("--out-dir", type=path_text, default=".",
                   help="folder for recordings (.rrd, .zarr) and PNG snapshots, created if needed (default .)")
    t.add_argument("--window", type=number, default=4.0, help="sliding window of the readouts, simulated s (default 4)")
    t.add_argument("--paused", action="store_true", help="start paused")
    add_backend(t)
    _add_overrides(t, live=True)  # the mill runs until quit: no --duration, --analysis-start
    t.set_defaults(fn=cmd_tui)


def cmd_tui(a) -> int:
    from taimill.cli.common import backend, overrides as _overrides
    from taimill.errors import ConfigError

    backend(a)
    from taimill.model.preset import load_preset

    if not 0.1 <= a.window <= 600:
        raise ConfigError("command line", "--window", a.window, "allowed range [0.1, 600] s")
    from taimill.model.files import check_output

    out_dir = check_output(a.out_dir, "--out-dir", overwrite=None, folder=True)  # recordings get new names
    overrides = _overrides(a)
    preset = load_preset(a.preset, overrides)
    from taimill.cli.common import print_warnings

    print_warnings(preset)
    from taimill.cli.run import say
    from taimill.runs.simulation import announcing
    from taimill.runs.live import LiveMill
    from taimill.runs.signals import sigterm_interrupts
    from taimill.tui.app import MillApp

    # while compiling: SIGTERM as Ctrl-C (one line, 143); the wait explained (CompilePlan)
    with sigterm_interrupts(), announcing(lambda plan: say(plan.text())):
        mill = LiveMill(preset, overrides)  # main thread: ti.init, fields, first kernel call
    app = MillApp(mill, out_dir=out_dir, window=a.window, paused=a.paused)
    app.run()
    return ended(app)


def ended(app) -> int:
    """The exit code of a TUI session, after one line on stderr for its fault (the
    app's `fault`, printed once Textual has restored the terminal): 5 a file it could
    not write, 143 SIGTERM, 70 an error in taimill itself; never 0 after an error."""
    from taimill.cli.common import EXIT_INTERNAL, EXIT_WRITE_REFUSED
    from taimill.errors import ConfigError, one_line

    fault = app.fault
    if fault is None:
        return app.return_code or 0
    if isinstance(fault, KeyboardInterrupt):
        print(f"taimill: {fault}", file=sys.stderr)
        return getattr(fault, "exit_code", 130)
    if isinstance(fault, ConfigError):  # StoreWriteError (5), a refused value (2)
        print(f"taimill: error: {fault}", file=sys.stderr)
        return fault.exit_code
    if os.environ.get("TAIMILL_DEBUG"):
        traceback.print_exception(fault, file=sys.stderr)
    if isinstance(fault, OSError):
        print(f"taimill: error: {fault.filename or 'tui'}: {fault.strerror or fault}", file=sys.stderr)
        return EXIT_WRITE_REFUSED
    print(f"taimill: error: tui: internal error ({type(fault).__name__}: {one_line(str(fault))}); "
          "TAIMILL_DEBUG=1 shows where", file=sys.stderr)
    return EXIT_INTERNAL
