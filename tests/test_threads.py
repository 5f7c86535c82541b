"""A large mill spreads its balls over all cores (parallel mode, docs/performance.md):
what it computes must not depend on how many. Each ball sums its own contacts in list
order and the only atomics are integer counters (pool rows, event slots, spectra), so
1 and 2 threads give the same events, spectra and final state, to the bit. Taichi
takes its thread count once per process: each count runs in its own interpreter."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = """
import hashlib, json
import numpy as np
from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.physics.runner import Runner
from taimill.physics.ti import init_taichi, ti
from taimill.store.sinks import MemorySink

init_taichi()
# 2000 balls of 2 mm thrown about: contacts open and close at every step, rows of the
# shared pool are popped by both threads at once
p = load_preset("p4-cy-steel", {"balls.count": 2000, "balls.diameter_mm": 2.0, "analysis_start": 0.0})
spec = from_preset(p).replace(steps=3000, frame_every=500)
spec = spec.replace(velocity=np.random.default_rng(3).normal(0.0, 1.0, (spec.n, 3)))
sink = MemorySink()
sink.start({}, spec.n, spec.radius)
runner = Runner([spec], mode="parallel")
runner.run([sink])
h = hashlib.sha256()
for table in (sink.event_table, sink.frame_table, sink.energy_table):  # frames: 2 blocks of the ledger's sums
    for k in sorted(table):
        h.update(np.ascontiguousarray(table[k]).tobytes())
for k, v in sorted(runner.final_state(0).items()):
    h.update(np.ascontiguousarray(v).tobytes())
h.update(sink.last_spectra.count.tobytes())
h.update(sink.last_spectra.fixed.tobytes())
print(json.dumps(dict(threads=ti.lang.impl.current_cfg().cpu_max_num_threads, mode=runner.engine.mode,
                      events=len(sink.event_table["t_start"]), frames=len(sink.frame_table["time"]),
                      digest=h.hexdigest())))
"""


def _run(threads: int) -> dict:
    env = os.environ | {"TI_CPU_MAX_NUM_THREADS": str(threads), "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_large_mill_gives_the_same_bits_on_one_and_two_threads():
    one, two = _run(1), _run(2)
    assert one["threads"] == 1 and two["threads"] == 2  # the setting took
    assert one["mode"] == two["mode"] == "parallel"
    assert one["events"] > 400  # contacts opened and closed throughout (624 when written)
    assert one["frames"] >= 2
    assert one["digest"] == two["digest"]
