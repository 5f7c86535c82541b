"""Signals and process lifetimes of runs and sweeps.

- `sigterm_interrupts()`: while a run or sweep works, SIGTERM takes the Ctrl-C path
  (`taimill.errors.Interrupted`, a KeyboardInterrupt): every buffered row is committed,
  the status becomes "interrupted" and the command exits with 143 (128 + SIGTERM; Ctrl-C
  gives 130). A second SIGTERM during that clean-up kills at once.
- `die_with_parent(pid)`: a sweep's worker process dies with the process that started
  it, also when that one is killed with SIGKILL and can clean nothing up. On Linux the
  kernel does it (prctl PR_SET_PDEATHSIG); elsewhere a thread polls os.getppid().
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time

from taimill.errors import Interrupted

EXIT_SIGTERM = 128 + signal.SIGTERM
PR_SET_PDEATHSIG = 1
POLL_SECONDS = 0.5


def _on_sigterm(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second one kills
    raise Interrupted("terminated (SIGTERM)", EXIT_SIGTERM)


@contextlib.contextmanager
def sigterm_interrupts():
    """SIGTERM raises Interrupted inside the block (module doc). Only in the main thread
    and only where nobody else handles SIGTERM; elsewhere the block runs unchanged."""
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return
    signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def die_with_parent(parent: int) -> None:
    """Make this process die when `parent` (its parent) dies (module doc)."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
            if os.getppid() != parent:  # it died before the prctl
                os._exit(1)
            return
        except (OSError, AttributeError):
            pass

    def watch():
        while os.getppid() == parent:
            time.sleep(POLL_SECONDS)
        os._exit(1)

    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, name="taimill-parent-watch", daemon=True).start()
