"""Small media at scale: the set-up path is O(N) (grid-hashed overlap checks and
placement) and still exact."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from taimill.errors import ConfigError
from taimill.model.overlap import first_overlap, overlapping_pairs
from taimill.model.preset import load_preset
from taimill.model.placement import lattice_placement
from taimill.model.geometry import build_profile
from taimill.store.run import open_run


def brute_pairs(x, r):
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    i, j = np.nonzero(np.triu(d < r[:, None] + r[None], 1))
    return np.column_stack([i, j])


@pytest.mark.parametrize("n, seed", [(2, 0), (50, 1), (800, 2), (2000, 3)])
def test_grid_overlap_check_equals_all_pairs(n, seed):
    rng = np.random.default_rng(seed)
    x = rng.random((n, 3)) * 0.05 * (n / 100) ** (1 / 3)
    r = rng.uniform(0.5e-3, 3e-3, n)  # mixed sizes: the cell edge is set by the largest
    ref = brute_pairs(x, r)
    assert np.array_equal(overlapping_pairs(x, r), ref)
    assert (first_overlap(x, r) is None) == (len(ref) == 0)


def bed(n, r):
    """n balls of radius r on a close-packed lattice at pitch 2r + 0.1 mm."""
    R = (n / 0.3 * 4 / 3 * r**3) ** (1 / 3)
    return lattice_placement(n, r, circle(R), R, seed=0), R


def circle(R):
    return build_profile((("circle", {"radius": R}),), 0.0)


def test_a_hundred_thousand_balls_are_checked_in_seconds_and_a_planted_overlap_is_found():
    r = 1e-3
    x, _ = bed(100_000, r)
    t0 = time.perf_counter()
    assert first_overlap(x, r) is None
    took = time.perf_counter() - t0
    assert took < 5.0, took  # measured 0.3 s; a dense matrix would need 80 GB
    # plant one overlap of 1 nm between two far-apart rows
    i, j = 1234, 98_765
    x = x.copy()
    x[j] = x[i] + np.array([2 * r - 1e-9, 0.0, 0.0])
    assert (i, j) in {tuple(p) for p in overlapping_pairs(x, r)}
    assert first_overlap(x, r) is not None


def test_initial_positions_of_a_hundred_thousand_balls_load_in_seconds(tmp_path):
    r = 1e-3
    x, R = bed(100_000, r)
    (tmp_path / "jar.toml").write_text(f'height_mm = {R * 1e3}\nwall_material = "aisi-304"\n'
                                       f'[[profile]]\ntype = "circle"\nradius_mm = {R * 1e3}\n')
    np.savez(tmp_path / "start.npz", positions=x)
    text = (f'jar = "jar.toml"\npair = "steel-steel"\nplate_rpm = 200\nratio = -2.6\nduration = 0.01\n'
            f'initial_positions = "start.npz"\n[balls]\ncount = {len(x)}\nmaterial = "steel-c1020"\nradius_mm = 1\n')
    (tmp_path / "p.toml").write_text(text)
    t0 = time.perf_counter()
    p = load_preset(tmp_path / "p.toml")
    assert time.perf_counter() - t0 < 10.0  # measured ≈ 1 s (the jar's SDF, the grid check)
    assert p.initial_positions.shape == (100_000, 3)
    x[500] = x[501] + np.array([0.0, 0.0, 1.5 * r])
    np.savez(tmp_path / "start.npz", positions=x)
    with pytest.raises(ConfigError, match="overlap"):
        load_preset(tmp_path / "p.toml")


@pytest.mark.parametrize("name", ["p4-zr80-beads-1mm", "p4-zr500-beads-3mm"])
def test_small_media_presets_run_via_the_cli(name, tmp_path):
    # ≈ 250 steps (frames every 125 steps: a run lasts whole frame intervals): set-up,
    # the engine, the store and the summary end to end
    ROOT = Path(__file__).resolve().parent.parent
    text = (ROOT / "presets" / f"{name}.toml").read_text().replace("trajectory_rate = 50", "trajectory_rate = 1")
    preset = load_preset(ROOT / "presets" / f"{name}.toml")
    rate = 1.0 / (125 * preset.dt)
    (tmp_path / "p.toml").write_text(text.replace("trajectory_rate = 1", f"trajectory_rate = {rate!r}"))
    out = tmp_path / "run.zarr"
    res = subprocess.run([sys.executable, "-m", "taimill", "run", str(tmp_path / "p.toml"),
                          "--duration", str(250 * preset.dt), "--out", str(out), "--json"],
                         capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads(res.stdout)
    assert summary["status"] == "complete" and summary["steps"] >= 250
    store = open_run(out)
    x = store.frames["position"]
    assert x.shape[1] == preset.balls.count and np.isfinite(x).all()
    assert store.radii.shape == (preset.balls.count,)


def wall_geometry(jar_name, ball_radius):
    from taimill.analysis.rungeometry import RunGeometry
    from taimill.model.frame import Ramp
    from taimill.model.jars import load_jar

    jar = load_jar(jar_name)
    return RunGeometry(jar.profile, jar.height, ball_radius, 1.0, 10, 0.1, Ramp(0, 0, 0, 1), Ramp(0, 0, 0, 1), 0.0, 1.0)


def brute_inside_area(g, edges, sub=6):
    """Every sub × sub sample of every cell through the SDF (the map's definition)."""
    n, h = len(edges) - 1, edges[1] - edges[0]
    u = (np.arange(n * sub) + 0.5) * h / sub + edges[0]
    xx, yy = np.meshgrid(u, u, indexing="ij")
    phi, _ = g.sdf(np.column_stack([xx.ravel(), yy.ravel()]))
    return (phi >= 0).reshape(n, sub, n, sub).sum(axis=(1, 3)) * (h / sub) ** 2


@pytest.mark.parametrize("jar, cells", [("T", 64), ("CY", 50), ("EFV45", 41)])
def test_floor_map_areas_sample_only_the_cells_the_wall_crosses_and_equal_sampling_all(jar, cells):
    from taimill.analysis.spatial import _inside_area

    g = wall_geometry(jar, 1e-3)
    R = g.jar_radius
    edges = np.linspace(-R, R, cells + 1)
    assert np.array_equal(_inside_area(g, edges), brute_inside_area(g, edges))


def test_the_summary_of_a_large_jar_starts_without_sampling_its_whole_floor(monkeypatch):
    # small beads in a jar 256 cells across: sampling every cell (6 × 6 points) put
    # 2.4 M points through the SDF, 0.6-7 s CPU at the start of every run (T jar: 12
    # pieces); only the ≈ 3 % of cells the wall crosses need it
    from taimill.analysis.spatial import WallMap

    g = wall_geometry("T", 5e-4)
    points = []
    sdf = type(g).sdf
    monkeypatch.setattr(type(g), "sdf", lambda self, xy: (points.append(len(xy)), sdf(self, xy))[1])
    t0 = time.process_time()
    m = WallMap(g)
    assert len(m.xy_edges) == 257
    assert sum(points) < 0.1 * (256 * 6) ** 2, sum(points)
    assert time.process_time() - t0 < 3.0  # measured 0.3 s CPU (7 s CPU before)


def test_taichi_source_positions_are_formatted_once_per_place_with_taichis_own_text():
    # Taichi formats an excerpt for every AST node of every kernel it transforms (its
    # compile cost in Python; ≈ 0.4 s CPU of a 10⁵-ball set-up): taimill formats each
    # place once. Every node of the engine's sources gets Taichi's own text, twice.
    import ast
    import types

    from taimill.physics import contacts, engine, neighbours, walls
    from taimill.physics import ti as door

    utils = door.internal("lang.ast.ast_transformer_utils")
    door.init_taichi()
    memo = utils.ASTTransformerContext.get_pos_info
    assert getattr(memo, "memoised", False)
    nodes = 0
    for mod in (engine, contacts, neighbours, walls):
        lines = Path(mod.__file__).read_text().splitlines()
        for top in ast.parse("\n".join(lines)).body:
            if not isinstance(top, ast.FunctionDef):
                continue
            start = min([top.lineno] + [d.lineno for d in top.decorator_list])
            src = lines[start - 1:top.end_lineno]
            # a context of Taichi's own class with what get_pos_info reads (taichi-forge
            # also keeps a per-context excerpt cache of its own)
            ctx = object.__new__(utils.ASTTransformerContext)
            ctx.__dict__.update(file=mod.__file__, src=src, indent=0, lineno_offset=start - 1, _source_info_cache={},
                                func=types.SimpleNamespace(func=types.SimpleNamespace(__name__=top.name)))
            for node in ast.walk(ast.parse("\n".join(src))):
                if isinstance(node, (ast.stmt, ast.expr)):
                    want = memo.original(ctx, node)
                    assert memo(ctx, node) == want and memo(ctx, node) == want
                    nodes += 1
    assert nodes > 1000


def test_writing_a_large_mill_is_one_kernel_launch(monkeypatch):
    # a to_numpy/from_numpy pair per field was 36 launches of Taichi's copy kernels,
    # each specialised on its field (compiled, or its AST transformed when cached:
    # ≈ 1.2 s CPU of a 10⁵-ball set-up), and copied every mill's rows twice
    from taimill.physics.ti import internal

    kernel_impl = internal("lang.kernel_impl")

    from taimill.model.preset import load_preset
    from taimill.model.spec import from_preset
    from taimill.physics.mill import write_mill
    from taimill.physics.runner import Runner

    r = 1e-3
    x, R = bed(20_000, r)  # parallel mode as at 10⁵ balls, without holding 10⁵ balls' fields for the session
    ROOT = Path(__file__).resolve().parent.parent
    preset = load_preset(ROOT / "presets" / "p4-cy-steel.toml")
    spec = from_preset(preset, 1e-3)
    n = len(x)
    spec = spec.replace(radius=np.full(n, r), mass=np.full(n, spec.mass[0]), position=x, velocity=np.zeros((n, 3)),
                        spin=np.ones((n, 3)), profile=circle(R), height=R)
    runner = Runner([spec], mode="parallel")
    F = runner.engine.F
    launches = []
    call = kernel_impl.Kernel.__call__
    monkeypatch.setattr(kernel_impl.Kernel, "__call__", lambda self, *a, **k: (launches.append(self.func.__name__),
                                                                                call(self, *a, **k))[1])
    t0 = time.process_time()
    write_mill(F, 0, spec)
    took = time.process_time() - t0
    assert launches == ["_load_mill"], launches
    assert took < 3.0, took  # measured 0.05 s CPU once compiled
    assert np.array_equal(F.state.x.to_numpy()[0, :n], x) and np.array_equal(F.state.s.to_numpy()[0, :n], spec.spin)
    assert (F.model.r.to_numpy()[0, n:] == 1.0).all() and (F.contacts.slot_mask.to_numpy()[0] == 0).all()
    assert np.array_equal(F.model.inv_i.to_numpy()[0, :n], 1.0 / spec.inertia)


def test_a_presets_two_contact_types_are_calibrated_in_one_batch(monkeypatch):
    # the bisection's impacts cost NumPy's per-call overhead (≈ 1500 RK4 steps a round):
    # both contact types in one batch per round halve it (≈ 1 s CPU of every run's set-up)
    from taimill.model import laws

    ROOT = Path(__file__).resolve().parent.parent
    calls = []
    simulate = laws.simulate_impact
    monkeypatch.setattr(laws, "simulate_impact", lambda *a, **k: (calls.append(k.get("steps", 2000)), simulate(*a, **k))[1])
    monkeypatch.setattr(laws, "_DAMPING", {})
    p = load_preset(ROOT / "presets" / "p4-cy-steel.toml", {"law": "hertz-mindlin"})
    assert calls.count(2000) == 4, calls  # 4 bisection rounds, both contact types in each
    c = [laws.calibrate_damping(q.model, q.e, q.k, q.m_eff, q.u_ref, q.d) for q in (p.ball_ball, p.ball_wall)]
    assert calls.count(2000) == 4 and c == [p.ball_ball.c, p.ball_wall.c]  # cached
