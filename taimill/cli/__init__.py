"""`taimill` command line: one module per subcommand, each with a `register`
function; shared helpers in `common.py`. Heavy imports (taichi, zarr) happen inside
the commands so `taimill --help` stays fast. Bad input: one line on stderr, exit code 2."""

from __future__ import annotations

import argparse
import sys

from taimill.cli import calibrate, catalog, compare, liggghts, record, report, run, sweep, tui
from taimill.cli.common import EXIT_BAD_INPUT

SUBCOMMANDS = (run, calibrate, catalog, sweep, report, record, tui, liggghts, compare)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="taimill", description="Planetary ball mill simulator (Taichi DEM in the jar frame).")
    sub = p.add_subparsers(dest="command", required=True)
    for module in SUBCOMMANDS:
        module.register(sub)
    return p


def main(argv=None) -> int:
    from taimill.errors import ConfigError

    a = parser().parse_args(argv)
    try:
        return a.fn(a)
    except ConfigError as err:
        print(f"taimill: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("taimill: interrupted", file=sys.stderr)
        return 130
