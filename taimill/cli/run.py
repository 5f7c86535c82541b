"""`taimill run PRESET [overrides]`: one simulation, its summary, store and recording."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from taimill.cli.common import (EXIT_UNSTABLE, DEFAULT_PRESET, PRESET_HELP, add_backend, add_overrides, backend, overrides, path_text,
                                plain, stderr_console, summary_table)
from taimill.model.cost import run_seconds


def register(sub) -> None:
    r = sub.add_parser("run", help="simulate a preset, summarise, store")
    r.add_argument("preset", type=path_text, nargs="?", default=DEFAULT_PRESET, help=PRESET_HELP)
    r.add_argument("--out", type=path_text, help="zarr store to write (RUN.zarr)")
    r.add_argument("--overwrite", action="store_true", help="replace an existing --out store or --rrd file")
    r.add_argument("--rrd", type=path_text, help="rerun recording to write (RUN.rrd); open it with `taimill view RUN.rrd`")
    r.add_argument("--json", action="store_true", help="print the summary as one JSON object on stdout")
    r.add_argument("--yes", action="store_true", help="run even when the estimate is over an hour of CPU (else refused)")
    r.add_argument("--dry-run", action="store_true", help="check everything and print the run's estimate; simulate nothing")
    add_backend(r)
    add_overrides(r)
    r.set_defaults(fn=cmd_run)


def cmd_run(a) -> int:
    from taimill.errors import SimulationUnstable
    from taimill.model.files import reads
    from taimill.model.preset import load_preset
    from taimill.cli.common import print_warnings

    backend(a)
    show_bar = sys.stderr.isatty()  # a bar on a pipe or log file draws nothing but leaves a blank line
    with reads() as inputs:  # the preset and every file it names: no output may replace them
        if sys.stderr.isatty():  # reading and checking 10⁵-10⁶ start positions takes seconds (on a
            # terminal only: elsewhere the bar's end leaves a blank line before a one-line error)
            preset = _with_status(f"reading {a.preset}…", load_preset, a.preset, overrides(a))
        else:
            preset = load_preset(a.preset, overrides(a))
    if a.dry_run:
        print(f"taimill: {preset.source}: {estimate_text(preset)}; nothing run (--dry-run)")
        return 0
    unasked_limit(preset, a.yes)
    if a.out:  # its folder must exist and be writable (an existing store: Output refuses it without --overwrite)
        from taimill.model.files import check_output

        check_output(a.out, "--out", overwrite=None)
    if a.rrd:
        from taimill.cli.record import check_output

        check_output(a.rrd, a.overwrite, inputs)
    from taimill.runs.simulation import run
    from taimill.store.output import Outputs
    from taimill.store.sinks import NullSink

    # each output locked, one that exists replaced only if it is a run store (a recording)
    # taimill wrote and none of the inputs, and only by a finished run (store/output.py)
    with Outputs() as outputs:
        sink = NullSink()
        if a.out:
            from taimill.store.layout import is_run_store, is_unstarted_store
            from taimill.store.run import holds_a_frame
            from taimill.store.writer import ZarrSink

            # a run refused or stopped before its first frame (balls that do not fit, Ctrl-C
            # while compiling) leaves no store in the way of its retry: kept only once it
            # holds a committed frame (holds_a_frame); an empty one an older taimill left is
            # replaced like a run store
            sink = ZarrSink(outputs.add(a.out, overwrite=a.overwrite, what="run", kind="run store",
                                        ours=lambda p: is_run_store(p) or is_unstarted_store(p), keep=holds_a_frame,
                                        inputs=inputs))
        if a.rrd:
            from taimill.cli.record import is_recording
            from taimill.recording.sink import RerunSink
            from taimill.store.sinks import FanOut

            sink = FanOut(sink, RerunSink(outputs.add(a.rrd, overwrite=a.overwrite, option="--rrd", what="recording",
                                                      ours=is_recording, inputs=inputs)))
        print_warnings(preset)  # once every check passed: a refusal stays one line
        note = long_run_note(preset)
        if note:
            print(f"taimill: note: {note}", file=sys.stderr)
        try:
            if show_bar:
                summary = _run_with_bar(run, preset, sink)
            else:
                summary = run(preset, sink, notice=say)
        except SimulationUnstable as err:
            print(f"taimill: {err}" + (f" ({outputs.kept()})" if outputs.items else ""), file=sys.stderr)
            return EXIT_UNSTABLE
        outputs.commit()
    if a.json:
        print(json.dumps(plain(summary)))
    else:
        b = preset.balls
        mill = f"{preset.mill.name}, " if preset.mill is not None else ""
        print(f"{preset.source}: {mill}{preset.jar.name} jar ({preset.jar.wall_material}), {b.count} balls of "
              f"{2e3 * b.radius:.4g} mm {b.material.name}, {Path(preset.pair).name}, Ω = {preset.drive.plate_rpm:g} rpm, "
              f"K = {preset.drive.ratio:g}")
        print(summary_table(summary))
        if a.out:
            print(f"stored in {a.out}")
        if a.rrd:
            print(f"recorded in {a.rrd} (open it with `taimill view {a.rrd}`)")
    return 0


LONG_SECONDS = 120.0  #: CPU seconds (the low estimate) from which `run` says how long it will take before it starts


# CPU seconds (the low estimate) above which a run needs --yes: a unit slip (a ball
# diameter of 0.01 typed for 10 mm) makes a run of 10⁹ steps that nobody meant to start.
UNASKED_SECONDS = 3600.0


def estimate_text(preset) -> str:
    """"2.4e+07 steps of dt = … for duration = … s; at … µs … this takes about 1 min to 5 min"."""
    steps, lo, hi = run_seconds(preset)
    return (f"{steps:.3g} steps of dt = {preset.dt:.3g} s for duration = {preset.duration:g} s; "
            f"at {lo / steps * 1e6:.2g}-{hi / steps * 1e6:.2g} µs of CPU a step for {preset.balls.count} balls "
            f"this takes about {span_text(lo)} to {span_text(hi)}")


def unasked_limit(preset, yes: bool) -> None:
    """Refuse a run estimated at more than UNASKED_SECONDS of CPU unless `yes` (--yes),
    naming the duration, the estimate and the ball size (whose unit is the usual slip)."""
    if yes or run_seconds(preset)[1] <= UNASKED_SECONDS:
        return
    from taimill.errors import ConfigError

    raise ConfigError("command line", "--duration", preset.duration,
                      f"{estimate_text(preset)}: over {span_text(UNASKED_SECONDS)}; pass --yes to run it, or check the "
                      f"balls' size ({preset.balls.radius * 2e3:g} mm diameter: --ball-diameter is in mm) and the duration")


def long_run_note(preset) -> str | None:
    """For a run expected to take more than a few minutes (even at the low end of
    docs/performance.md's CPU cost per step, more than LONG_SECONDS), a line that says
    how many steps and roughly how long they take; else None."""
    return estimate_text(preset) if run_seconds(preset)[1] > LONG_SECONDS else None


def span_text(seconds: float) -> str:
    for unit, size in (("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.2g} {unit}"
    return f"{seconds:.2g} s"


def _bar(console=None):
    """A transient progress bar on stderr whose remaining-time column stays empty until
    it has a total."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    class Remaining(TimeRemainingColumn):
        def render(self, task):
            return TextColumn("").render(task) if task.total is None else super().render(task)

    return Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[done]}"), Remaining(),
                    transient=True, console=console or stderr_console())


