#!/usr/bin/env python
"""Screenshot of a recording in the rerun viewer on a headless Linux machine.

Needs Debian's xvfb, xdotool and mesa-vulkan-drivers (llvmpipe: the viewer's GL
backend lacks the R32Float render target on Mesa 22, Vulkan works). The recording's
own layout is used with one change for the picture: the time panel follows the newest
data, so the viewer shows the end of the run instead of playing from t = 0.

    scripts/rerun_screenshot.py RUN.rrd OUT.png [--lab-frame] [--size 1600x900]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rerun.blueprint as rrb

from taimill.recording import scene
from taimill.cli.record import viewer_binary

DISPLAY = ":97"
# program -> what provides it (Debian)
NEEDED = {"Xvfb": "apt-get install xvfb", "xdotool": "apt-get install xdotool"}


def missing_tool() -> str | None:
    """One line naming the first missing program and how to install it, or None."""
    for program, install in NEEDED.items():
        if shutil.which(program) is None:
            return f"rerun_screenshot: {program} not found; install it with `{install}` (and mesa-vulkan-drivers for the viewer)"
    if viewer_binary() is None:
        return "rerun_screenshot: the rerun viewer not found; install it with `pip install rerun-sdk`"
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rrd", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--lab-frame", action="store_true", help="the recording has the lab view")
    ap.add_argument("--size", default="1600x900", help="viewer window in logical points")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    problem = missing_tool() or (None if a.rrd.is_file() else f"rerun_screenshot: {a.rrd} is not a file")
    if problem:
        print(problem, file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        bp = scene.blueprint(a.lab_frame, scene.recorded_extent(a.rrd))
        bp.time_panel = rrb.TimePanel(timeline=scene.TIME, state="collapsed", play_state="following")
        follow = Path(tmp) / "follow.rbl"
        bp.save("taimill", follow)
        # the screen holds the window at 2 pixels per point; the pointer parks outside it (no hover tooltip)
        xvfb = subprocess.Popen(["Xvfb", DISPLAY, "-screen", "0", f"{2 * w + 200}x{2 * h + 200}x24"])
        try:
            time.sleep(2)
            env = {**os.environ, "DISPLAY": DISPLAY, "XDG_RUNTIME_DIR": tmp}
            subprocess.run(["xdotool", "mousemove", str(2 * w + 190), str(2 * h + 190)], env=env, check=True)
            subprocess.run([viewer_binary(), str(a.rrd), str(follow), "--screenshot-to", str(a.out),
                            "--window-size", a.size, "--renderer", "vulkan"], env=env, check=True, timeout=600,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        finally:
            xvfb.terminate()
    print(a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
