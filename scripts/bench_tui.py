"""Speed of the live mill inside `taimill tui` and the latency of its screen (issue 7).

    .venv/bin/python scripts/bench_tui.py [PRESET] [--seconds S] [--presses N] [--no-tmux]

1. In process (Textual's headless driver, the real app at 120 × 40): simulated seconds
   per wall second and per CPU second of the whole process (the second is what an idle
   machine would give: the GIL makes the app one core's worth of work), and frames
   drawn per second by the top view.
2. As a user sees it (tmux, needs the `tmux` binary): `taimill tui PRESET` in a 120 × 40
   pane; the real-time factor and frame rate read off its status line; and the
   input-to-screen latency: press `p` and time until the pane shows the status change
   (polling capture-pane every 2 ms), N times.
"""

from __future__ import annotations

import argparse
import asyncio
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def in_process(preset: Path, seconds: float) -> dict:
    from taimill.model.preset import load_preset
    from taimill.runs.live import LiveMill
    from taimill.tui.app import MillApp

    mill = LiveMill(load_preset(preset))
    out = {}

    async def main():
        app = MillApp(mill, out_dir=tempfile.mkdtemp())
        async with app.run_test(size=(120, 40)) as pilot:
            await asyncio.sleep(3.0)  # past the first readouts
            t0, w0, c0, d0 = mill.time, time.perf_counter(), time.process_time(), app.top_view.drawn
            await asyncio.sleep(seconds)
            t1, w1, c1, d1 = mill.time, time.perf_counter(), time.process_time(), app.top_view.drawn
            out.update(sim_per_wall=(t1 - t0) / (w1 - w0), sim_per_cpu=(t1 - t0) / (c1 - c0),
                       cpu_per_wall=(c1 - c0) / (w1 - w0), frames_per_s=(d1 - d0) / (w1 - w0))
            await pilot.press("q")

    asyncio.run(main())
    return out


def tmux(*args) -> str:
    return subprocess.run(["tmux", *args], capture_output=True, text=True, check=True).stdout


def screen() -> str:
    return tmux("capture-pane", "-p", "-t", "bench")


def wait_for(pattern: str, timeout: float) -> tuple[float, str]:
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < timeout:
        s = screen()
        if re.search(pattern, s):
            return time.perf_counter() - t0, s
        time.sleep(0.002)
    raise TimeoutError(f"{pattern!r} not on screen after {timeout} s")


def in_tmux(preset: Path, seconds: float, presses: int) -> dict:
    subprocess.run(["tmux", "kill-session", "-t", "bench"], capture_output=True)
    out_dir = tempfile.mkdtemp()
    tmux("new", "-d", "-s", "bench", "-x", "120", "-y", "40",
         f"cd {ROOT} && .venv/bin/taimill tui {preset} --out-dir {out_dir}")
    try:
        wait_for(r"▶ running .* frames/s", 120)
        time.sleep(seconds)
        rates = [float(x) for x in re.findall(r"([\d.]+)× real time", screen())]
        fps = [float(x) for x in re.findall(r"view (\d+) frames/s", screen())]
        latencies = []
        for _ in range(presses):
            tmux("send-keys", "-t", "bench", "p")
            dt, s = wait_for(r"❚❚ paused", 10)
            latencies.append(dt)
            time.sleep(0.3)
            tmux("send-keys", "-t", "bench", "p")
            dt, s = wait_for(r"▶ running", 10)
            latencies.append(dt)
            time.sleep(0.7)
        last = screen()
        tmux("send-keys", "-t", "bench", "q")
        return {"realtime_factor": rates[-1] if rates else None, "frames_per_s": fps[-1] if fps else None,
                "latency_worst_ms": 1e3 * max(latencies), "latency_median_ms": 1e3 * statistics.median(latencies),
                "presses": len(latencies), "screen": last}
    finally:
        time.sleep(1.0)
        subprocess.run(["tmux", "kill-session", "-t", "bench"], capture_output=True)


def main() -> int:
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("preset", nargs="?", default=str(ROOT / "presets" / "p4-cy-steel.toml"))
    a.add_argument("--seconds", type=float, default=10.0, help="measuring time (wall s)")
    a.add_argument("--presses", type=int, default=10, help="pause/resume pairs timed in tmux")
    a.add_argument("--no-tmux", action="store_true")
    args = a.parse_args()
    r = in_process(Path(args.preset), args.seconds)
    print("in process (headless): " + ", ".join(f"{k} {v:.2f}" for k, v in r.items()))
    if not args.no_tmux and shutil.which("tmux"):
        t = in_tmux(Path(args.preset), args.seconds, args.presses)
        print(t.pop("screen"))
        print("tmux: " + ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in t.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
