"""Parameter sweeps (`taimill sweep`): plan the cartesian product of the swept
values and the replicas' seeds, validate every point before any kernel runs, batch the
points into chunks of B mills (one Runner, one fused kernel per chunk), run the chunks
on spawned local processes or a dask cluster (executors), store them (taimill.store.sweep), and
optionally refine the location of a figure's maximum along K (taimill.analysis.sweep).

A point is exactly the run `taimill run PRESET` with the same overrides and seed: the
same MillSpec, the same summary code (simulation.start_point / point_result), so its
event table is bit-identical (tests/test_sweep.py).
"""

from __future__ import annotations

import decimal
import hashlib
import itertools
import json
import math
import os
from dataclasses import dataclass

from taimill.errors import ConfigError, WorkerDied
from taimill.runs.executors import Job, PoolBroken, chunk_seconds, run_dask, run_local
from taimill.runs.signals import sigterm_interrupts
from taimill.analysis.sweep import CURVE_COLUMNS, parabolic_peak, refine_candidates
from taimill.store.layout import plain
from taimill.store.sweep import SweepStore, scalars

# Swept preset keys, outermost first (ratio innermost: a chunk holds neighbouring K).
# "friction.mu" is one Coulomb coefficient, μ_s = μ_d, of the preset's pair (both contact
# kinds unless pair_ball_wall is given); "friction.mu_r" its rolling resistance.
AXES = ("mill", "plate_radius_mm", "jar", "jar_volume_ml", "jar_material", "balls.material", "balls.diameter_mm", "balls.count", "pair",
        "pair_ball_wall", "friction.mu", "friction.mu_r", "plate_rpm", "ratio")
# the table column of each outer axis (refinement finds a combination's curve by them)
AXIS_COLUMNS = {"mill": "mill", "plate_radius_mm": "plate_radius_mm", "jar": "jar", "jar_material": "jar_material", "balls.material": "ball_material",
                "balls.diameter_mm": "ball_diameter_mm", "balls.count": "balls", "pair": "pair_name", "pair_ball_wall": "pair_ball_wall",
                "friction.mu": "mu", "friction.mu_r": "mu_r", "plate_rpm": "plate_rpm"}
MAX_POINTS = 10_000
MEDIA_AXES = ("jar_material", "balls.material", "balls.diameter_mm")
# The flattened keys of a resolved configuration each swept file sets: a change to that
# file is named by them (content).
FILE_AXES = {"mill": ("mill",), "jar": ("jar",), "jar_volume_ml": ("jar",), "pair": ("pair", "friction", "ball_ball", "ball_wall"),
             "pair_ball_wall": ("wall_friction",), "balls.material": ("balls", "ball_ball", "ball_wall"),
             "jar_material": ("jar", "ball_wall")}
AXIS_OPTIONS = {"balls.material": "--ball-material", "balls.diameter_mm": "--ball-diameter", "jar_volume_ml": "--jar-volume",
                "plate_radius_mm": "--plate-radius"}  # else --KEY
MAX_AUTO_BATCH = 16


