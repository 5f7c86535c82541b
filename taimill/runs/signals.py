"""Signals and process lifetimes of runs and sweeps.

- `sigterm_interrupts()`: while a run or sweep works, SIGTERM takes the Ctrl-C path
  (`taimill.errors.Interrupted`, a KeyboardInterrupt): every buffered row is committed,
  the status becomes "interrupted" and the command exits with 143 (128 + SIGTERM; Ctrl-C
  gives 130). A second SIGTERM during that clean-up kills at once. The command line
  enters it around every command, so each one stops so.
- An interrupt is remembered until the block ends: code that swallows exceptions
  (Taichi's kernel decorator wraps a source lookup in a bare `except:`, run at every
  import of a module that defines kernels) would otherwise lose a Ctrl-C that lands
  there, and a sweep interrupted 1 s in ran to its end. `check()` raises it again; the
  run and sweep loops call it between launches and while they wait, `record` between
  blocks. One raised inside a `__del__` (rerun's recording streams have one) cannot
  leave it: Python prints it as "Exception ignored in" with a traceback, which the block
  keeps quiet (`_quiet_unraisable`), the interrupt being remembered.
- zarr's sync calls make a coroutine and then hand it to zarr's event-loop thread; an
  interrupt landing between the two leaves that coroutine unawaited, and Python warned
  about it at exit, after the fault's one line. Once interrupted, that warning is off.
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
import warnings

from taimill.errors import Interrupted

EXIT_SIGTERM = 128 + signal.SIGTERM
PR_SET_PDEATHSIG = 1
POLL_SECONDS = 0.5


# While a launch's rows are handed to the sinks the interrupt waits (hold/release): a
# block that reached the run summary but not the store would make the store disagree
# with its own summary (events counted but never written), which readers call damage.
_held = {"depth": 0, "pending": None, "seen": None}


def _interrupt(err: KeyboardInterrupt) -> None:
    _held["seen"] = err
    # what it cut off between a coroutine's making and its loop is not the user's fault (module doc)
    warnings.filterwarnings("ignore", message=r"coroutine .* was never awaited", category=RuntimeWarning)
    if _held["depth"]:
        _held["pending"] = err
        return
    raise err


def _on_sigterm(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second one kills
    _interrupt(Interrupted("terminated (SIGTERM)", EXIT_SIGTERM))


def _on_sigint(signum, frame):
    _interrupt(KeyboardInterrupt())


def hold() -> None:
    """SIGTERM and Ctrl-C wait until the matching `release()` (nested calls count)."""
    _held["depth"] += 1


def release() -> None:
    """End a hold; an interrupt that arrived during it is raised here."""
    _held["depth"] = max(0, _held["depth"] - 1)
    if _held["depth"] == 0 and _held["pending"] is not None:
        err, _held["pending"] = _held["pending"], None
        raise err


def check() -> None:
    """Raise an interrupt that arrived in this block and was swallowed on its way out
    (module doc); nothing while a hold lasts (release raises it then)."""
    if _held["seen"] is not None and not _held["depth"]:
        _held["pending"] = None
        raise _held["seen"]


def drop_hold() -> None:
    """End every hold without raising (the run is finishing anyway)."""
    _held["depth"], _held["pending"] = 0, None


def _quiet_unraisable(before):
    """sys.unraisablehook that drops an interrupt raised where it cannot leave (a
    `__del__`): it is remembered and `check()` raises it again (module doc)."""

    def hook(info):
        if not isinstance(info.exc_value, KeyboardInterrupt):
            before(info)

    return hook


@contextlib.contextmanager
def sigterm_interrupts():
    """SIGTERM raises Interrupted, and Ctrl-C KeyboardInterrupt, inside the block (module
    doc), each waiting while a `hold()` lasts. Only in the main thread and only where
    nobody else handles the signal; elsewhere the block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    ours = {}
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        ours[signal.SIGTERM] = signal.signal(signal.SIGTERM, _on_sigterm)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        ours[signal.SIGINT] = signal.signal(signal.SIGINT, _on_sigint)
    unraisable = sys.unraisablehook
    if ours:
        sys.unraisablehook = _quiet_unraisable(unraisable)
    try:
        yield
    finally:
        sys.unraisablehook = unraisable
        for signum, before in ours.items():
            signal.signal(signum, before)
        drop_hold()
        if ours:
            _held["seen"] = None


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
