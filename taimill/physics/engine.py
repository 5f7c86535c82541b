"""Kernels and their launcher: `Engine` advances B independent mills.

Two launch modes share every physics function:
- fused: one kernel runs ≥ 10⁴ steps of every mill, the time loop inside the kernel,
  one mill per CPU task (the loop is padded by PAD so that Taichi's ≥ 512-iteration
  CPU tasks put different mills on different threads: unpadded, B ≤ 512 mills share one);
- parallel: one large mill (B = 1), one launch per step (its phases loops over the
  balls on all cores), the lists rebuilt between launches when stale. Used where the
  per-step work dwarfs the launch (≈ 35 µs, ≈ 100 µs after a step of 10⁵ balls has
  moved Taichi's and Python's own data out of the caches).
"""


import sys

import numpy as np

from taimill.physics import state as S
from taimill.physics.neighbours import rebuild_parallel, rebuild_serial
from taimill.physics.contacts import ball_forces
from taimill.physics.pool import keep_open_mask, pool_settle, release_rows
from taimill.physics.frame import drive_turning, psi_at, steady, ramp_turn
from taimill.physics.integrator import frame_acceleration, integrate
from taimill.physics.snapshot import frame_ball, frame_record, ledger_block, snapshot, sum_blocks
from taimill.physics.ti import ti, where

PAD = 512
PSI_RESYNC = 4096  # steps between exact evaluations of cos ψ, sin ψ (psi_trig)


@ti.func
def drive(F: ti.template(), b, t):
    """The drive of mill b over [t, t + dt] with the step's four angles' cos and sin
    kept where they can be: the jar's turn while it repeats to the bit (every step at
    constant speed), ψ by a rotation recurrence (psi_trig)."""
    dt = F.model.dt[b]
    turn = ramp_turn(F.model.jar_ramp[b], t, dt)
    trig = F.state.turn_trig[b]
    if trig[0] != turn:
        trig = ti.Vector([turn, ti.cos(turn), ti.sin(turn)])
        F.state.turn_trig[b] = trig
    cpsi, spsi = psi_trig(F, b, t, dt)
    return drive_turning(F.model.plate_ramp[b], F.model.jar_ramp[b], t, dt, trig[1], trig[2], cpsi, spsi)


@ti.func
def psi_trig(F: ti.template(), b, t, dt):
    """cos ψ, sin ψ at t. Once both ramps have reached their end speeds ψ grows by
    δ = (Ω - w) dt a step, and the values of the step before are turned by δ (4
    multiplications instead of two libm calls, 9 % of a 12-ball step); every
    PSI_RESYNC steps, and whenever the record is not of the step before, they are
    computed from ψ(t). The record (F.state.psi_rec: t, cos, sin) serves every call of a step
    (parallel mode calls this once per phase). Drift: a rounding of the rotation a
    step, ≤ 1e-12 relative over PSI_RESYNC steps, below the rounding of ψ(t) itself
    (|ψ| ε ≈ 4e-13 rad at ψ = 2000 rad)."""
    plate, jar = F.model.plate_ramp[b], F.model.jar_ramp[b]
    rec = F.state.psi_rec[b]
    step = F.state.step[b]  # t = step dt, as every caller computes it
    prev = (step - 1) * dt  # the step before's t, computed as it was
    if rec[0] != t:
        if (rec[0] == prev and step % PSI_RESYNC != 0 and steady(plate, prev) and steady(jar, prev)):
            delta = (plate[2] - jar[2]) * dt
            rot = F.state.psi_rot[b]
            if rot[0] != delta:
                rot = ti.Vector([delta, ti.cos(delta), ti.sin(delta)])
                F.state.psi_rot[b] = rot
            rec = ti.Vector([t, rec[1] * rot[1] - rec[2] * rot[2], rec[2] * rot[1] + rec[1] * rot[2]])
        else:
            psi = psi_at(plate, jar, t)
            rec = ti.Vector([t, ti.cos(psi), ti.sin(psi)])
        F.state.psi_rec[b] = rec
    return rec[1], rec[2]