def _with_status(text, fn, *args, console=None):
    """fn(*args) under a pulsing bar saying `text`."""
    with _bar(console) as bar:
        bar.add_task(text, total=None, done="")
        return fn(*args)


def say(text: str) -> None:
    """A line on stderr that explains a wait ("taimill: compiling kernels for …")."""
    print(f"taimill: {text}", file=sys.stderr, flush=True)


def _run_with_bar(run, preset, sink, console=None):
    """The run under a progress bar on stderr. Until the first launch returns (set-up:
    summary and store, Taichi's fields, kernel compilation, seconds) the bar names the
    set-up phase (run's `stage`) and pulses; then it counts simulated seconds, its clock
    restarted so the remaining time is the simulation's."""
    with _bar(console) as bar:
        task = bar.add_task(f"setting up {preset.balls.count} balls…", total=None, done="")

        def stage(text):
            bar.update(task, description=text, refresh=True)  # drawn now, not at the next tick

        def progress(t):
            if bar.tasks[0].total is None:
                bar.reset(task, total=preset.duration, description="simulating")
            bar.update(task, completed=t, done=f"{t:.2f}/{preset.duration:.1f} s")

        def notice(text):  # above the bar, kept when the bar goes
            bar.console.print(f"taimill: {text}", markup=False, highlight=False)

        return run(preset, sink, progress=progress, stage=stage, notice=notice)
