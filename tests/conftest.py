import os
import signal

import pytest

# `make test` runs the suite in one pytest-xdist worker per core. Each worker's Taichi
# (in-process, and the CLI runs it starts, which inherit the environment) then gets one
# thread: two workers with two threads each on two cores made the multi-threaded
# tests wait on each other's spinning thread pools (one test went from 8 s to 196 s).
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("TI_CPU_MAX_NUM_THREADS", "1")

# The Ctrl-C tests send SIGINT as a terminal does. A suite started where SIGINT is
# ignored (a background job of a non-interactive shell, `make test &`) passes that on
# across exec, Python keeps it ignored, and every Ctrl-C test failed (a run that ignores
# the signal is right to). The suite takes SIGINT back, so what it starts gets it too.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def taichi():
    """ti.init once for the session, for tests that call Taichi kernels directly (a
    second ti.init would invalidate fields). Runs, runners and the live mill start
    Taichi themselves; NumPy-only tests never do."""
    from taimill.physics.ti import init_taichi

    init_taichi()


# The slowest files first: `make test` hands whole files to its workers in collection
# order, so the heavy ones start at once and small ones fill the end (in the old
# alphabetical order test_tui and test_sweep came last and one worker idled ≈ 25 s).
HEAVY_FIRST = ("test_faults.py", "test_fault_lines.py", "test_tui.py", "test_runs.py", "test_sweep.py", "test_report.py",
               "test_calibrate.py", "test_cli.py", "test_mechanisms.py", "test_liggghts.py")


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: order inside a file kept