@ti.func
def can_step(F: ti.template(), b, margin):
    """The next step of mill b may run: it is due, the event buffer has room for the
    worst step, and the frame buffer for its frame if it takes one (so a launch of
    frame_capacity × frame_every steps from a frame step fills the buffer exactly:
    Runner)."""
    ok = F.state.status[b] == S.OK and F.state.step[b] < F.model.target[b] and F.out.n_events[b] + margin <= F.event_capacity
    if ok and F.out.n_frames[b] >= F.frame_capacity:  # (Taichi evaluates both sides of `and`: no modulo per step)
        ok = F.state.step[b] % F.model.frame_every[b] != 0
    return ok


@ti.func
def step_mill(F: ti.template(), b, use_grid: ti.template()):
    """One time step of mill b: neighbour lists if stale, forces, frame (its stored
    energy is that of the forces just computed), integration."""
    dt = F.model.dt[b]
    st = F.state.step[b]
    t = st * dt
    dr = drive(F, b, t)
    if F.spatial.rebuild[b]:
        rebuild_serial(F, b, use_grid)
    for i in range(F.model.n_balls[b]):
        ball_forces(F, b, i, t, dr, dt)
    if st % F.model.frame_every[b] == 0:
        snapshot(F, b, t, dr)
    pool_settle(F, b)
    a_frame = frame_acceleration(F, b, dr)
    for i in range(F.model.n_balls[b]):
        integrate(F, b, i, dr, dt, a_frame)
        release_rows(F, b, i)
    F.state.step[b] = st + 1


@ti.kernel
def advance_fused(F: ti.template(), n_steps: ti.i32, margin: ti.i32, use_grid: ti.template()):
    for task in range(F.B * PAD):
        if task % PAD == 0:
            b = task // PAD
            for _ in range(n_steps):
                if not can_step(F, b, margin):
                    break
                step_mill(F, b, use_grid)


