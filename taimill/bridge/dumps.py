"""LIGGGHTS dumps back into a taimill run store (docs/liggghts.md).

A LIGGGHTS case exported by `taimill.bridge.liggghts` dumps the balls in the ground
frame. `import_case` turns them into a normal run store:

- frames in the jar frame, per the store's conventions (docs/outputs.md): position
  about the jar axis, velocity relative to the rotating jar frame, absolute spin in
  jar-frame components; the frame's drive (plate and jar angles and speeds) per frame
  from the same ramps the deck moves the mesh with;
- collision events *reconstructed from the frames* (`reconstruct_events`): LIGGGHTS
  does not write collision events, so a contact is found between two dumps — by the
  ball's free flight from the earlier dump (exact in the ground frame while it touches
  nothing: a straight line under gravity), else by the overlap seen at the later dump
  — with its onset speeds u̇n, u̇t from the earlier dump's velocities and spins carried
  to the touch. Impacts shorter than a dump interval are found; several contacts of a
  pair within one interval count once; a contact already open at a dump continues.
  The store's `events_source` attribute says so, and which columns are not known;
- no energy ledger: drive work and dissipation are not in the dumps, and a ledger
  without them would not balance. The table is empty and `energy_source` says why.

NumPy only.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from taimill.analysis.rungeometry import FLOOR, LID, SIDE, RunGeometry
from taimill.analysis.summary import SummarySink
from taimill.bridge.liggghts import FORMAT, MANIFEST
from taimill.errors import ConfigError
from taimill.schema import EVENT_COLUMNS
from taimill.store.writer import ZarrSink
from taimill.store.sinks import FanOut

EVENTS_SOURCE = ("reconstructed from frames at dump resolution: a contact is found between two frames by "
                 "the ball's free flight from the earlier frame (or the overlap at the later one); onset u̇n, "
                 "u̇t from the earlier frame's velocities and spins carried to the touch; several contacts of a "
                 "pair within one frame interval count once; duration is an upper bound (to the first frame "
                 "without overlap), peak_penetration the largest overlap seen in frames (0 if none); "
                 "peak_force, dissipated_normal and dissipated_friction are not known and stored as 0")
UNKNOWN_EVENT_COLUMNS = ("peak_force", "dissipated_normal", "dissipated_friction")
ENERGY_SOURCE = ("empty: the dumps hold no drive work and no dissipation, and a ledger without them cannot "
                 "balance")
BISECTIONS = 40
SAMPLE_SPACING = 50e-6  #: s, flight samples against the wall (at least 8 per interval)


# ---------------------------------------------------------------- dump files
def read_dump(path) -> tuple[np.ndarray, list[str], np.ndarray]:
    """(timesteps (F,), column names, values (F, N, C)) of a LAMMPS/LIGGGHTS text dump
    (`dump custom`), each snapshot sorted by atom id; a last snapshot cut short (the run
    was killed while it dumped) is left out. ConfigError if the atom count changes
    (atoms were lost)."""
    steps, snaps, columns, count = [], [], None, None
    with open(path) as f:
        lines = iter(f)
        try:
            for line in lines:
                if line.startswith("ITEM: TIMESTEP"):
                    step = int(next(lines))
                elif line.startswith("ITEM: NUMBER OF ATOMS"):
                    n = int(next(lines))
                    if count is None:
                        count = n
                    elif n != count:
                        raise ConfigError(path, "NUMBER OF ATOMS", n, f"{count} atoms at the start: atoms were lost "
                                          f"by timestep {step}")
                elif line.startswith("ITEM: ATOMS"):
                    columns = line.split()[2:]
                    rows = np.array([next(lines).split() for _ in range(count)], dtype=float)
                    if rows.shape != (count, len(columns)):
                        break
                    snaps.append(rows[np.argsort(rows[:, columns.index("id")])])
                    steps.append(step)
        except (StopIteration, ValueError):  # a snapshot cut short (a run killed while dumping): dropped
            pass
    if not snaps:
        raise ConfigError(path, "dump", str(path), "holds no snapshot (did LIGGGHTS run?)")
    return np.array(steps), columns, np.array(snaps)


# ---------------------------------------------------------------- frames
def _drive(ramp, t) -> tuple[np.ndarray, np.ndarray]:
    """(speed, angle) of a taimill Ramp at times t (any shape)."""
    speed, _, angle = np.vectorize(ramp.at, otypes=[float, float, float])(np.asarray(t, dtype=float))
    return speed, angle


def _rotation(phi) -> np.ndarray:
    """(..., 3, 3): jar basis -> ground basis for jar angles phi."""
    c, s = np.cos(phi), np.sin(phi)
    z, o = np.zeros_like(phi), np.ones_like(phi)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


class Frames:
    """The jar frame's drive at given times (from a run's config) and the conversions
    between the ground frame of LIGGGHTS and taimill's jar frame (docs/outputs.md)."""

    def __init__(self, geom: RunGeometry, t):
        self.t = np.asarray(t, dtype=float)
        self.plate_speed, self.plate_angle = _drive(geom.plate, self.t)
        self.jar_spin, self.jar_angle = _drive(geom.jar, self.t)
        rp = geom.plate_radius
        cp, sp = np.cos(self.plate_angle), np.sin(self.plate_angle)
        z = np.zeros_like(cp)
        self.centre = rp * np.stack([cp, sp, z], -1)
        self.centre_velocity = (self.plate_speed * rp)[..., None] * np.stack([-sp, cp, z], -1)
        self.rot = _rotation(self.jar_angle)

    def _e(self, a):
        """Broadcast per-time arrays over a ball axis."""
        return a[..., None, :] if a.ndim == self.t.ndim + 1 else a[..., None, :, :]

    def to_jar(self, xg, vg, sg):
        """Ground-frame (…, N, 3) position, velocity, spin -> jar frame (docs/outputs.md)."""
        rot = self._e(self.rot)
        x = np.einsum("...ij,...i->...j", rot, xg - self._e(self.centre))
        u = np.einsum("...ij,...i->...j", rot, vg - self._e(self.centre_velocity))
        w = self.jar_spin[..., None]
        v = u - np.stack([-w * x[..., 1], w * x[..., 0], np.zeros_like(x[..., 0])], -1)
        s = np.einsum("...ij,...i->...j", rot, sg)
        return x, v, s

    def to_ground(self, x, v, s):
        """Inverse of `to_jar`."""
        rot = self._e(self.rot)
        w = self.jar_spin[..., None]
        u = v + np.stack([-w * x[..., 1], w * x[..., 0], np.zeros_like(x[..., 0])], -1)
        xg = np.einsum("...ij,...j->...i", rot, x) + self._e(self.centre)
        vg = np.einsum("...ij,...j->...i", rot, u) + self._e(self.centre_velocity)
        return xg, vg, np.einsum("...ij,...j->...i", rot, s)

    def positions_to_jar(self, xg):
        """Ground-frame positions (…, N, 3) -> jar frame."""
        return np.einsum("...ij,...i->...j", self._e(self.rot), xg - self._e(self.centre))

    def block(self, x, v, s) -> dict:
        """A frames block of the store (jar-frame states and the drive columns)."""
        return {"time": self.t, "position": x, "velocity": v, "spin": s, "plate_angle": self.plate_angle,
                "plate_speed": self.plate_speed, "jar_angle": self.jar_angle, "jar_spin": self.jar_spin}


