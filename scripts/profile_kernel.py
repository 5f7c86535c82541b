"""Where a run's CPU time goes, down to the machine code of the Taichi kernels.

    .venv/bin/python scripts/profile_kernel.py [PRESET] [--seconds S] [--out DIR]

Taichi compiles its kernels at run time, so a sampling profiler sees them as anonymous
code without symbols. This script runs PRESET (default presets/p4-cy-steel.toml) for S
simulated seconds on one thread under `perf record` (Linux perf; objdump from binutils),
copies the process's anonymous executable memory (the compiled kernels) to DIR before
it exits, and then reports:

- the share of samples in the kernels, libm (the drive's trigonometry), the Python
  interpreter (drains and sinks), Taichi's runtime library and the rest;
- the kernel's hottest 256-byte blocks;
- DIR/kernel.asm: the disassembled kernel with the sample count of every instruction,
  to read beside the source (a `lock cmpxchg` loop is a Taichi atomic `+=`, `vsqrtsd`
  a norm, `vdivsd` a division, spills are moves to and from (%rsp)).

Quote ratios from one run: the machine is shared and the counts are samples of CPU
time (perf's cpu-clock; virtual machines often have no hardware counters).
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BLOCK = 256


def child(preset: str, seconds: float, out: Path) -> None:
    """Runs the preset (a compiling run first), then dumps the anonymous executable maps."""
    os.environ["TI_CPU_MAX_NUM_THREADS"] = "1"
    from taimill.model.preset import load_preset
    from taimill.physics.ti import init_taichi
    from taimill.runs.simulation import run
    from taimill.store.sinks import NullSink

    init_taichi(1)
    p = load_preset(preset)
    run(p, NullSink(), duration=min(0.05, seconds))
    t0 = time.clock_gettime(time.CLOCK_MONOTONIC)
    steps = run(p, NullSink(), duration=seconds)["steps"]
    (out / "window.txt").write_text(f"{t0} {time.clock_gettime(time.CLOCK_MONOTONIC)}\n")
    print(f"{steps} steps of {Path(preset).name}", file=sys.stderr)
    with open("/proc/self/maps") as maps, open("/proc/self/mem", "rb") as mem:
        for line in maps:
            parts = line.split()
            anonymous = len(parts) < 6 or not parts[5].startswith(("/", "["))
            if "x" not in parts[1] or not anonymous:
                continue
            lo, hi = (int(v, 16) for v in parts[0].split("-"))
            try:
                mem.seek(lo)
                (out / f"code_{lo:x}.bin").write_bytes(mem.read(hi - lo))
            except (OSError, ValueError, OverflowError):
                continue


def samples(data: Path, window: tuple[float, float]) -> list[tuple[int, str]]:
    """(address, library) of every sample taken during the profiled run (perf's clock
    is CLOCK_MONOTONIC, as the child's window)."""
    text = subprocess.run(["perf", "script", "-i", str(data), "-F", "time,ip,dso"], capture_output=True, text=True,
                          check=True).stdout
    out = []
    for line in text.splitlines():
        m = re.match(r"\s*([0-9.]+):\s+([0-9a-f]+)\s+\((.*)\)", line)
        if m and window[0] <= float(m.group(1)) <= window[1]:
            out.append((int(m.group(2), 16), m.group(3)))
    return out


def kind(dso: str, in_kernel: bool) -> str:
    if in_kernel:
        return "Taichi kernels (JIT code)"
    for key, name in (("libm", "libm (trigonometry)"), ("libpython", "Python interpreter"),
                      ("taichi_python", "Taichi runtime library"), ("taichi_forge", "Taichi runtime library"), ("numpy", "NumPy"), ("libc.so", "libc"),
                      ("kallsyms", "operating system")):
        if key in dso:
            return name
    return "other"


def report(out: Path) -> None:
    regions = []
    for f in out.glob("code_*.bin"):
        lo = int(f.stem.split("_")[1], 16)
        regions.append((lo, lo + f.stat().st_size, f))
    window = tuple(float(v) for v in (out / "window.txt").read_text().split())
    hits = samples(out / "perf.data", window)
    counts = collections.Counter()
    per_region = collections.Counter()
    per_ip = collections.Counter()
    for ip, dso in hits:
        region = next((r for r in regions if r[0] <= ip < r[1]), None)
        counts[kind(dso, region is not None)] += 1
        if region:
            per_region[region] += 1
            per_ip[ip] += 1
    total = sum(counts.values())
    print(f"\n{total} samples during the profiled run ({window[1] - window[0]:.2f} s wall):")
    for name, n in counts.most_common():
        print(f"  {100 * n / total:5.1f} %  {name}")
    if not per_region:
        print("no samples in anonymous code: did the kernel run?")
        return
    (lo, hi, path), n = per_region.most_common(1)[0]
    blocks = collections.Counter()
    for ip, c in per_ip.items():
        if lo <= ip < hi:
            blocks[(ip - lo) // BLOCK] += c
    print(f"\nhottest kernel code ({hi - lo} bytes at {lo:#x}, {n} samples), by {BLOCK}-byte block:")
    for b, c in blocks.most_common(12):
        print(f"  {lo + b * BLOCK:#x}  {100 * c / n:5.1f} %")
    asm = subprocess.run(["objdump", "-D", "-b", "binary", "-mi386:x86-64", f"--adjust-vma={lo:#x}", str(path)],
                         capture_output=True, text=True, check=True).stdout
    lines = []
    for line in asm.splitlines():
        m = re.match(r"\s*([0-9a-f]+):", line)
        lines.append(f"{per_ip.get(int(m.group(1), 16), 0) if m else '':>6} {line}")
    (out / "kernel.asm").write_text("\n".join(lines) + "\n")
    print(f"\nannotated disassembly: {out / 'kernel.asm'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("preset", nargs="?", default=str(ROOT / "presets" / "p4-cy-steel.toml"))
    ap.add_argument("--seconds", type=float, default=3.0, help="simulated seconds profiled (default 3)")
    ap.add_argument("--out", type=Path, default=None, help="folder for perf.data, the code dumps and kernel.asm")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    out = a.out or Path(tempfile.mkdtemp(prefix="taimill-profile-"))
    out.mkdir(parents=True, exist_ok=True)
    if a.child:
        child(a.preset, a.seconds, out)
        return
    for tool in ("perf", "objdump"):
        if not shutil.which(tool):
            sys.exit(f"profile_kernel: the `{tool}` command is needed (Debian: apt-get install "
                     f"{'linux-perf' if tool == 'perf' else 'binutils'})")
    cmd = ["perf", "record", "-k", "mono", "-F", "4000", "-o", str(out / "perf.data"), sys.executable, __file__, a.preset,
           "--seconds", str(a.seconds), "--out", str(out), "--child"]
    subprocess.run(cmd, check=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    report(out)


if __name__ == "__main__":
    main()