@ti.kernel
def rebuild_fused(F: ti.template(), use_grid: ti.template()):
    for task in range(F.B * PAD):
        if task % PAD == 0:
            rebuild_serial(F, task // PAD, use_grid)


# ---- parallel mode (b = 0): a step is one launch, its phases the kernel's loops
GO, STALE, FRAME = 1, 2, 4


@ti.func
def flags(F: ti.template(), margin, last):
    """0 (stop: at step `last`, done, a fault, or a buffer full) or GO, plus STALE if
    the lists need a rebuild before the next step, FRAME if it takes a frame."""
    go = 0
    if can_step(F, 0, margin) and F.state.step[0] < last:
        go = GO + STALE * F.spatial.rebuild[0]
        if F.state.step[0] % F.model.frame_every[0] == 0:
            go += FRAME
    return go


@ti.kernel
def step_flags(F: ti.template(), margin: ti.i32, last: ti.i64) -> ti.i32:
    return flags(F, margin, last)


step_flags.serial_kernel = True  # one thread, whatever the thread count (scripts/bench_kernels.py)


@ti.kernel
def step_parallel(F: ti.template(), margin: ti.i32, last: ti.i64, steps: ti.template(),
                  with_frame: ti.template()) -> ti.i32:
    """Up to `steps` steps of the large mill in one launch (unrolled: each step's phases
    are loops over the balls on every thread), then the flags of the next (flags). A
    step that may not run does nothing, and neither do the launch's later ones: at a
    stop, stale lists (the launcher rebuilds them) or, unless `with_frame`, a frame
    (the launcher takes that step alone with_frame). Every loop of a kernel costs a
    dispatch to the threads even when it has nothing to do (≈ 47 µs on the 2-core
    machine): the frame's loops are in the frame steps' kernel only."""
    for _ in ti.static(range(steps)):
        one_step(F, margin, last, with_frame)
    return flags(F, margin, last)


@ti.func
def one_step(F: ti.template(), margin, last, with_frame: ti.template()):
    """One step of the large mill: forces, the frame (with_frame), integration. The
    scalars between the loops run on one thread: a few dozen operations a step."""
    dt = F.model.dt[0]
    st = F.state.step[0]
    t = st * dt
    due = st % F.model.frame_every[0] == 0
    go = 0
    if can_step(F, 0, margin) and st < last and (ti.static(with_frame) or not due):
        go = 1 - F.spatial.rebuild[0]
    n = F.model.n_balls[0]
    dr = drive(F, 0, t)
    for i in range(n * go):
        ball_forces(F, 0, i, t, dr, dt)
    if ti.static(with_frame):
        frame = go * due
        k = F.out.n_frames[0]
        for u in range(n * frame):
            frame_ball(F, 0, k, u)
        for blk in range(sum_blocks(F, 0) * frame):
            F.out.ledger_part[blk] = ledger_block(F, 0, blk, dr)
        if frame:
            sums = F.out.ledger_part[0]
            for blk in range(1, sum_blocks(F, 0)):
                sums += F.out.ledger_part[blk]
            frame_record(F, 0, k, t, sums)
    pool_settle(F, 0)
    a_frame = frame_acceleration(F, 0, dr)
    for i in range(n * go):
        integrate(F, 0, i, dr, dt, a_frame)
        release_rows(F, 0, i)  # after the force pass, the only one that takes rows
        keep_open_mask(F, 0, i)
    if go:
        F.state.step[0] = st + 1


# ---- draining the output buffers
@ti.kernel
def export_events(F: ti.template(), b: ti.i32, n: ti.i32, out: ti.types.ndarray()):
    for e, c in ti.ndrange(n, S.NCOL):
        out[e, c] = F.out.events[b, e][c]


@ti.kernel
def export_frames(F: ti.template(), b: ti.i32, n: ti.i32, nb: ti.i32, t: ti.types.ndarray(),
                  x: ti.types.ndarray(), v: ti.types.ndarray(), s: ti.types.ndarray(), ledger: ti.types.ndarray(),
                  drive: ti.types.ndarray()):
    for k in range(n):
        t[k] = F.out.frame_t[b, k]
        for c in ti.static(range(len(S.DRIVE_FIELDS))):
            drive[k, c] = F.out.frame_drive[b, k][c]
        for c in ti.static(range(len(S.LEDGER_FIELDS))):
            ledger[k, c] = F.out.frame_ledger[b, k][c]
        for i in range(nb):
            for c in ti.static(range(3)):
                x[k, i, c] = F.out.frame_x[b, k, i][c]
                v[k, i, c] = F.out.frame_v[b, k, i][c]
                s[k, i, c] = F.out.frame_s[b, k, i][c]


class Engine:
    """Allocates the fields of B mills × N balls and advances them.

    `mode` is "fused" or "parallel" (B = 1 only); `use_grid` builds the neighbour lists
    from the spatial hash instead of all pairs (identical lists, tests/test_neighbours;
    the Runner builds small mills' lists from all pairs, 7 % faster at 12 balls:
    runner.ALL_PAIRS_UP_TO).

    Each mill's ball rows are padded to a multiple of BALL_PAD so that two mills never
    share a cache line: unpadded 12-ball mills on two threads ran 2-4x slower than one.
    Output buffers are sized to about BUFFER_BYTES per mill. In parallel mode (10⁵-10⁶
    balls) they are bounded by LARGE_FRAME_BYTES and LARGE_EVENT_BYTES instead of
    growing with N: the launcher drains after every launch, and a launch stops at a
    full frame buffer (one frame of 10⁶ balls is 72 MB). `pool`: rows of each mill's
    open-contact pool (default state.pool_rows; tests force a small one). `reorder`:
    keep the ball rows in grid order (reorder.py; parallel mode only, its default);
    read balls through `ball_rows` and `neighbour_lists`, which give own indices.
    `models`: per contact type the ContactModels the kernels are compiled for
    (state.Fields; default the thesis' model).
    """

    BALL_PAD = 8  # f64 × 8 = 64 B
    BUFFER_BYTES = 64 << 20
    EVENT_ROWS = 1 << 14  # event buffer rows at least (×120 B)
    LARGE_FRAME_BYTES = 8 << 20  # frames buffered in parallel mode (at least one)
    LARGE_EVENT_BYTES = 32 << 20  # events buffered in parallel mode, half of them the per-step margin
    # parallel mode: a launch stops at this share of the event buffer. Peak RSS of a 10⁵-ball
    # drum (`taimill run`, one thread, 2000 steps, kernels cached; the CPU time did not
    # move): 1 (the whole buffer) 412 MiB, 8: 383, 32: 381; and with LARGE_FRAME_BYTES
    # 8 MiB instead of 16 (one frame of 10⁵ balls instead of two), 8: 376 MiB = 395 MB
    LAUNCH_EVENT_SHARE = 8
    # parallel mode: steps per launch (step_parallel). A launch costs ≈ 100-150 µs after a
    # step of 10⁵ balls (Taichi's and Python's own data are out of the caches by then):
    # 3 % of a step on one thread (4.4 ms). Each step more is one more copy of the force
    # pass to compile: 3.7 s CPU for one step, 18.2 for four (2-core AMD EPYC machine)
    STEPS_PER_KERNEL = 2
    # on a GPU the launch returns its flags, a wait for the device: four steps between
    # waits (a guess until a lent machine measures it: scripts/device_check.sh)
    STEPS_PER_KERNEL_ON_GPU = 4

    def __init__(self, batch, balls, *, mode="fused", use_grid=True, grid_cells=1, frame_capacity=256, pool=None,
                 reorder=None, models=None):
        if mode == "parallel" and batch != 1:
            raise ValueError("parallel mode runs one mill")
        reorder = mode == "parallel" if reorder is None else reorder
        self.mode, self.use_grid = mode, use_grid or mode == "parallel"
        n = -(-balls // self.BALL_PAD) * self.BALL_PAD
        # worst case: every open contact of every ball closes in one step
        self.margin = min(n * S.SLOTS, max(1 << 15, 2 * n))
        # room for a launch's events (Runner: 0.25 s at up to ≈ 50 000 events/s in a
        # dozen-ball mill) so a launch rarely stops early for a full buffer
        events = max(2 * self.margin, self.EVENT_ROWS)
        frames = int(max(4, min(frame_capacity, self.BUFFER_BYTES // (72 * n))))
        if mode == "parallel":  # a step that closes more events than the margin raises (drain)
            events = max(self.EVENT_ROWS, min(events, self.LARGE_EVENT_BYTES // (8 * S.NCOL)))
            self.margin = min(self.margin, events // 2)
            frames = int(max(1, min(frame_capacity, self.LARGE_FRAME_BYTES // (72 * n))))
        # a launch stops once more than 1/LAUNCH_EVENT_SHARE of the event buffer is used
        # (each of its steps still has `margin` rows free): what a drain copies (NumPy
        # rows, the sorted table, the sinks' share) stays small beside the mill's fields
        self.launch_margin = max(self.margin, events - max(1, events // self.LAUNCH_EVENT_SHARE))
        self.F = S.Fields(batch, n, events, frames, grid_cells, pool, share_pairs=mode == "fused", reorder=reorder,
                          models=models)
        self._spare: dict[int, list[np.ndarray]] = {}  # drain's frame arrays per mill (_frame_arrays)
        on_gpu = where()[0] == "cuda"
        self.steps_per_kernel = self.STEPS_PER_KERNEL_ON_GPU if on_gpu else self.STEPS_PER_KERNEL

    @property
    def B(self):
        return self.F.B

    def advance(self, n_steps: int):
        """Advance every unfinished mill by up to n_steps; stops early at a full buffer
        or a fault (the caller drains and calls again)."""
        F = self.F
        if self.mode == "fused":
            advance_fused(F, n_steps, self.margin, self.use_grid)
            return
        last = int(F.state.step[0]) + n_steps
        go = step_flags(F, self.launch_margin, last)
        while go:
            if go & STALE:
                rebuild_parallel(F)
            if go & FRAME:
                go = step_parallel(F, self.launch_margin, last, 1, True)
            else:
                go = step_parallel(F, self.launch_margin, last, self.steps_per_kernel, False)

    def build_lists(self):
        """Rebuild every neighbour list now (the step does it when they go stale)."""
        if self.mode == "fused":
            rebuild_fused(self.F, self.use_grid)
        else:
            rebuild_parallel(self.F)

    def own_order(self, b: int) -> np.ndarray:
        """Row of each ball of mill b, by own index (the identity unless F.reorder)."""
        n = int(self.F.model.n_balls[b])
        return self.F.state.row_of.to_numpy()[b, :n] if self.F.reorder else np.arange(n)

    def ball_rows(self, b: int, name: str) -> np.ndarray:
        """Per-ball field `name` (x, v, s, r, …) of mill b by own index."""
        return self.F.field(name).to_numpy()[b][self.own_order(b)]

    def neighbour_lists(self, b: int) -> list[list[int]]:
        """Each ball's neighbour list, by own index."""
        count = self.F.spatial.nbr_count.to_numpy()[b]
        nbr = self.F.spatial.nbr.to_numpy()[b]
        user = self.F.state.user_of.to_numpy()[b] if self.F.reorder else np.arange(len(count))
        return [[int(j) for j in user[nbr[i, : count[i]]]] for i in self.own_order(b)]

    def _frame_arrays(self, b: int, nf: int, nb: int) -> list[np.ndarray]:
        """Arrays for nf frames of mill b (time, position, velocity, spin, ledger, drive),
        every element of which the export writes. The arrays of mill b's previous drain
        are reused once nothing but this engine holds them or a view of them (a sink
        that keeps a block keeps them: then new ones): fresh arrays cost a page fault
        per 4 KiB on the export's first write, which at 10⁵ frames/s took 60 % of it
        (18 vs 7 ms per launch of 24 000 frames of 12 balls)."""
        shapes = [(), (nb, 3), (nb, 3), (nb, 3), (len(S.LEDGER_FIELDS),), (len(S.DRIVE_FIELDS),)]
        spare = self._spare.get(b)
        if (spare is None or any(spare[i].shape[1:] != row or len(spare[i]) < nf for i, row in enumerate(shapes))
                or not all(sys.getrefcount(spare[i]) <= 2 for i in range(len(spare)))):  # the list's + the call's
            spare = self._spare[b] = [np.empty((nf, *row)) for row in shapes]
        return [a[:nf] for a in spare]

    def spectra(self) -> tuple[np.ndarray, np.ndarray]:
        """Every mill's spectra so far: events and fixed-point energies [B, kind, class,
        measure, bin] (taimill.model.spectra)."""
        return self.F.out.spectrum_count.to_numpy(), self.F.out.spectrum_fixed.to_numpy()

    def drain(self, b: int):
        """Frames and events of mill b buffered since the last drain, as NumPy arrays;
        resets the buffers."""
        F = self.F
        nb = int(F.model.n_balls[b])
        ne = min(int(F.out.n_events[b]), F.event_capacity)
        nf = int(F.out.n_frames[b])
        ev = np.zeros((ne, S.NCOL))
        if ne:
            export_events(F, b, ne, ev)
        t, x, v, s, ledger, drive = self._frame_arrays(b, nf, nb)
        if nf:
            export_frames(F, b, nf, nb, t, x, v, s, ledger, drive)
        overflow = int(F.out.n_events[b]) > F.event_capacity
        F.out.n_events[b] = 0
        F.out.n_frames[b] = 0
        if overflow:
            raise RuntimeError(f"more than {self.margin} collision events ended in one step: event buffer overflow")
        frames = {"time": t, "position": x, "velocity": v, "spin": s}
        return frames | {k: drive[:, c] for c, k in enumerate(S.DRIVE_FIELDS)}, ev, ledger
