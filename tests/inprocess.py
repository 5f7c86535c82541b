"""The CLI called in the test's own process (no subprocess, no Taichi for analyse,
report, record): exit code, stdout, stderr."""

from __future__ import annotations

import contextlib
import io

from taimill import cli


def main(*args) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(list(map(str, args)))
    return code, out.getvalue(), err.getvalue()