# ---------------------------------------------------------------- events
def _wall_gaps(geom: RunGeometry, radii, x) -> np.ndarray:
    """(…, N, 3) gaps (m, < 0 overlapping) of balls at jar-frame x to side, floor, lid."""
    shape = x.shape[:-1]
    phi = geom.sdf(x.reshape(-1, 3)[:, :2])[0].reshape(shape)
    z = x[..., 2]
    return np.stack([phi - radii, z - radii, geom.height - z - radii], -1)


def _pairs(n):
    return np.triu_indices(n, 1)


def _ball_gaps(radii, x) -> np.ndarray:
    """(…, P) gaps of every ball pair i < j (m, < 0 overlapping)."""
    i, j = _pairs(x.shape[-2])
    return np.linalg.norm(x[..., j, :] - x[..., i, :], axis=-1) - (radii[i] + radii[j])


def reconstruct_events(geom: RunGeometry, radii, mass, t, xg, vg, sg, gravity: float, *, samples: int | None = None
                       ) -> dict:
    """Collision events (EVENT_COLUMNS) between consecutive frames (module doc). t (F,)
    s; xg, vg, sg (F, N, 3) ground-frame positions, velocities, absolute spins."""
    radii, mass = np.asarray(radii, float), np.asarray(mass, float)
    F, N = xg.shape[:2]
    fr = Frames(geom, t)
    xj = fr.positions_to_jar(xg)
    wall_gap = _wall_gaps(geom, radii, xj)  # (F, N, 3)
    ball_gap = _ball_gaps(radii, xg)  # (F, P)
    rows = []
    if F < 2:
        return _empty()
    dt = np.diff(t)
    g = np.array([0.0, 0.0, gravity])
    # ---- ball-ball: relative free flight is a straight line (gravity cancels)
    pi, pj = _pairs(N)
    d0 = xg[:-1, pj] - xg[:-1, pi]
    dv = vg[:-1, pj] - vg[:-1, pi]
    reach = radii[pi] + radii[pj]
    a = np.einsum("fpk,fpk->fp", dv, dv)
    b = 2.0 * np.einsum("fpk,fpk->fp", d0, dv)
    c = np.einsum("fpk,fpk->fp", d0, d0) - reach**2
    disc = b * b - 4 * a * c
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = np.where((disc >= 0) & (b < 0) & (a > 0), (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
    free = ball_gap[:-1] > 0
    flight = free & (tau > 0) & (tau <= dt[:, None])
    seen = free & ~flight & (ball_gap[1:] <= 0)  # touched, but not in free flight: from the overlap
    lin = ball_gap[:-1] / np.where(ball_gap[:-1] - ball_gap[1:] > 0, ball_gap[:-1] - ball_gap[1:], 1.0)
    tau = np.where(flight, tau, np.where(seen, lin * dt[:, None], np.nan))
    for k, p in zip(*np.nonzero(flight | seen)):
        rows.append(("bb", k, int(pi[p]), int(pj[p]), p, tau[k, p]))
    # ---- ball-wall: the ball's ground-frame flight, the wall's exact motion
    # samples of the flight per interval: every SAMPLE_SPACING, at least 8
    S = samples or int(np.clip(math.ceil(dt.max() / SAMPLE_SPACING), 8, 256))
    chunk = max(1, int(4e6 // (S * N)))
    cand = []
    for k0 in range(0, F - 1, chunk):
        k1 = min(k0 + chunk, F - 1)
        frac = np.arange(1, S + 1) / S
        tt = t[k0:k1, None] + dt[k0:k1, None] * frac  # (K, S)
        ts = (tt - t[k0:k1, None])[..., None, None]
        path = xg[k0:k1, None] + vg[k0:k1, None] * ts - 0.5 * g * ts**2  # (K, S, N, 3)
        xs = Frames(geom, tt).positions_to_jar(path)
        gaps = _wall_gaps(geom, radii, xs)  # (K, S, N, 3)
        start = wall_gap[k0:k1, None] > 0  # (K, 1, N, 3)
        hit = (gaps <= 0) & start
        first = np.where(hit.any(1), hit.argmax(1), -1)  # (K, N, 3)
        for k, i, w in zip(*np.nonzero(first >= 0)):
            s = first[k, i, w]
            cand.append((k0 + k, i, w, (s / S), (s + 1) / S))
        late = (first < 0) & (wall_gap[k0 + 1:k1 + 1] <= 0) & (wall_gap[k0:k1] > 0)
        for k, i, w in zip(*np.nonzero(late)):
            g0, g1 = wall_gap[k0 + k, i, w], wall_gap[k0 + k + 1, i, w]
            rows.append(("bw", k0 + k, i, w, None, dt[k0 + k] * g0 / (g0 - g1)))
    if cand:
        k, i, w, lo, hi = (np.array(v) for v in zip(*cand))
        lo, hi = lo * dt[k], hi * dt[k]
        for _ in range(BISECTIONS):
            mid = 0.5 * (lo + hi)
            pos = xg[k, i] + vg[k, i] * mid[:, None] - 0.5 * g * mid[:, None] ** 2
            xs = Frames(geom, t[k] + mid).positions_to_jar(pos[:, None])[:, 0]
            gap = _wall_gaps(geom, radii[i][:, None], xs[:, None])[:, 0][np.arange(len(k)), w]
            inside = gap <= 0
            hi, lo = np.where(inside, mid, hi), np.where(inside, lo, mid)
        rows += [("bw", int(a), int(b), int(c), None, float(d)) for a, b, c, d in zip(k, i, w, hi)]
    if not rows:
        return _empty()
    return _event_table(rows, geom, radii, mass, t, xg, vg, sg, g, ball_gap, wall_gap)


def _empty() -> dict:
    return {k: np.zeros(0, dtype=dtype) for k, (dtype, _, _) in EVENT_COLUMNS.items()}


def _event_table(rows, geom, radii, mass, t, xg, vg, sg, g, ball_gap, wall_gap) -> dict:
    kinds = np.array([r[0] == "bw" for r in rows])
    k = np.array([r[1] for r in rows])
    i = np.array([r[2] for r in rows])
    other = np.array([r[3] for r in rows])  # partner ball, or wall 0 side, 1 floor, 2 lid
    tau = np.array([r[5] for r in rows], dtype=float)
    ts = t[k] + tau
    fr = Frames(geom, ts)
    # states at the touch, free flight from frame k
    xi = xg[k, i] + vg[k, i] * tau[:, None] - 0.5 * g * tau[:, None] ** 2
    vi = vg[k, i] - g * tau[:, None]
    si = sg[k, i]
    xj_i, vj_i, sj_i = fr.to_jar(xi[:, None], vi[:, None], si[:, None])
    xj_i, vj_i, sj_i = xj_i[:, 0], vj_i[:, 0], sj_i[:, 0]
    w = fr.jar_spin
    rel_spin = sj_i - np.column_stack([np.zeros_like(w), np.zeros_like(w), w])
    n = np.zeros_like(xj_i)
    ri = radii[i]
    vrel = np.zeros_like(xj_i)
    meff = np.zeros(len(rows))
    body_j = np.where(kinds, np.choose(np.where(kinds, other, 0), [SIDE, FLOOR, LID]), other)
    # walls (at rest in the jar frame)
    wall = kinds
    if wall.any():
        side = wall & (other == 0)
        grad = geom.sdf(xj_i[side, :2])[1]
        n[side] = np.column_stack([-grad, np.zeros(side.sum())])
        n[wall & (other == 1)] = [0.0, 0.0, -1.0]
        n[wall & (other == 2)] = [0.0, 0.0, 1.0]
        vrel[wall] = vj_i[wall] + np.cross(rel_spin[wall], ri[wall, None] * n[wall])
        meff[wall] = mass[i[wall]]
    # ball pairs (in the ground frame, then the normal into the jar basis)
    bb = ~kinds
    if bb.any():
        j = other[bb]
        xjb = xg[k[bb], j] + vg[k[bb], j] * tau[bb, None] - 0.5 * g * tau[bb, None] ** 2
        d = xjb - xi[bb]
        ng = d / np.linalg.norm(d, axis=1, keepdims=True)
        vr = (vi[bb] + np.cross(si[bb], ri[bb, None] * ng)
              - (vg[k[bb], j] - g * tau[bb, None] + np.cross(sg[k[bb], j], -radii[j][:, None] * ng)))
        rot = fr.rot[bb]
        n[bb] = np.einsum("nij,ni->nj", rot, ng)
        vrel[bb] = np.einsum("nij,ni->nj", rot, vr)
        meff[bb] = mass[i[bb]] * mass[j] / (mass[i[bb]] + mass[j])
    un = np.einsum("ij,ij->i", vrel, n)
    ut = np.linalg.norm(vrel - un[:, None] * n, axis=1)
    point = xj_i + ri[:, None] * n
    # end: the first frame after the touch without overlap (an upper bound)
    pair_index = {(a, b): p for p, (a, b) in enumerate(zip(*_pairs(xg.shape[1])))}
    duration = np.full(len(rows), np.nan)
    peak = np.zeros(len(rows))
    for e in range(len(rows)):
        series = wall_gap[:, i[e], other[e]] if kinds[e] else ball_gap[:, pair_index[(i[e], other[e])]]
        after = series[k[e] + 1:]
        free = np.flatnonzero(after > 0)
        if len(free):
            end = k[e] + 1 + free[0]
            duration[e] = t[end] - ts[e]
            peak[e] = max(0.0, float(-after[:free[0]].min())) if free[0] > 0 else 0.0
    keep = np.isfinite(duration) & (un > 0)  # open at the end of the dumps, or not approaching
    out = {
        "t_start": ts, "duration": duration, "body_i": i, "body_j": body_j, "kind": kinds.astype(np.int8),
        "x": point[:, 0], "y": point[:, 1], "z": point[:, 2], "un": un, "ut": ut, "m_eff": meff,
        "se_n": 0.5 * meff * un**2, "se_t": 0.5 * meff * ut**2,
        "peak_force": np.zeros(len(rows)), "peak_penetration": peak,
        "dissipated_normal": np.zeros(len(rows)), "dissipated_friction": np.zeros(len(rows)),
    }
    order = np.lexsort((out["body_j"][keep], out["body_i"][keep], (ts + duration)[keep]))
    return {c: np.asarray(out[c][keep][order], dtype=EVENT_COLUMNS[c][0]) for c in EVENT_COLUMNS}


# ---------------------------------------------------------------- the case
LOG = "log.liggghts"  #: LIGGGHTS' log in the case directory (run.sh: -log log.liggghts)
LOOP_TIME = re.compile(r"^Loop time of ([0-9.eE+-]+) on (\d+) procs?", re.M)


def liggghts_run_time(case) -> tuple[float, int] | None:
    """(seconds, processes) LIGGGHTS ran the case's time steps for: the sum of its log's
    "Loop time of X on N procs" lines (one per `run` command of the deck), read from
    the case's LOG; None without a log or such a line (the case not run, or killed)."""
    try:
        text = (Path(case) / LOG).read_text(errors="replace")
    except OSError:
        return None
    loops = [(float(x), int(n)) for x, n in LOOP_TIME.findall(text)]
    if not loops:
        return None
    return sum(x for x, _ in loops), max(n for _, n in loops)


def read_manifest(case) -> dict:
    path = Path(case) / MANIFEST
    if not path.exists():
        raise ConfigError("command line", "DIR", str(case), f"not a case exported by `taimill export liggghts` (no {MANIFEST})")
    man = json.loads(path.read_text())
    if man.get("format") != FORMAT:
        raise ConfigError(path, "format", man.get("format"), f"must be {FORMAT}")
    return man


def import_case(case, out, *, dump: str | None = None) -> dict:
    """Write the run store `out` from the dumps of the exported case directory `case`;
    returns its summary (docs/outputs.md), events reconstructed as the module doc says.
    Its wall_seconds is LIGGGHTS' own run time (liggghts_run_time; NaN without its
    log), not the import's; the store's `source` attribute has it with the processes."""
    case = Path(case)
    man = read_manifest(case)
    dump_path = Path(dump) if dump else case / man["dump"]
    if not dump_path.exists():
        raise ConfigError("command line", "DIR", str(case), f"no dump {dump_path}: run the case first (./run.sh)")
    steps, cols, data = read_dump(dump_path)
    config = dict(man["config"])
    radii = np.asarray(man["radii"], float)
    n = len(radii)
    if data.shape[1] != n:
        raise ConfigError(dump_path, "NUMBER OF ATOMS", data.shape[1], f"the case has {n} balls")
    col = {c: cols.index(c) for c in cols}
    xg = data[..., [col["x"], col["y"], col["z"]]]
    vg = data[..., [col["vx"], col["vy"], col["vz"]]]
    sg = data[..., [col["omegax"], col["omegay"], col["omegaz"]]]
    mass = data[0, :, col["mass"]] if "mass" in col else None
    t = steps * float(man["dt"])
    config["duration"] = float(t[-1])
    geom = RunGeometry.from_config(config, radii)
    if mass is None:
        mass = np.full(n, geom.ball_mass)
    fr = Frames(geom, t)
    x, v, s = fr.to_jar(xg, vg, sg)
    events = reconstruct_events(geom, radii, mass, t, xg, vg, sg, float(config.get("gravity", 9.81)))
    analysis_start = min(float(config.get("analysis_start", 0.0)), float(t[-1]))
    summary_sink = SummarySink(analysis_start, float(t[-1]))
    store = ZarrSink(out)
    sink = FanOut(summary_sink, store)
    sink.start(config, n, radii)
    for a in range(0, len(t), 1024):
        sl = slice(a, a + 1024)
        sink.frames(Frames(geom, t[sl]).block(x[sl], v[sl], s[sl]))
    sink.events(events)
    ran = liggghts_run_time(case)
    summary = summary_sink.result(float(t[-1]), ran[0] if ran else math.nan)
    d = geom.drive
    status = "complete" if abs(t[-1] - man["steps"] * man["dt"]) < 0.5 * man["dt"] else "incomplete dumps"
    summary.update(dt=float(man["dt"]), steps=int(steps[-1]), status=status, ratio=d.ratio, plate_rpm=d.plate_rpm)
    sink.finish(summary, status)
    store.group.attrs.update({
        "source": {"code": "LIGGGHTS-PUBLIC", "case": str(case.resolve()), "dump": str(dump_path),
                   "mapping": man.get("mapping"), "jar_mesh": man.get("jar_mesh"),
                   "time_step_check": man.get("time_step_check"),
                   "loop_seconds": ran[0] if ran else None, "processes": ran[1] if ran else None},
        "events_source": EVENTS_SOURCE, "events_unknown_columns": list(UNKNOWN_EVENT_COLUMNS),
        "energy_source": ENERGY_SOURCE,
    })
    return summary


def events_from_store(run) -> dict:
    """The same reconstruction applied to a taimill run store's frames (to compare a
    taimill run with an imported one like for like)."""
    geom = RunGeometry.from_config(run.config, run.radii)
    f = run.frames
    fr = Frames(geom, f["time"])
    xg, vg, sg = fr.to_ground(f["position"], f["velocity"], f["spin"])
    mass = geom.ball_mass * (run.radii / geom.ball_radius) ** 3
    return reconstruct_events(geom, run.radii, mass, f["time"], xg, vg, sg, float(run.config.get("gravity", 9.81)))

