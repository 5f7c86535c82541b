"""One mill run interactively (the TUI's engine): advanced in short kernel chunks, with
speeds, friction, jar and ball count changed while it runs.

Physics of a live change (docs/model.md):
- A speed change starts a new smoothstep `Ramp` from the angular velocities and
  angles the drive has at the current simulated time, so Ω, w and the jar's angle are
  continuous and the Euler terms Ω̇, ẇ are real. (Ω̇ itself may jump when a change
  interrupts a ramp still in progress: the smoothstep starts from rest in Ω̇.)
- The automatic time step follows the speeds (`rules.running_dt`): it is chosen
  for the largest speed the new ramp passes through. The kernel computes t = step·dt,
  so a new dt is rounded down to dt' = t/n, n = ⌈t/dt_target⌉, and the step counter set
  to n: simulated time stays continuous to rounding (open contacts keep their onset
  times, ramps their t0).
- Drive ramps, time step and friction are field data the next step reads, written by
  the setters of `taimill.physics.mill`; the rules a change must keep are those of the
  preset loader (`taimill.model.rules`).
- Reset and a new jar or ball count restart the mill at t = 0 from the seeded placement,
  ramping from rest to the current speeds (a new charge cannot continue the old one).

Threads: a running kernel holds the GIL, so `advance` runs chunks of about
`chunk_seconds` of wall time. New Taichi fields must be materialised in the thread that
called ti.init: construct the LiveMill and call `rebuild` there (the UI thread);
`advance` and the setters may run in any thread — every change of the fields goes
through one lock (tunables are field data), and `advance` yields it between chunks to a waiting
setter.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
import time

import numpy as np

from taimill.errors import ConfigError, SimulationUnstable
from taimill.model import rules
from taimill.model.drive import Drive
from taimill.model.frame import Ramp
from taimill.model.materials import load_friction
from taimill.model.preset import KINDS, Preset, load_preset
from taimill.model.ranges import RANGES
from taimill.model.spec import from_preset
from taimill.physics.mill import set_clock, set_drive, set_friction
from taimill.physics.runner import Runner
from taimill.physics.ti import compute  # noqa: F401 - what runs the kernels, for the TUI's recordings
from taimill.store.sinks import FanOut

SOURCE = "TUI"  # names live input in ConfigError messages
FOREVER = 2**62  # step target of a live mill: it runs until stopped
CHUNK_SECONDS = 0.01  # wall s per kernel launch (measured: worst UI gap 132 ms at 10 ms)

# Live value -> its entry in the table of allowed ranges (taimill.model.ranges), which
# narrows some of them for a running mill.
LIVE_KEYS = {"plate_rpm": "plate_rpm", "ratio": "ratio", "jar_rpm": "jar_rpm", "mu_s": "mu_s", "mu_d": "mu_d",
             "mu_r": "mu_r", "ramp_time": "ramp_time", "balls": "balls.count"}
LIMITS = {key: RANGES[name].live_bounds for key, name in LIVE_KEYS.items()}  #: key -> [lo, hi]


def check(key: str, value) -> float:
    """value if it lies in the live range of key, else ConfigError naming key, value and range."""
    return RANGES[LIVE_KEYS[key]].check_live(SOURCE, key, value)


def wrap(angle: float) -> float:
    """Angle in [-π, π] (rad): ramps restart from it, so φ stays small after hours."""
    return math.remainder(angle, 2.0 * math.pi)


class LiveMill:
    """A `Runner` of one mill that runs until stopped and takes live changes.

    preset: the starting point (its speeds, friction, dt are kept up to date as
    `self.preset`); overrides: the command-line overrides it was loaded with (a rebuild
    reloads the preset file with them)."""

    def __init__(self, preset: Preset, overrides: dict | None = None, *, chunk_seconds: float = CHUNK_SECONDS):
        self.overrides = {k: v for k, v in (overrides or {}).items() if v is not None}
        self.chunk_seconds = chunk_seconds
        self._lock = threading.Lock()
        self._count_lock = threading.Lock()
        self._waiting = 0
        self.dt_fixed = None if preset.dt_auto else preset.dt  #: s, a preset's explicit dt
        self._sinks: list = []
        self._out = FanOut()
        self._step_cost = 1e-6  # wall s per step, refined by every chunk
        self._start(preset)

    # ------------------------------------------------------------------ set-up
    def _start(self, preset: Preset):
        """Load preset into a fresh Runner at t = 0 (speeds ramp up from rest)."""
        spec = from_preset(preset, preset.duration).replace(steps=FOREVER)
        self.preset = preset
        self.changes: list[dict] = []  #: live changes since t = 0 (for recordings)
        self.runner = Runner([spec])
        self.runner.engine.advance(0)  # compile / materialise now, in the calling thread
        self.plate, self.jar = spec.plate, spec.jar

    @property
    def spec(self):
        return self.runner.specs[0]

    @property
    def F(self):
        return self.runner.engine.F

    # ------------------------------------------------------------------ reading
    @property
    def time(self) -> float:
        """Simulated time, s."""
        return self.runner.time(0)

    @property
    def dt(self) -> float:
        return self.spec.dt

    @property
    def n_balls(self) -> int:
        return self.spec.n

    @property
    def radius(self) -> np.ndarray:
        return self.spec.radius

    @property
    def target(self) -> Drive:
        """The speeds the mill runs at or ramps to."""
        return self.preset.drive

    @property
    def plate_rpm(self) -> float:
        """Target plate speed Ω, rpm."""
        return self.target.plate_rpm

    @property
    def jar_rpm(self) -> float:
        """Target jar speed relative to the plate, ω = w - Ω, rpm."""
        return self.target.jar_rpm

    @property
    def ratio(self) -> float:
        """Target K = w/Ω (nan for Ω = 0)."""
        return self.target.ratio

    @property
    def friction(self):
        """Friction of ball-ball contacts."""
        return self.spec.friction

    @property
    def frictions(self):
        """(ball-ball, ball-wall) friction."""
        return self.spec.frictions

    def drive(self, t: float | None = None) -> dict:
        """Ω, Ω̇, φ_plate and w, ẇ, φ_jar (rad/s, rad/s², rad) at time t (default now)."""
        t = self.time if t is None else t
        om, om_dot, phi_p = self.plate.at(t)
        w, w_dot, phi_j = self.jar.at(t)
        return {"plate": om, "plate_accel": om_dot, "plate_angle": phi_p, "jar": w, "jar_accel": w_dot, "jar_angle": phi_j}

    def state(self, *, velocities: bool = False) -> dict:
        """The current state: time (s), position (N, 3) m in the jar frame, ψ =
        φ_plate - φ_jar (rad, the direction away from the plate axis), Ω and w now
        (rad/s); with velocities, also velocity (m/s, jar frame) and spin (rad/s)."""
        n = self.n_balls
        with self._locked():
            t = self.time
            rows = self.runner.engine.ball_rows  # by the ball's own index (parallel mode reorders rows)
            out = {"position": rows(0, "x")[:n]}
            if velocities:
                out |= {"velocity": rows(0, "v")[:n], "spin": rows(0, "s")[:n]}
        d = self.drive(t)
        return out | {"time": t, "psi": d["plate_angle"] - d["jar_angle"], "plate": d["plate"], "jar": d["jar"]}

    def config(self) -> dict:
        """The resolved configuration now (for a sink started mid-run), JSON-able."""
        return self.preset.as_dict() | {"live_start_time": self.time}

    # ------------------------------------------------------------------ sinks
    def add_sink(self, sink):
        """Stream everything from now on to sink: its start() gets the config at
        `live_start_time` = now, and the mill waits for it (so that nothing between is
        lost; call from a worker thread if opening the sink takes long)."""
        with self._locked():
            self._drain(report=False)  # what came before is not the new sink's
            sink.start(self.config(), self.n_balls, self.radius)
            self._sinks.append(sink)
            self._out = FanOut(*self._sinks)

    def remove_sink(self, sink):
        """Stop streaming to sink (the caller finishes it: nothing reaches it after this)."""
        with self._locked():
            self._drain(report=False)  # everything up to now reaches it
            if sink in self._sinks:
                self._sinks.remove(sink)
                self._out = FanOut(*self._sinks)

    # ------------------------------------------------------------------ running
    @contextlib.contextmanager
    def _locked(self):
        """The field lock; a setter announces itself so `advance` yields between chunks."""
        with self._count_lock:
            self._waiting += 1
        try:
            self._lock.acquire()
        finally:
            with self._count_lock:
                self._waiting -= 1
        try:
            yield
        finally:
            self._lock.release()

    def _chunk(self, max_steps: int) -> int:
        """One kernel launch of at most max_steps steps; returns the steps taken. The
        buffers are drained by `_drain`, or here once a launch stopped early (a full
        event or frame buffer, or a fault)."""
        while self._waiting:  # let a waiting setter in first (CPython locks are not fair)
            time.sleep(0.0005)
        with self._lock:
            room = (self.F.frame_capacity - 2 - int(self.F.out.n_frames[0])) * self.spec.frame_every
            n = max(1, min(max_steps, room, int(self.chunk_seconds / self._step_cost)))
            before = int(self.F.state.step[0])
            t0 = time.perf_counter()
            self.runner.engine.advance(n)
            wall = time.perf_counter() - t0
            taken = int(self.F.state.step[0]) - before
            if taken < n:
                self._drain()
        if taken:
            self._step_cost = 0.7 * self._step_cost + 0.3 * wall / taken
        return taken

    def _drain(self, report: bool = True):
        """Stream the buffered frames, events and ledger to the sinks (lock held);
        raises SimulationUnstable, if `report`, after streaming what came before a fault."""
        fault = self.runner.drain([self._out])[0]
        if fault and report:
            raise SimulationUnstable(fault)

    def advance(self, *, wall_budget: float | None = None, steps: int | None = None) -> float:
        """Run for about wall_budget wall seconds, or exactly `steps` steps, in kernel
        launches of ≈ chunk_seconds, then stream the results to the sinks; returns the
        simulated seconds advanced. Raises SimulationUnstable (everything up to the
        fault has reached the sinks)."""
        if (wall_budget is None) == (steps is None):
            raise ValueError("give wall_budget or steps")
        t_start, wall0 = self.time, time.perf_counter()
        left = steps
        while True:
            taken = self._chunk(left if steps is not None else FOREVER)
            if steps is not None:
                left -= taken
                if left <= 0:
                    break
            elif time.perf_counter() - wall0 >= wall_budget:
                break
        with self._locked():
            self._drain()
        return self.time - t_start

    # ------------------------------------------------------------------ live changes
    def set_speeds(self, plate_rpm: float | None = None, *, ratio: float | None = None,
                   jar_rpm: float | None = None, ramp_time: float | None = None):
        """New target speeds, reached by a smooth ramp from the current ones.
        plate_rpm: Ω; jar speed as ratio K = w/Ω or jar_rpm ω = w - Ω (relative to the
        plate); with neither, K is kept (ω when Ω was 0). ramp_time (s) defaults to
        the preset's start-up ramp."""
        rules.one_jar_speed(SOURCE, ratio, jar_rpm)
        mill = self.preset.mill
        given = {"plate_rpm": plate_rpm, "ratio": ratio, "jar_rpm": jar_rpm, "ramp_time": ramp_time}
        if plate_rpm is not None:  # the mill's plate speeds (the global cap where unknown)
            rules.plate_speed_fits(SOURCE, "plate_rpm", mill.plate_range.check_live(SOURCE, "plate_rpm", plate_rpm), mill)
        key = "jar_rpm" if jar_rpm is not None else "ratio"
        speed_given = ratio is not None or jar_rpm is not None
        if speed_given and mill.gear.kind == "fixed":
            rules.gear_ratio(SOURCE, key, given[key], mill)
        new = self.target.retarget(**{k: v if k == "plate_rpm" else check(k, v) for k, v in given.items() if v is not None})
        rules.jar_speed_fits(SOURCE, key, jar_rpm if jar_rpm is not None else new.ratio, new)
        if speed_given:
            rules.gear_ratio(SOURCE, key, given[key], mill, new)
        om, w, T = new.plate_omega, new.jar_spin, new.ramp_time
        dt = rules.running_dt(self.preset, self._peak(self.plate, om), self._peak(self.jar, w), self.dt_fixed)
        with self._locked():
            t = self.time
            d = self.drive(t)
            self.plate = Ramp(t, d["plate"], om, T, wrap(d["plate_angle"]))
            self.jar = Ramp(t, d["jar"], w, T, wrap(d["jar_angle"]))
            set_drive(self.F, 0, self.plate, self.jar)
            self.runner.specs[0] = self.spec.replace(plate=self.plate, jar=self.jar)
            self.preset = dataclasses.replace(self.preset, drive=new)
            self._set_dt(dt)
            self.changes.append({"time": t, "plate_rpm": self.plate_rpm, "ratio": self.ratio, "jar_rpm": self.jar_rpm,
                                 "ramp_time": T, "dt": self.dt})

    def _peak(self, ramp: Ramp, target: float) -> float:
        """Largest |speed| from now to the end of a new ramp to target (ramps are monotone)."""
        now = ramp.at(self.time)[0]
        still_ramping = self.time < ramp.t0 + ramp.duration
        return max(abs(now), abs(target), abs(ramp.end) if still_ramping else 0.0)

    def _set_dt(self, dt_target: float):
        """Switch to a step ≤ dt_target keeping t = step·dt (lock held)."""
        if math.isclose(dt_target, self.dt, rel_tol=1e-9):
            return
        t = self.time
        n = math.ceil(t / dt_target * (1 - 1e-12)) if t > 0 else 0
        dt = t / n if n else dt_target
        every = rules.frame_every(self.preset.trajectory_rate, dt)
        set_clock(self.F, 0, dt, n, every)
        self.runner.specs[0] = self.spec.replace(dt=dt, frame_every=every)
        self.preset = dataclasses.replace(self.preset, dt=dt)

    def set_friction(self, mu_s: float | None = None, mu_d: float | None = None, *, pair: str | None = None,
                     mu_r: float | None = None, kind: str | None = None):
        """Friction from now on, of one contact kind ("ball_ball" or "ball_wall") or of
        both (kind None): a pair's coefficients (same contact set as the balls and jar),
        then μ_s / μ_d / μ_r if given. μ_d ≤ μ_s."""
        if kind is not None and kind not in KINDS:
            raise ConfigError(SOURCE, "kind", kind, f"must be one of {', '.join(KINDS)} (or both)")
        base = None
        if pair is not None:
            base, contact = load_friction(pair, SOURCE)
            _, current = load_friction(self.preset.pair, SOURCE)
            rules.same_contact_set(SOURCE, "pair", pair, contact, current, "these balls and jar use")
        new = list(self.frictions)
        for ct, k in enumerate(KINDS):
            if kind not in (None, k):
                continue
            fr = base or new[ct]
            s_ = check("mu_s", mu_s) if mu_s is not None else fr.mu_s
            d_ = check("mu_d", mu_d) if mu_d is not None else fr.mu_d
            r_ = check("mu_r", mu_r) if mu_r is not None else fr.mu_r
            rules.friction_order(SOURCE, "mu_d", s_, d_)
            if (fr.tangential, fr.rolling) != (self.frictions[ct].tangential, self.frictions[ct].rolling):
                # the running kernels are compiled for the mill's sub-models (physics.state)
                raise ConfigError(SOURCE, "pair", pair, f"its sub-models ({fr.tangential}, {fr.rolling}) differ from the "
                                  f"running mill's ({self.frictions[ct].tangential}, {self.frictions[ct].rolling}); "
                                  "they are chosen in the preset")
            name = fr.name if (s_, d_, r_) == (fr.mu_s, fr.mu_d, fr.mu_r) else f"{(pair or self.preset.pair)} (tuned)"
            new[ct] = dataclasses.replace(fr, name=name, mu_s=s_, mu_d=d_, mu_r=r_)
        wall = new[1] if new[1] != new[0] else None
        with self._locked():
            for ct, fr in enumerate(new):
                set_friction(self.F, 0, fr, ct)
            self.runner.specs[0] = self.spec.replace(friction=new[0], wall_friction=wall)
            self.preset = dataclasses.replace(self.preset, friction=new[0], wall_friction=wall,
                                              pair=pair if pair is not None and kind is None else self.preset.pair)
            fr = new[0] if kind is None else new[KINDS.index(kind)]
            change = {"time": self.time, "pair": self.preset.pair, "mu_s": fr.mu_s, "mu_d": fr.mu_d, "mu_r": fr.mu_r}
            self.changes.append(change if kind is None else change | {"kind": kind})

    def reset(self):
        """Back to t = 0: the seeded placement, ramping from rest to the current targets."""
        with self._locked():
            p = self.preset
            self._start(dataclasses.replace(p, dt=rules.running_dt(p, p.drive.plate_omega, p.drive.jar_spin, self.dt_fixed)))

    def rebuilt(self, *, jar: str | None = None, balls: int | None = None) -> Preset:
        """The preset of a new jar (a bundled name or a path) and/or ball count with the
        current speeds and friction, validated (ConfigError); nothing changes yet."""
        p = self.preset
        if balls is not None:
            check("balls", balls)
        over = {**self.overrides, "jar": jar or self.overrides.get("jar"), "balls.count": balls or p.balls.count,
                "balls.filling": None}  # the count as it is now, whether the preset gave a count or a filling
        try:
            new = load_preset(p.source, over)
        except ConfigError as err:
            raise (ConfigError(SOURCE, err.key, err.value, err.allowed) if err.source == "command line" else err) from None
        d = p.drive
        new = dataclasses.replace(new, drive=d, dt=rules.running_dt(new, d.plate_omega, d.jar_spin, self.dt_fixed))
        if load_friction(new.pair, SOURCE)[1] == load_friction(p.pair, SOURCE)[1]:
            new = dataclasses.replace(new, friction=p.friction, wall_friction=p.wall_friction, pair=p.pair)
        return new

    def restart(self, preset: Preset):
        """Start over at t = 0 from preset (see `rebuilt`). Call from the ti.init thread:
        a ball count beyond the padded capacity of the current engine allocates new fields."""
        with self._locked():
            self._start(preset)
        self.overrides.update({"jar": preset.jar.source, "balls.count": preset.balls.count})

    def rebuild(self, *, jar: str | None = None, balls: int | None = None):
        """A new jar and/or ball count, restarting at t = 0 with the current speeds and friction."""
        self.restart(self.rebuilt(jar=jar, balls=balls))
