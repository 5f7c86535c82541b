"""The open-contact pool (physics/contacts.py, state.py): the event data of open
contacts lives in a sparse pool of rows per mill, not in 15 slots of every ball. Memory
per ball of a large mill, a pool that runs out stopping the run with a clear message,
and a planted many-contact cluster booking every event as the per-ball slots did."""

import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from taimill.errors import SimulationUnstable
from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.physics.runner import Runner
from taimill.store.sinks import MemorySink

ROOT = Path(__file__).resolve().parent.parent
CY = str(ROOT / "presets" / "p4-cy-steel.toml")

# Resident bytes per ball of the fields of a mill in parallel mode, its output buffers
# (bounded by bytes, not per ball) left out: 1210 B measured with the pool of 6 rows a
# ball, 4 of them its home rows (≈ 1900 B with the 15 slots of event data per ball).
# Measured as the slope between 10³ and 10⁵ balls (1058–1136 B, 2026-11-28): what the fields'
# first use costs whatever the size (≈ 30 MB of compiled accessors and allocator pages
# here) once counted per ball of the large mill alone, and it had grown from 1346 to
# 1389 B of the 1400 allowed.
FIELD_BYTES_PER_BALL = 1400
SMALL, LARGE = 1000, 100_000

_MEASURE = """
import sys
from taimill.physics.ti import init_taichi
init_taichi(1)
from taimill.physics.engine import Engine
def rss():
    return next(int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmRSS")) * 1024
n = int(sys.argv[1])
e = Engine(1, n, mode="parallel", grid_cells=1 << 18)
F = e.F
buffers = (F.out.events.shape[1] * F.out.events.n + 9 * F.frame_capacity * F.N) * 8  # bounded by bytes (Engine)
before = rss()
F.model.n_balls[0] = 1  # materialises every field
print(rss() - before - buffers)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_fields_of_a_large_mill_have_no_per_ball_slots_of_event_data():
    grown = {}
    for n in (SMALL, LARGE):
        res = subprocess.run([sys.executable, "-c", _MEASURE, str(n)], capture_output=True, text=True, cwd=ROOT,
                             timeout=300)
        assert res.returncode == 0, res.stderr
        grown[n] = float(res.stdout.split()[-1])
    per_ball = (grown[LARGE] - grown[SMALL]) / (LARGE - SMALL)
    assert 0 < per_ball <= FIELD_BYTES_PER_BALL, grown


@pytest.mark.parametrize("mode", ["fused", "parallel"])
def test_a_pool_that_runs_out_stops_the_run_with_a_clear_message(mode):
    # the cluster below opens 36 contacts in its first step
    with pytest.raises(SimulationUnstable) as err:
        Runner([_cluster_spec()], mode=mode, pool=8).run([MemorySink()])
    msg = str(err.value)
    assert msg.startswith("unstable at t = 0.000001 s: ball ")  # in the first step
    assert "opened a contact beyond the mill's open-contact pool of 8 rows" in msg


def _cluster_spec(duration=0.04):
    """Ball 0 inside a shell of its 12 close-packed neighbours, all overlapping by 10 µm
    (36 contacts open at once, 12 of them owned by ball 0, the most a ball can own),
    flying apart into the jar."""
    spec = from_preset(load_preset(CY), duration).replace(height=0.05)  # room for three layers
    r = spec.radius[0]
    a = 2 * r - 10e-6
    shell = [(x, y, 0.0) for x, y in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    shell += [(x, 0.0, z) for x in (1, -1) for z in (1, -1)] + [(0.0, y, z) for y in (1, -1) for z in (1, -1)]
    x = np.vstack([[0.0, 0.0, 0.0], np.array(shell) * a / np.sqrt(2)]) + [0.0, 0.0, spec.height / 2]
    n = len(x)
    return spec.replace(position=x, velocity=np.zeros((n, 3)), spin=np.zeros((n, 3)),
                        radius=np.full(n, r), mass=np.full(n, spec.mass[0]))


def _digest(table):
    h = hashlib.sha256()
    for k in sorted(table):
        h.update(k.encode() + np.ascontiguousarray(table[k]).tobytes())
    return h.hexdigest()[:24]


# The event table of the cluster with the per-ball slots (before the pool, b644d41: digest
# 5337ad0eeecf512756a09c3e), rewritten when the stored 1/m, the ψ recurrence and the
# friction formula changed the last bits (the same 62 events; tests/test_ensemble.py).
CLUSTER_EVENTS, CLUSTER_DIGEST = 62, "50af734bf802936ba25aba33"


@pytest.mark.parametrize("mode,pool", [("fused", None), ("fused", 44), ("parallel", None), ("parallel", 44)])
def test_a_many_contact_cluster_books_every_event_as_the_slots_did(mode, pool):
    # default: 4 home rows a ball (ball 0 takes 8 shared rows more); 44 rows: 1 home row a
    # ball and 28 shared, the 36 contacts of the first step and little more, reused all along
    sink = MemorySink()
    Runner([_cluster_spec()], mode=mode, pool=pool).run([sink])
    table = sink.event_table
    assert len(table["t_start"]) == CLUSTER_EVENTS
    assert (table["body_i"] == 0).sum() >= 12
    assert _digest(table) == CLUSTER_DIGEST


@pytest.mark.parametrize("mode", ["fused", "parallel"])
def test_contacts_take_their_owners_home_rows_first(mode):
    # after the cluster's first step: each ball's open contacts sit in its own home rows
    # (rows i·home …, read in memory order by the force pass); only ball 0, owning 12,
    # spills the 8 beyond its 4 home rows into the shared part of the pool
    runner = Runner([_cluster_spec()], mode=mode)
    runner.engine.advance(1)
    F = runner.engine.F
    assert F.state.step[0] == 1
    assert F.home == 4 and F.spill_base == 4 * F.N
    mask, rows = F.contacts.slot_mask.to_numpy()[0], F.contacts.slot_row.to_numpy()[0]
    shared = []
    for i in range(13):
        open_rows = [rows[i, k] for k in range(15) if mask[i] >> k & 1]
        home = [r for r in open_rows if r < F.spill_base]
        assert all(i * 4 <= r < i * 4 + 4 for r in home), (i, open_rows)
        assert len(home) == min(4, len(open_rows))
        shared += [r for r in open_rows if r >= F.spill_base]
    assert sorted(shared) == list(range(F.spill_base, F.spill_base + 8))
