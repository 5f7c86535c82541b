"""`taimill` command line: one module per subcommand, each with a `register`
function; shared helpers in `common.py`. Heavy imports (taichi, zarr) happen inside
the commands so `taimill --help` stays fast.

Bad input (docs/outputs.md, errors): one line on stderr, `taimill: error: ` then the
file (or "command line"), the key or option, the value and what is allowed; exit code
2; checked before anything runs or is written. argparse's own errors are one line too
(common.Parser). Every other fault is one line as well, with its exit code (common.py):
a write the system refused (5), a sweep worker that died (6), Ctrl-C (130), SIGTERM
(143)."""

from __future__ import annotations

import functools
import os
import sys

from taimill.cli import (advise, calibrate, catalog, compare, design, heat, kinetics, liggghts, record, report, run, sizes,
                         sweep, tui, wear)
from taimill.cli.common import EXIT_BAD_INPUT, EXIT_WRITE_REFUSED, Parser

SUBCOMMANDS = (run, calibrate, catalog, sweep, advise, report, record, tui, liggghts, compare, kinetics, sizes, design,
               heat, wear)


def version() -> str:
    """The installed package's version."""
    from importlib.metadata import PackageNotFoundError, version as _version

    try:
        return _version("taimill")
    except PackageNotFoundError:
        return "unknown (not installed)"


@functools.lru_cache(maxsize=1)
def parser() -> Parser:
    """The command line's parser (built once: parsing leaves it unchanged)."""
    p = Parser(prog="taimill", description="Planetary ball mill simulator (Taichi DEM in the jar frame).")
    p.add_argument("--version", action="version", version=f"taimill {version()}")
    sub = p.add_subparsers(dest="command", required=True)
    for module in SUBCOMMANDS:
        module.register(sub)
    return p


def main(argv=None) -> int:
    from taimill.errors import ConfigError, WorkerDied

    try:
        a = parser().parse_args(argv)
    except SystemExit as done:  # --help, --version (0) or a one-line usage error (2)
        return done.code if isinstance(done.code, int) else EXIT_BAD_INPUT
    from taimill.runs.signals import sigterm_interrupts

    try:
        with sigterm_interrupts():  # every command: SIGTERM exits 143 as Ctrl-C exits 130, in one line
            return a.fn(a)
    except ConfigError as err:  # also StoreError (2) and StoreWriteError (5): taimill.errors
        print(f"taimill: error: {err}", file=sys.stderr)
        return getattr(err, "exit_code", EXIT_BAD_INPUT)
    except WorkerDied as err:  # a sweep's worker process was killed: the finished points are stored
        print(f"taimill: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt as err:  # Ctrl-C 130, SIGTERM 143 (taimill.runs.signals)
        print(f"taimill: {str(err) or 'interrupted'}", file=sys.stderr)
        return getattr(err, "exit_code", 130)
    except BrokenPipeError:  # `taimill presets | head`: the reader left; nothing to report
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the interpreter's final flush stays quiet
        return 0
    except OSError as err:  # a write refused where no output names it (a folder the OS would not create)
        where = f"{err.filename}: " if err.filename else ""
        print(f"taimill: error: {where}{err.strerror or err}", file=sys.stderr)
        return EXIT_WRITE_REFUSED
