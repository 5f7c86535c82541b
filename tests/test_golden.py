"""Golden runs: two presets with a fixed seed, run through the real CLI, must store
bit-identical event tables, frames, energy ledgers and summaries to the recorded
digests in `golden/runs.json`.

A refactoring must leave these unchanged. A deliberate change of the physics or of
the summary rewrites them (`TAIMILL_WRITE_GOLDEN=1 pytest tests/test_golden.py`) and
says why in its commit message.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import zarr

from taimill.schema import MACHINE_KEYS

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
GOLDEN = HERE / "golden" / "runs.json"
# (preset, overrides): the thesis' steel case and a low-friction case in a jar with corners,
# then one short case per other normal law and one with rolling resistance.
CASES = {
    "cy-steel": ("presets/p4-cy-steel.toml", ["--duration", "1.2", "--seed", "3"]),
    "hm-fluorite": ("presets/p4-hm-fluorite.toml", ["--duration", "1.2", "--seed", "5", "--ratio", "-3.0"]),
    # one short run per other normal law, and one with rolling resistance on both kinds
    "cy-steel-kelvin-voigt": ("presets/p4-cy-steel.toml", ["--duration", "0.6", "--seed", "2", "--law", "kelvin-voigt"]),
    "cy-steel-hertz-damper": ("presets/p4-cy-steel.toml", ["--duration", "0.6", "--seed", "2", "--law", "hertz-damper"]),
    "hm-fluorite-hunt-crossley": ("presets/p4-hm-fluorite.toml", ["--duration", "0.6", "--seed", "2", "--ratio", "-3.0",
                                                                  "--law", "hunt-crossley"]),
    "hm-fluorite-hertz-mindlin": ("presets/p4-hm-fluorite.toml", ["--duration", "0.6", "--seed", "2", "--ratio", "-3.0",
                                                                  "--law", "hertz-mindlin"]),
    "hm-rolling": ("tests/golden/hm-rolling.toml", []),
    "cy-history": ("tests/golden/cy-history.toml", []),  # the sub-models with a per-contact history
}
# Summary entries that measure the machine, not the run (the wall time, the backend).
TIMING_KEYS = MACHINE_KEYS


def _digest(a: np.ndarray) -> str:
    if a.dtype.kind in "OUT":  # names (the spectra's coordinates): their text
        return f"str{list(a.shape)}:" + hashlib.sha256(json.dumps(np.asarray(a).tolist()).encode()).hexdigest()[:24]
    a = np.ascontiguousarray(a)
    return f"{a.dtype.str}{list(a.shape)}:" + hashlib.sha256(a.tobytes()).hexdigest()[:24]


def _read_digests(path: Path) -> dict:
    """Per stored array a digest of its committed rows; the summary as canonical JSON."""
    g = zarr.open_group(path, mode="r")
    out = {}
    for table in sorted(k for k, _ in g.groups()):
        n = g[table].attrs.get("n_valid")  # None: not a table (the spectra): every element
        for name, arr in sorted(g[table].arrays()):
            out[f"{table}/{name}"] = _digest(arr[:n] if n is not None else arr[...])
    summary = {k: v for k, v in dict(g.attrs["summary"]).items() if k not in TIMING_KEYS}
    out["summary"] = hashlib.sha256(json.dumps(summary, sort_keys=True).encode()).hexdigest()[:24]
    out["events"] = summary["events"]
    return out


def _taimill() -> list[str]:
    exe = Path(sys.executable).with_name("taimill")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "taimill"]


def _run_case(name: str, tmp_path: Path) -> dict:
    preset, extra = CASES[name]
    out = tmp_path / f"{name}.zarr"
    subprocess.run([*_taimill(), "run", preset, *extra, "--out", str(out), "--json"], cwd=ROOT,
                   check=True, capture_output=True, text=True)
    return _read_digests(out)


@pytest.mark.parametrize("name", sorted(CASES))
def test_run_is_bit_identical_to_the_golden_record(name, tmp_path):
    got = _run_case(name, tmp_path)
    if os.environ.get("TAIMILL_WRITE_GOLDEN"):
        record = json.loads(GOLDEN.read_text()) if GOLDEN.exists() else {}
        record[name] = got
        GOLDEN.parent.mkdir(exist_ok=True)
        GOLDEN.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    want = json.loads(GOLDEN.read_text())[name]
    changed = sorted(k for k in set(want) | set(got) if want.get(k) != got.get(k))
    assert not changed, f"{name}: these outputs changed: {changed}"
