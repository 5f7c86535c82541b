"""`taimill record RUN.zarr --rrd RUN.rrd` (a stored run as a rerun recording) and
`taimill view RUN.rrd` (the rerun viewer shipped with rerun-sdk).

`record` replays the store through the same `RerunSink` a live run feeds (no second
path): in blocks of REPLAY_SECONDS, the events that ended by the block's last frame,
then the frames, then their ledger rows — the order and kind of blocks a live run
emits."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

EXIT_NO_DISPLAY = 4
REPLAY_SECONDS = 0.05  # simulated seconds per replayed block, as a live launch


def _existing(path: str, key: str, folder: bool) -> Path:
    """An existing store folder (folder=True) or file (a recording)."""
    from taimill.errors import ConfigError

    from taimill.model.files import kind_of_path, name_kind

    p = Path(path)
    if not os.path.exists(p):  # os.path: a name the OS refuses (too long) is no such file either
        raise ConfigError("command line", key, path, "no such file or directory")
    if folder:  # a preset, jar, …, sweep store given as the run store
        name_kind("run store", kind_of_path(p), path, "command line", key)
    if folder and not os.path.isdir(p):
        raise ConfigError("command line", key, path, "is a file; need a run store folder (RUN.zarr)")
    if not folder and not os.path.isfile(p):
        raise ConfigError("command line", key, path, "not a regular file; need a recording file (RUN.rrd)")
    return p


RRD_MAGIC = b"RRF"  #: a rerun recording file starts with these bytes (then its format version)


def is_recording(path) -> bool:
    """True if `path` is a rerun recording (what --overwrite may replace)."""
    try:
        with open(path, "rb") as f:
            return f.read(len(RRD_MAGIC)) == RRD_MAGIC
    except OSError:
        return False


def check_output(path: str, overwrite: bool, inputs=()) -> None:
    """--rrd: a file name ending in .rrd in an existing writable folder; an existing
    file only with --overwrite, and only if it is a recording and none of `inputs`."""
    from taimill.model.files import check_output as _check_output

    _check_output(path, "--rrd", overwrite=overwrite, suffixes=(".rrd",), what="rerun recording", ours=is_recording,
                  inputs=inputs)


def replay(store, sink) -> None:
    """Stream a `RunStore`'s tables into `sink` as a live run would (module doc)."""
    import numpy as np

    from taimill.runs.signals import check

    frames, events, energy = store.frames, store.events, store.energy
    t = frames["time"]
    ends = events["t_start"] + events["duration"]
    sink.start(store.config, store.n_balls, store.radii)
    status = store.status or "unknown"
    try:
        begin, done = 0, -np.inf
        while begin < len(t):
            check()  # an interrupt rerun's code swallowed (runs.signals) stops the replay here
            stop = int(np.searchsorted(t, t[begin] + REPLAY_SECONDS, side="right"))
            last = t[stop - 1] if stop < len(t) else np.inf  # the last block takes every event left
            pick = (ends > done) & (ends <= last)
            if pick.any():
                sink.events({k: v[pick] for k, v in events.items()})
            sink.frames({k: v[begin:stop] for k, v in frames.items()})
            sink.energy({k: v[begin:stop] for k, v in energy.items()})
            begin, done = stop, last
    finally:
        sink.finish(store.summary or {}, status)


def cmd_record(a) -> int:
    from taimill.analysis.run import geometry
    from taimill.errors import ConfigError
    from taimill.store.output import Output
    from taimill.store.run import open_run

    check_output(a.rrd, a.overwrite)
    source = _existing(a.run, "RUN.zarr", folder=True)
    try:
        store = open_run(source)
    except ConfigError:  # StoreError names what is damaged
        raise
    except Exception as err:  # zarr raises several kinds for a directory that is no store
        raise ConfigError("command line", "RUN.zarr", a.run, f"not a taimill run store ({err})") from None
    if store.config is None or not len(store.frames["time"]):
        raise ConfigError("command line", "RUN.zarr", a.run, "a run store with a config and at least one frame")
    geometry(store)  # StoreError if its config is not a run's
    from taimill.recording.sink import RerunSink  # rerun is slow to import: after the checks

    # locked, built beside its place and renamed in when complete; one that failed (a
    # full disk) is deleted: the store it comes from is still there to record again
    with Output(a.rrd, overwrite=a.overwrite, option="--rrd", what="recording", kind="rerun recording",
                ours=is_recording, inputs=[source], whole=True, keep=lambda _: False) as out:
        replay(store, RerunSink(out.build, lab_frame=a.lab_frame, histogram_every=a.histogram_every))
        out.commit()
    print(f"{a.rrd}: {len(store.frames['time'])} frames, {len(store.events['t_start'])} events "
          f"(run status: {store.status}); open it with `taimill view {a.rrd}`")
    return 0


def viewer_binary() -> str | None:
    """The `rerun` executable shipped with rerun-sdk, next to this interpreter, else on PATH."""
    local = Path(sys.executable).parent / "rerun"
    return str(local) if local.exists() else shutil.which("rerun")


def has_display() -> bool:
    """False on a Linux machine without an X11 or Wayland display."""
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def cmd_view(a) -> int:
    path = _existing(a.rrd, "RUN.rrd", folder=False)
    binary = viewer_binary()
    if binary is None:
        print("taimill: the rerun viewer is not installed (pip install rerun-sdk)", file=sys.stderr)
        return EXIT_NO_DISPLAY
    if a.web:
        return subprocess.call([binary, "--web-viewer", str(path)])
    if not has_display():
        print(f"taimill: no display here (DISPLAY and WAYLAND_DISPLAY are unset), so the rerun viewer cannot "
              f"open a window. Copy {path} to a machine with a screen and run `rerun {path.name}`, or serve it "
              f"to a browser with `taimill view {path} --web`.", file=sys.stderr)
        return EXIT_NO_DISPLAY
    return subprocess.call([binary, str(path)])


def register(sub) -> None:
    from taimill.cli.common import path_text

    r = sub.add_parser("record", help="convert a stored run (RUN.zarr) into a rerun recording (.rrd)")
    r.add_argument("run", metavar="RUN.zarr", type=path_text, help="run store written by `taimill run --out`")
    r.add_argument("--rrd", required=True, metavar="RUN.rrd", type=path_text, help="recording to write")
    r.add_argument("--overwrite", action="store_true", help="replace an existing --rrd file")
    r.add_argument("--lab-frame", action="store_true", help="also record the jar moving on the plate")
    r.add_argument("--histogram-every", type=_positive, default=1.0, metavar="S",
                   help="period of the onset-speed histograms (simulated s, default 1)")
    r.set_defaults(fn=cmd_record)
    v = sub.add_parser("view", help="open a recording in the rerun viewer")
    v.add_argument("rrd", metavar="RUN.rrd", type=path_text)
    v.add_argument("--web", action="store_true", help="serve the web viewer instead of opening a window (headless machines)")
    v.set_defaults(fn=cmd_view)


def _positive(text: str) -> float:
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text!r}: a finite number of seconds > 0")
    return value