def auto_batch(n_points: int, workers: int) -> int:
    """Mills per kernel B. Measured on the 2-core machine (CY steel, K = -2.6, 3 s per
    mill, one thread): 0.535, 0.550, 0.58 µs per mill-step for B = 1, 2, 4, i.e. a
    batch costs B single mills: launches of ≥ 10⁴ steps already amortise the ≈ 30 µs
    launch, and B mills on one thread run one after another (the engine pads each mill
    to its own ≥ 512-iteration task, so B > 1 could also spread over threads, but
    sweeps use one process per core instead: 2× on 2 cores). So B buys little speed and
    costs load balance; it only cuts per-chunk overhead (a task round trip, a result
    hand-over) in large sweeps: B = 1 up to 8 chunks per worker, then growing to keep
    about 8 chunks per worker, at most MAX_AUTO_BATCH."""
    return max(1, min(MAX_AUTO_BATCH, n_points // (8 * max(1, workers))))


def parse_values(text: str, key: str, kind=float) -> list:
    """Swept values from the command line: "A:B:STEP" (A to B inclusive, the step's
    sign taken from A → B) or "v1,v2,…" or one value. Numbers are rounded to 10
    decimals so that -2.6 from a range is the -2.6 one would type. Strings for kind=str."""
    def bad(why):
        return ConfigError("command line", key, text, why)

    text = text.strip()
    if kind is str:
        values = [v.strip() for v in text.split(",")]
        if not all(values):
            raise bad("a comma-separated list of names with no empty entry")
    elif ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise bad("a range A:B:STEP (e.g. 0:-4:0.2), a list v1,v2,… or one value")
        try:
            a, b, step = (float(p) for p in parts)
        except ValueError:
            raise bad("A, B and STEP of A:B:STEP must be numbers") from None
        # STEP = 0 and the count from the text in decimal: after a Taichi run this
        # process's CPU flushes subnormals to zero, and float("1e-308") reads 0
        exact = [decimal.Decimal(p.strip()) for p in parts]
        if not all(map(math.isfinite, (a, b, step))) or not all(d.is_finite() for d in exact) or exact[2] == 0:
            raise bad("A:B:STEP needs finite numbers and STEP ≠ 0")
        with decimal.localcontext(traps=[]):  # a 1e-999999999 STEP counts as infinitely many
            count = abs(exact[1] - exact[0]) / abs(exact[2])
        if count >= MAX_POINTS:
            raise bad(f"more than {MAX_POINTS} values; at most {MAX_POINTS}")
        n = int(math.floor(abs(b - a) / abs(step) + 1e-9)) + 1
        step = math.copysign(abs(step), b - a) if b != a else step
        values = [round(a + i * step, 10) for i in range(n)]
    else:
        try:
            values = [kind(v) for v in text.split(",")]
        except ValueError:
            raise bad(f"a comma-separated list of {'integers' if kind is int else 'numbers'}, or a range A:B:STEP") from None
        if kind is float and not all(map(math.isfinite, values)):
            raise bad("values must be finite")
    if kind is int and any(v != int(v) for v in values):
        raise bad("values must be integers")
    values = [kind(v) for v in values]
    if len(set(values)) != len(values):
        raise bad("a value is repeated")
    return values


@dataclass
class Request:
    """A sweep as asked for: preset file, fixed overrides (the run options), swept
    values per preset key (AXES), replicas (seeds seed … seed+R−1)."""

    preset: str
    overrides: dict
    axes: dict
    replicas: int = 1
    refine_metric: str | None = None
    refine_rounds: int = 0

    def identity(self) -> dict:
        """What makes two sweeps the same store (refinement may extend either)."""
        return {"preset": os.path.abspath(self.preset), "overrides": self.overrides,
                "axes": self.axes, "replicas": self.replicas}


def plan(req: Request, ratios_for=None) -> list[dict]:
    """Points of the cartesian product in AXES order, replicas innermost, each
    {overrides, values, preset}; every preset is loaded and validated here, before
    any kernel runs. `ratios_for(curve_values) -> list[K]` replaces the K axis (refine)."""
    from taimill.model.preset import load_preset

    base = load_preset(req.preset, req.overrides)
    seed0 = base.seed
    if not 1 <= req.replicas <= 1000:
        raise ConfigError("command line", "--replicas", req.replicas, "allowed range [1, 1000]")
    if seed0 + req.replicas - 1 > 2**63 - 1:
        raise ConfigError("command line", "--seed", seed0, f"seed + replicas - 1 must stay below 2^63; allowed range [0, {2**63 - req.replicas}]")
    outer = [req.axes.get(k, [None]) for k in AXES[:-1]]
    n = math.prod(map(len, outer)) * len(req.axes.get("ratio", [None])) * req.replicas
    if ratios_for is None and n > MAX_POINTS:
        raise ConfigError("command line", "sweep", n, f"at most {MAX_POINTS} points (values × replicas)")
    points = []
    for combo in itertools.product(*outer):
        fixed = {k: v for k, v in zip(AXES[:-1], combo) if v is not None}
        ratios = req.axes.get("ratio", [None]) if ratios_for is None else ratios_for(fixed)
        for k, r in itertools.product(ratios, range(req.replicas)):
            ov = dict(req.overrides) | fixed | {"seed": seed0 + r}
            if k is not None:
                ov.pop("jar_rpm", None)
                ov["ratio"] = k
            if "friction.mu" in ov:
                mu = ov.pop("friction.mu")
                ov["friction.mu_s"] = ov["friction.mu_d"] = mu
            p = load_preset(req.preset, ov)
            # a jar or mill as given: the built-in CY and a user's CY.toml share a name, not a curve
            label = {k: fixed[k] for k in ("mill", "jar") if k in fixed}
            if any(k in req.axes for k in MEDIA_AXES):  # the pair label tells the media's curves apart
                label["pair"] = f"{friction_label(p)}, {media_label(p)}"
            points.append({"overrides": ov, "values": point_values(p, r) | label, "preset": p})
    return points


def flat(config: dict, prefix: str = "") -> dict:
    """A resolved configuration as {"balls.count": 12, …}; where a file was named from
    (`source`) is left out: the same files named from another folder are the same sweep."""
    out = {}
    for k, v in config.items():
        if isinstance(v, dict):
            out |= flat(v, f"{prefix}{k}.")
        elif k != "source":
            out[f"{prefix}{k}"] = v
    return out


def content(req: Request, points: list[dict]) -> dict:
    """What the request resolved to, for a sweep store to resume only against the same
    (taimill.store.sweep): `sha256` of every planned point's resolved configuration
    (Preset.as_dict: the values of the preset, jar, pair and material files, not their
    bytes, so a comment edited changes nothing), and `parts` that name a change: the
    preset's configuration with the fixed overrides, and the keys each swept jar or
    pair file sets (FILE_AXES)."""
    from taimill.model.preset import load_preset

    parts = {f"preset {req.preset}": flat(plain(load_preset(req.preset, req.overrides).as_dict()))}
    digest = hashlib.sha256()
    for p in points:  # one point at a time: 10⁴ configurations with start positions are large
        config = flat(plain(p["preset"].as_dict()))
        digest.update(json.dumps(config, sort_keys=True).encode())
        for key, names in FILE_AXES.items():
            label = f"{AXIS_OPTIONS.get(key, '--' + key.replace('_', '-'))} {p['overrides'].get(key)}"
            if key in req.axes and label not in parts:
                parts[label] = {k: x for k, x in config.items() if k.split(".")[0] in names}
    return {"sha256": digest.hexdigest(), "parts": parts}


def point_values(p, replica: int) -> dict:
    """The table's description of a resolved preset (SI radii, rpm). `pair` tells the
    curves apart: the preset's pair, and what differs from its own friction."""
    bb, bw = p.frictions
    return {"mill": p.mill.name, "jar": p.jar.name, "balls": p.balls.count, "pair": friction_label(p), "plate_rpm": round(p.drive.plate_rpm, 9),
            "ratio": round(p.drive.ratio, 10), "seed": p.seed, "replica": replica, "plate_radius": p.plate_radius,
            "ball_mass": p.balls.mass,
            "jar_radius": p.jar.radius, "ball_radius": p.balls.radius, "duration": p.duration,
            "mu": bb.mu_s, "mu_d": bb.mu_d, "mu_r": bb.mu_r, "mu_wall": bw.mu_s, "mu_d_wall": bw.mu_d, "mu_r_wall": bw.mu_r,
            "pair_name": p.pair, "pair_ball_wall": bw.name, "jar_material": p.jar.wall_material,
            "ball_material": p.balls.material.name, "ball_diameter_mm": round(2e3 * p.balls.radius, 9),
            "plate_radius_mm": round(1e3 * p.plate_radius, 9)}


def media_label(p) -> str:
    """The balls and the wall: "zirconia balls Ø12 mm, aisi-304 wall"."""
    return f"{p.balls.material.name} balls Ø{round(2e3 * p.balls.radius, 9):g} mm, {p.jar.wall_material} wall"


def friction_label(p) -> str:
    """The pair, plus the coefficients where the run's friction differs from the pair's
    own: ", μ 0.3 μ_r 0.05" (both kinds, or ball-ball), ", wall steel-fluorite" or
    ", wall μ 0.2" (ball-wall)."""
    from taimill.model.materials import load_friction

    def coefficients(f):
        return f.mu_s, f.mu_d, f.v_s, f.v_d, f.mu_r

    def text(f):
        return f"μ {f.mu_s:g}" + (f"/{f.mu_d:g}" if f.mu_d != f.mu_s else "") + (f" μ_r {f.mu_r:g}" if f.mu_r else "")

    own = load_friction(p.pair, "sweep")[0]
    bb, bw = p.frictions
    label = p.pair
    if coefficients(bb) != coefficients(own):
        label += f", {text(bb)}"
    if coefficients(bw) != coefficients(bb):
        label += f", wall {bw.name if 'tuned' not in bw.name else text(bw)}"
    return label


def chunks(jobs: list[Job], batch: int) -> list[list[Job]]:
    """Chunks of at most `batch` jobs with the same ball count and jar file (one engine
    shape per process; two jar files may share a name), the costliest first
    (longest-processing-time-first balances the workers); cost = ball-steps = balls ×
    duration / dt."""
    def cost(j):
        return j.preset.balls.count * j.preset.duration / j.preset.dt

    groups: dict = {}
    for j in sorted(jobs, key=lambda j: (j.preset.balls.count, j.preset.jar.source, -cost(j), j.index)):
        groups.setdefault((j.preset.balls.count, j.preset.jar.source), []).append(j)
    out = [g[i:i + batch] for g in groups.values() for i in range(0, len(g), batch)]
    return sorted(out, key=lambda c: -sum(map(cost, c)))


class Progress:
    """Simulated mill-seconds done over all pending points → callback(done, total)."""

    def __init__(self, all_chunks, callback):
        self.total = sum(chunk_seconds(c) for c in all_chunks)
        self.parts: dict[int, float] = {}
        self.callback = callback

    def __call__(self, cid, seconds):
        self.parts[cid] = seconds
        if self.callback:
            self.callback(sum(self.parts.values()), self.total)


def execute(points, store: SweepStore | None, *, batch=None, workers=None, scheduler=None,
            progress=None, notice=None) -> dict[int, dict]:
    """Run the points not yet in the store in chunks of `batch` mills (default
    auto_batch) on `workers` local processes (default one per core) or the dask
    scheduler at `scheduler`; returns {point index: table row} for all points.
    `notice(text)`: told which kernels the workers compile first."""
    if store is not None:
        index = store.add_points(points)
        done = store.done()
    else:
        index, done = list(range(len(points))), set()
    jobs = [Job(i, p["preset"]) for i, p in zip(index, points) if i not in done]
    jobs = list({j.index: j for j in jobs}.values())
    rows = {}
    workers = workers or os.cpu_count() or 1
    # a cluster's size is unknown here and a dask task round trip costs milliseconds: B = 1
    all_chunks = chunks(jobs, batch or (1 if scheduler else auto_batch(len(jobs), workers)))
    if all_chunks:
        if notice:
            from taimill.runs.simulation import compile_texts

            for text in compile_texts(all_chunks):
                notice(text)
        prog = Progress(all_chunks, progress)
        keep = store is not None
        if scheduler:
            stream = run_dask(all_chunks, scheduler, keep, prog)
        else:
            stream = run_local(all_chunks, min(workers, len(all_chunks)), keep, prog)
        try:
            for results in stream:
                for r in results:
                    if store is not None:
                        store.write_point(r)
                    rows[r.index] = r.summary
        except PoolBroken as broken:
            raise WorkerDied(died(broken, store, dict(zip(index, points)))) from None
        finally:
            stream.close()  # a failed write stops the workers now, not at interpreter exit
    if store is None:
        return {i: {"point": i, **scalars(rows[i]), **p["values"]} for i, p in zip(index, points)}
    table = store.table()
    where = {int(v): k for k, v in enumerate(table["point"])}
    return {i: {name: _py(col[where[i]]) for name, col in table.items()} for i in index}


DESCRIBED = ("jar", "balls.count", "pair", "pair_ball_wall", "friction.mu_s", "friction.mu_r", "plate_rpm", "ratio", "seed")


def died(broken: PoolBroken, store: SweepStore | None, points: dict[int, dict]) -> str:
    """The one line for a sweep whose worker died: which worker, how, the points it was
    running and those stopped with it, and what is kept."""
    def one(i):
        ov = points[i]["overrides"]
        return f"point {i} ({', '.join(f'{k} {ov[k]}' for k in DESCRIBED if k in ov)})"

    def named(indices):
        return ", ".join(one(i) for i in sorted(indices) if i in points)

    dead = {pid for pid, _ in broken.dead}
    who = "; ".join(f"worker process {pid} {how}" if pid else f"a worker {how}" for pid, how in broken.dead) \
        or "a worker process died"
    ran = [i for pid, ids in broken.lost.items() if pid in dead or not dead for i in ids]
    also = [i for pid, ids in broken.lost.items() if dead and pid not in dead for i in ids]
    text = who + (f" while it ran {named(ran)}" if ran else "")
    if also:
        text += f"; stopped with it: {named(also)}"
    if store is None:
        return f"sweep: {text}; nothing is stored (no --out)"
    # an --overwrite sweep is built beside the old store (store.output): resumed there
    again = (f"--out {store.where} with the other arguments unchanged resumes the sweep" if ".partial-" in store.where
             else "the same command resumes the sweep")
    return f"{store.where}: {text}; {len(store.done())} of {len(store.plan)} points are stored, {again}"


def _py(v):
    return v.item() if hasattr(v, "item") else v


def curve_of(row: dict) -> tuple:
    return tuple(row.get(k, "") for k in CURVE_COLUMNS)  # rows from before mills have no mill


def run_sweep(req: Request, store: SweepStore | None = None, **run_kw) -> tuple[list[dict], list[dict]]:
    """Grid, then `refine_rounds` rounds of refinement per curve; returns (rows in plan
    order, peaks per curve of the refine metric — empty without refinement). SIGTERM
    interrupts it like Ctrl-C (signals.sigterm_interrupts); finished points stay stored."""
    with sigterm_interrupts():
        return _run_sweep(req, store, **run_kw)


def _run_sweep(req: Request, store: SweepStore | None, **run_kw) -> tuple[list[dict], list[dict]]:
    rows = execute(plan(req), store, **run_kw)
    if not req.refine_metric:
        return [rows[i] for i in sorted(rows)], []

    def evaluate(extra: dict) -> dict:
        return execute(plan(req, lambda fixed: extra.get(_fixed_curve(fixed, rows), [])), store, **run_kw)

    rows, peaks = refine(rows, req.refine_metric, req.refine_rounds, evaluate)
    if store is not None:
        store.set_refine({"metric": req.refine_metric, "rounds": req.refine_rounds, "peaks": peaks})
    return [rows[i] for i in sorted(rows)], peaks


def refine(rows: dict, metric: str, rounds: int, evaluate) -> tuple[dict, list[dict]]:
    """`rounds` rounds of refine_candidates (taimill.analysis.sweep) per curve; evaluate({curve:
    [K, …]}) simulates the new K values (all replicas) and returns their rows by index.
    Returns (all rows, parabolic peak per curve)."""
    rows = dict(rows)
    for _ in range(rounds):
        by_curve: dict = {}
        for r in rows.values():
            by_curve.setdefault(curve_of(r), []).append(r)
        extra = {}
        for curve, rs in by_curve.items():
            new = refine_candidates([r["ratio"] for r in rs], [r.get(metric, math.nan) for r in rs])
            if new:
                extra[curve] = new
        if not extra:
            break
        rows |= evaluate(extra)
    return rows, peaks_by_curve(rows.values(), metric)


def _fixed_curve(fixed: dict, rows: dict) -> tuple:
    """The curve a `plan` combination of outer axes belongs to (values resolved as in
    the table: the preset's own where the axis is not swept)."""
    for r in rows.values():
        if all(_same(r.get(AXIS_COLUMNS[k], r.get(k)), v) for k, v in fixed.items()):
            return curve_of(r)
    return ()


def _same(a, b) -> bool:
    return math.isclose(a, b, rel_tol=1e-12) if isinstance(a, float) and not isinstance(b, str) else str(a) == str(b)


def peaks_by_curve(rows, metric: str) -> list[dict]:
    """Parabolic peak (taimill.analysis.sweep.parabolic_peak) of `metric` along K for each curve."""
    by_curve: dict = {}
    for r in rows:
        by_curve.setdefault(curve_of(r), []).append(r)
    out = []
    for curve, rs in sorted(by_curve.items(), key=lambda kv: str(kv[0])):
        peak = parabolic_peak([r["ratio"] for r in rs], [r.get(metric, math.nan) for r in rs])
        out.append(dict(zip(CURVE_COLUMNS, curve)) | {"metric": metric} | peak)
    return out

