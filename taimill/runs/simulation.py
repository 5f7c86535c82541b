"""One run of a preset: the summary sink and the caller's sink fed by one stream.

    run(preset, sink) — one mill from a preset, summary returned.
"""

from __future__ import annotations

import time

from taimill.analysis.summary import SummarySink
from taimill.errors import SimulationUnstable
from taimill.model.spec import from_preset
from taimill.outcome.dose import dose_keys, shear_keys
from taimill.physics.backend import select as select_backend  # noqa: F401 - the CLI's way to it (layers)
from taimill.physics.ti import compute
from taimill.physics.runner import Runner, announcing  # noqa: F401 - announcing: the CLI says when kernels compile
from taimill.runs import signals
from taimill.runs.signals import sigterm_interrupts
from taimill.schema import with_units
from taimill.store.sinks import FanOut, NullSink, Relay


def start_point(preset, spec, sink) -> tuple[SummarySink, FanOut]:
    """The summary sink of one mill and the stream feeding it and `sink`, started
    (shared by run() and sweeps so that a sweep point is the same run)."""
    sim_seconds = spec.steps * spec.dt
    if preset.events_output == "spectra":
        sink = SpectraOnly(sink)
    summary = SummarySink(min(preset.analysis_start, sim_seconds), sim_seconds, preset.jar.radius, preset.balls.radius)
    out = FanOut(summary, sink)
    out.start(preset.as_dict() | {"duration": sim_seconds}, spec.n, spec.radius)
    return summary, out


def point_result(preset, spec, summary, runner, b, wall, status) -> dict:
    """Run summary (docs/outputs.md) of mill b of `runner`; wall in s."""
    result = summary.result(runner.time(b), wall)
    result.update(dt=spec.dt, steps=int(runner.engine.F.state.step[b]), status=status,
                  ratio=preset.drive.ratio, plate_rpm=preset.drive.plate_rpm, compute=compute())
    if preset.softening != 1.0:  # the run's contacts are not the measured ones: said with every result
        result["softening"] = preset.softening
    # the dose per gram of powder (with a [powder] table) and the gentle / shear view
    result.update(dose_keys(result, preset.as_dict()))
    result.update(shear_keys(result, summary.summary.geom.wall_area))
    result.update(_wear_keys(result, preset.as_dict()))
    return with_units(result)


def _wear_keys(result: dict, config: dict) -> dict:
    """Wear per unit wear coefficient (taimill.outcome.wear.wear_keys)."""
    from taimill.outcome.dose import powder_grams
    from taimill.outcome.wear import wear_keys
    from taimill.outcome.wearfiles import bodies

    return wear_keys(result, *bodies(config), powder_grams(config))


class SpectraOnly(Relay):
    """The caller's sink of a run that keeps the events' spectra, not their rows
    (outputs.events = "spectra"): the summary still sees every event."""

    def events(self, block):
        pass


class WholeLaunches(Relay):
    """Hands each launch to the sinks whole: a launch's drain sends its events, then
    frames, then ledger rows (physics.runner; frames and ledger rows only when the
    launch took a frame), and SIGTERM or Ctrl-C arriving meanwhile waits until
    `launch_done()` after the drain (signals.hold), so the store and the summary hold
    the same launches. (The hold once ended with the ledger rows: a 10⁵-ball run whose
    launches took no frame held it from launch to launch, and Ctrl-C waited 18 s.)"""

    def __init__(self, sink):
        super().__init__(sink)
        self.holding = False

    def _hold(self):
        if not self.holding:
            signals.hold()
            self.holding = True

    def events(self, block):
        self._hold()
        self.sink.events(block)

    def frames(self, block):
        self._hold()
        self.sink.frames(block)

    def energy(self, block):
        self._hold()
        self.sink.energy(block)

    def spectra(self, spectra):
        self._hold()
        super().spectra(spectra)

    def launch_done(self):
        """The drain is over: an interrupt that waited is raised here, between launches."""
        if self.holding:
            self.holding = False
            signals.release()

    def finish(self, summary, status):
        if self.holding:
            self.holding = False
            signals.drop_hold()
        self.sink.finish(summary, status)


def run(preset, sink=None, *, duration: float | None = None, progress=None, stage=None, notice=None) -> dict:
    """Simulate one preset; streams to `sink`; returns the run summary (docs/outputs.md).
    Ctrl-C and SIGTERM (signals.sigterm_interrupts) end it with status "interrupted",
    any other error with "failed: …"; the sink is finished either way. `progress(t)`
    gets the simulated time after every launch, `stage(text)` each set-up phase as it
    begins (seconds each for 10⁵ balls: the CLI's progress bar shows them), `notice(text)`
    what the caller should say in a line of its own: the kernels are compiled, and for
    how long (physics.runner.CompilePlan). The summary's wall time and speed leave the
    set-up and compiling out (Runner.setup_seconds)."""
    stage = stage or (lambda text: None)

    def on_compile(plan):
        stage(plan.text() + "…")
        if notice:
            notice(plan.text())
    sink = sink or NullSink()
    n = preset.balls.count
    if preset.initial_positions is None:
        stage(f"placing {n} balls…")
    spec = from_preset(preset, duration)
    stage(f"setting up {n} balls: summary, store, Taichi fields…")
    summary, out = start_point(preset, spec, sink)
    out = WholeLaunches(out)
    runner = Runner([spec], on_compile=on_compile)
    stage("first neighbour lists, first launch…")
    t0 = time.perf_counter()
    status = "complete"
    def after_launch(t):
        out.launch_done()
        signals.check()
        if progress:
            progress(t)

    with sigterm_interrupts():
        try:
            signals.check()  # a Ctrl-C that landed in the kernels' imports or compiling
            runner.run([out], after_launch)
        except SimulationUnstable as err:
            status = f"unstable: {err}"
            raise
        except KeyboardInterrupt:
            status = "interrupted"
            raise
        except Exception as err:
            status = f"failed: {err}"
            raise
        finally:
            result = point_result(preset, spec, summary, runner, 0, time.perf_counter() - t0, status)
            out.finish(result, status)
    return result


def compile_texts(job_chunks) -> list[str]:
    """What the worker processes of a sweep compile before they simulate, one line per
    engine shape (physics.runner.CompilePlan.text): each worker compiles each shape of
    the chunks it runs once. `job_chunks`: lists of executors.Job."""
    from taimill.physics.runner import compile_plan

    texts = {}
    for chunk in job_chunks:
        shape = (len(chunk), chunk[0].preset.balls.count, chunk[0].preset.jar.source)
        if shape not in texts:
            texts[shape] = compile_plan([from_preset(j.preset) for j in chunk]).text()
    return list(dict.fromkeys(texts.values()))
