"""The architecture as rules on the import graph, read from the source with `ast`
(no import is executed). Each package may import only the packages listed for it in
LAYERS; only the door to Taichi (`taimill/physics/ti.py`) imports taichi or its fork
taichi_forge, in the package, its tests and scripts, and only `figures` (and the recording, for
colour maps) import matplotlib; no module imports itself through a cycle; the TUI reaches the
simulation only through the live mill's public API; only `physics` writes Taichi fields
(everything else changes a mill through the setters of `taimill.physics.mill`); the
rules of the rule book (`taimill.model.rules`) are stated nowhere else. A failure names
the import, the write or the rule.
Every import counts, also one inside a function: a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "taimill"

# package -> the taimill packages it may import (besides itself). Top-level modules
# count as packages of their own name.
NEUTRAL = {"errors", "schema"}
LAYERS: dict[str, set[str]] = {
    "": set(),  # taimill/__init__.py
    "__main__": {"cli"},
    "errors": set(),
    "schema": set(),
    "model": NEUTRAL,
    "physics": NEUTRAL | {"model"},
    "store": NEUTRAL | {"model"},
    "analysis": NEUTRAL | {"model", "store"},
    "outcome": NEUTRAL | {"model", "store", "analysis"},
    "figures": NEUTRAL | {"model", "store", "analysis", "outcome"},
    "recording": NEUTRAL | {"model", "store", "analysis"},
    "bridge": NEUTRAL | {"model", "store", "analysis"},
    "runs": NEUTRAL | {"model", "physics", "store", "analysis", "outcome"},
    "calibration": NEUTRAL | {"model", "physics", "store", "analysis", "runs"},
    "tui": NEUTRAL | {"model", "store", "analysis", "figures", "recording", "runs"},
    "design": NEUTRAL | {"model", "store", "analysis", "figures", "runs"},
    "cli": NEUTRAL | {"model", "store", "analysis", "figures", "recording", "runs", "calibration", "tui", "bridge", "outcome", "design"},
}
# The recording takes its colour tables from matplotlib's colormaps; it draws nothing.
THIRD_PARTY_HOMES = {"taichi": {"physics"}, "taichi_forge": {"physics"}, "matplotlib": {"figures", "recording"}}
# The one module that imports an implementation of Taichi (by name, from its own table),
# and the import names of those implementations.
DOOR = "taimill/physics/ti.py"
TAICHI_MODULES = ("taichi", "taichi_forge")
# The one module of `runs` the TUI may use, and only its public names.
TUI_GATE = "taimill.runs.live"


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, root: Path) -> list[tuple[str, tuple[str, ...], int]]:
    """(imported module, names taken from it, line) for every import in a file;
    relative imports are resolved."""
    me = module_name(path, root)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, (), node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([node.module] if node.module else []))
            out.append((base, tuple(a.name for a in node.names), node.lineno))
    return out


def import_graph(root: Path) -> dict[str, list[tuple[str, tuple[str, ...], int]]]:
    """module -> its imports; `from pkg import mod` is recorded as an import of pkg.mod."""
    modules = {module_name(p, root): p for p in root.rglob("*.py")}
    graph = {}
    for mod, path in modules.items():
        edges = []
        for target, names, line in imports(path, root):
            subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in modules]
            edges += [(s, (), line) for s in subs] or [(target, names, line)]
        graph[mod] = edges
    return graph


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "taimill":
        return None
    return parts[1] if len(parts) > 1 else ""


def private_attributes(path: Path) -> list[tuple[str, int]]:
    """`x._name` where x is not self/cls: reaching into another object's internals."""
    bad = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            if not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                bad.append((ast.unparse(node), node.lineno))
    return bad


# Names an engine's fields object goes by (`engine.F`, `self.F`, a local `F`, `fields`).
FIELDS_NAMES = {"F", "fields"}
# Methods of a Taichi field that write it.
FIELD_WRITERS = {"fill", "from_numpy", "from_torch", "from_paddle", "copy_from"}


def is_fields(node) -> bool:
    """`F`, `fields`, or any `x.F` / `x.fields`: an engine's fields object."""
    return (isinstance(node, ast.Name) and node.id in FIELDS_NAMES) or (
        isinstance(node, ast.Attribute) and node.attr in FIELDS_NAMES)


def reaches_fields(node) -> bool:
    """`node` is an attribute of an engine's fields object, directly or through its
    groups (`F.x`, `F.state.x`)."""
    while isinstance(node, ast.Attribute):
        if is_fields(node.value):
            return True
        node = node.value
    return False


def field_writes(path: Path) -> list[tuple[str, int]]:
    """Writes to a Taichi field: `F.group.name[...] = …` (also augmented, or in a tuple
    of targets) and `F.group.name.fill(…)` / `.from_numpy(…)` … on an engine's fields
    object."""
    def targets(node):
        if isinstance(node, (ast.Tuple, ast.List)):
            for elt in node.elts:
                yield from targets(elt)
        elif isinstance(node, ast.Starred):
            yield from targets(node.value)
        else:
            yield node

    bad = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Assign):
            written = [x for tgt in node.targets for x in targets(tgt)]
        elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
            written = list(targets(node.target))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in FIELD_WRITERS:
            written = [node.func]
        else:
            continue
        for x in written:
            if isinstance(x, (ast.Subscript, ast.Attribute)) and isinstance(x.value, ast.Attribute) and reaches_fields(x.value):
                bad.append((ast.unparse(x), node.lineno))
    return bad


def violations(root: Path) -> list[str]:
    graph = import_graph(root)
    found = []
    for mod, edges in sorted(graph.items()):
        layer = layer_of(mod)
        if layer not in LAYERS:
            found.append(f"{mod}: package '{layer}' has no place in LAYERS")
            continue
        for target, names, line in edges:
            top = target.split(".")[0]
            if top in THIRD_PARTY_HOMES and layer not in THIRD_PARTY_HOMES[top]:
                found.append(f"{mod}:{line} imports {top} (only {', '.join(sorted(THIRD_PARTY_HOMES[top]))} may)")
            other = layer_of(target)
            if other is None or other == layer or other == "":
                continue
            if other not in LAYERS[layer]:
                found.append(f"{mod}:{line} imports {target}: '{layer}' may not import '{other}'")
            if layer == "tui" and other == "runs":
                if target != TUI_GATE:
                    found.append(f"{mod}:{line} imports {target}: the TUI uses only {TUI_GATE}")
                found += [f"{mod}:{line} imports private {TUI_GATE}.{n}" for n in names if n.startswith("_")]
    for path in sorted((root / "tui").glob("*.py")):
        found += [f"{module_name(path, root)}:{line} reaches into {expr}" for expr, line in private_attributes(path)]
    for path in sorted(root.rglob("*.py")):
        if layer_of(module_name(path, root)) != "physics":
            found += [f"{module_name(path, root)}:{line} writes the Taichi field {expr} (only physics may: "
                      "taimill.physics.mill has the setters)" for expr, line in field_writes(path)]
    found += [f"import cycle: {' -> '.join(c)}" for c in cycles(graph)]
    return found


def cycles(graph) -> list[list[str]]:
    """One cycle per strongly connected component of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w, _, _ in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp) + [sorted(comp)[0]])

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def planted(tmp_path: Path, file: str, line: str, dirs=("taimill",)) -> tuple[Path, int]:
    """A copy of the repository's `dirs` under tmp_path with `line` appended to `file`
    (its path in the repository): (the copy of the package, the planted line's number)."""
    for d in dirs:
        shutil.copytree(PACKAGE.parent / d, tmp_path / d, ignore=shutil.ignore_patterns("__pycache__", "__snapshots__", "golden"))
    target = tmp_path / file
    n = len(target.read_text().splitlines()) + 1
    target.write_text(target.read_text() + line + "\n")
    return tmp_path / "taimill", n


def test_the_package_keeps_its_layers():
    assert violations(PACKAGE) == []


@pytest.mark.parametrize("file, line, expected", [
    ("model/geometry.py", "import taichi as ti", "taimill.model.geometry:{n} imports taichi"),
    ("physics/state.py", "from taimill.store.sinks import Sink", "'physics' may not import 'store'"),
    ("analysis/events.py", "from taimill.physics import state", "'analysis' may not import 'physics'"),
    ("store/run.py", "import matplotlib.pyplot as plt", "imports matplotlib"),
    ("tui/controls.py", "from taimill.runs.sweep import plan", "the TUI uses only taimill.runs.live"),
    ("tui/app.py", "x = self.mill._lock", "reaches into self.mill._lock"),
    ("model/frame.py", "from taimill.model import spec", "import cycle: * taimill.model.frame -> "),
    ("runs/live.py", "self.F.model.dt[0] = 1e-6", "taimill.runs.live:{n} writes the Taichi field self.F.model.dt[0]"),
    ("runs/simulation.py", "runner.engine.F.state.step[b] += 1", "writes the Taichi field runner.engine.F.state.step[b]"),
    ("tui/app.py", "a, F.model.mu_s[0, 1] = 1, 0.2", "writes the Taichi field F.model.mu_s[0, 1]"),
    ("store/run.py", "fields.x.from_numpy(x)", "writes the Taichi field fields.x.from_numpy"),
])
def test_a_planted_bad_import_is_named(tmp_path, file, line, expected):
    root, n = planted(tmp_path, f"taimill/{file}", line)
    found = violations(root)
    parts = expected.format(n=n).split("*")
    assert any(all(part.strip() in v for part in parts) for v in found), found


# Phrases of the rule book's messages (taimill.model.rules): a ConfigError elsewhere that
# says one of them restates a rule, which then can drift from the rule book's.
RULE_BOOK = "taimill.model.rules"
RULE_PHRASES = ("not both", "must not exceed static", "contact set", "steps per contact")
# The time-step rule's parts in taimill.model.laws, which only the rule book combines.
TIME_STEP_PARTS = ("auto_dt", "rolling_dt")


def config_error_texts(path: Path) -> list[tuple[str, int]]:
    """The literal text of every ConfigError(...) a file raises (f-strings: their literal parts)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) == "ConfigError":
            text = " ".join(c.value for arg in node.args for c in ast.walk(arg)
                            if isinstance(c, ast.Constant) and isinstance(c.value, str))
            out.append((text, node.lineno))
    return out


def time_step_calls(path: Path) -> list[tuple[str, int]]:
    """Calls of laws.auto_dt / laws.rolling_dt (not of the rule book's own auto_dt)."""
    return [(node.func.attr, node.lineno) for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in TIME_STEP_PARTS
            and not (isinstance(node.func.value, ast.Name) and node.func.value.id == "rules")]


def _name(node) -> str:
    """The name a Name or an Attribute ends in; '' for any other node."""
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""


def _quotient_by_product(node) -> bool:
    """a / (b * c), whatever a, b and c are."""
    return (isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div)
            and isinstance(node.right, ast.BinOp) and isinstance(node.right.op, ast.Mult))


def _frame_interval(node) -> bool:
    """The frame-interval arithmetic: round(a / (b * c)), a time in whole steps or whole
    frame intervals, or 1 / (rate * dt), the steps between frames."""
    if isinstance(node, ast.Call) and _name(node.func) == "round" and node.args and _quotient_by_product(node.args[0]):
        return True
    if not (_quotient_by_product(node) and isinstance(node.left, ast.Constant) and node.left.value == 1):
        return False
    factors = {_name(node.right.left), _name(node.right.right)}
    return "dt" in factors and any("rate" in f for f in factors)


def _fillet_fit(node) -> bool:
    """A radius compared with a fillet: whether a ball fits the jar's corners."""
    names = [_name(n) for n in ast.walk(node)] if isinstance(node, ast.Compare) else []
    return any("fillet" in n for n in names) and any("radius" in n for n in names)


# Computations of the rule book's rules by their shape in the syntax tree, whatever the
# names and spacing: a computation made again drifts from the rule book's as a restated
# message does. rule -> a test of one node.
RULE_SHAPES = {
    "the frame-interval rule (rules.frame_every, rules.frame_intervals)": _frame_interval,
    "the ball-fits-the-fillet rule (rules.ball_fits_corners)": _fillet_fit,
}


def computed_rules(path: Path) -> list[tuple[str, int]]:
    """(rule, line) of each computation of a rule of RULE_SHAPES in a file, once per line."""
    tree = ast.parse(path.read_text())
    return sorted({(rule, node.lineno) for node in ast.walk(tree) for rule, shape in RULE_SHAPES.items() if shape(node)},
                  key=lambda found: found[1])


def restated_rules(root: Path) -> list[str]:
    """Rules of the rule book stated again elsewhere: a ConfigError with one of its
    phrases, a computation of the shape of one of its rules, or a time step computed
    from the laws' parts (which the laws themselves combine)."""
    found = []
    for path in sorted(root.rglob("*.py")):
        mod = module_name(path, root)
        if mod == RULE_BOOK:
            continue
        found += [f"{mod}:{line} computes {rule} of {RULE_BOOK}" for rule, line in computed_rules(path)]
        if mod == "taimill.model.laws":
            continue
        found += [f"{mod}:{line} states a rule of {RULE_BOOK} ('{phrase}')"
                  for text, line in config_error_texts(path) for phrase in RULE_PHRASES if phrase in text]
        found += [f"{mod}:{line} computes a time step with laws.{part} (the time-step rule of {RULE_BOOK})"
                  for part, line in time_step_calls(path)]
    return found


def test_each_rule_is_stated_once():
    assert restated_rules(PACKAGE) == []
    assert len(config_error_texts(PACKAGE / "model" / "rules.py")) >= len(RULE_PHRASES)


def test_a_restated_rule_is_named(tmp_path):
    root = tmp_path / "taimill"
    shutil.copytree(PACKAGE, root, ignore=shutil.ignore_patterns("__pycache__"))
    target = root / "runs" / "live.py"
    target.write_text(target.read_text() + 'raise ConfigError("TUI", "jar_rpm", 1, "give either ratio or jar_rpm, not both")\n')
    assert any(v.startswith("taimill.runs.live:") and "'not both'" in v for v in restated_rules(root))


def taichi_imports(path: Path) -> list[tuple[str, int]]:
    """Every way a file reaches a Taichi implementation by name: `import taichi…`,
    `from taichi_forge… import …`, and import_module / __import__ of such a name."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        elif isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) in (
                "import_module", "__import__"):
            names = [a.value for a in node.args[:1] if isinstance(a, ast.Constant) and isinstance(a.value, str)]
        found += [(n, node.lineno) for n in names if n.split(".")[0] in TAICHI_MODULES]
    return found


def outside_the_door(repo: Path) -> list[str]:
    """Imports of a Taichi implementation anywhere in the package, its tests or scripts
    but the door."""
    files = [p for d in ("taimill", "tests", "scripts") for p in sorted((repo / d).rglob("*.py"))]
    return [f"{p.relative_to(repo)}:{line} imports {name} (only {DOOR} may)"
            for p in files if p.relative_to(repo).as_posix() != DOOR for name, line in taichi_imports(p)]


def test_only_the_door_imports_taichi():
    assert outside_the_door(PACKAGE.parent) == []


@pytest.mark.parametrize("file, line", [
    ("taimill/physics/grid.py", "import taichi as ti"),
    ("taimill/physics/engine.py", "from taichi_forge.lang import impl"),
    ("tests/test_laws.py", "kernel_impl = importlib.import_module('taichi.lang.kernel_impl')"),
    ("scripts/bench.py", "import taichi_forge"),
])
def test_a_planted_taichi_import_is_named(tmp_path, file, line):
    root, n = planted(tmp_path, file, line, ("taimill", "tests", "scripts"))
    repo = root.parent
    assert any(v.startswith(f"{file}:{n} imports taichi") for v in outside_the_door(repo)), outside_the_door(repo)


@pytest.mark.parametrize("file, line, rule", [
    ("runs/live.py", "every = max(1, int(round(1.0 / (rate * dt))))", "frame-interval"),
    ("store/run.py", "frames = round(config['duration'] / (steps * step)) + 1", "frame-interval"),
    ("tui/app.py", "per_frame = 1 / (self.trajectory_rate*self.dt)", "frame-interval"),
    ("design/constraints.py", "fits = jar.fillet >= limits.ball_radius - 1e-12", "ball-fits-the-fillet"),
])
def test_a_restated_computation_is_named(tmp_path, file, line, rule):
    # a second statement of a rule's arithmetic, found by its shape whatever its names
    root, n = planted(tmp_path, f"taimill/{file}", line)
    mod = module_name(root / file, root)
    assert [v for v in restated_rules(root) if v.startswith(f"{mod}:")] == [
        next(f"{mod}:{n} computes {r} of {RULE_BOOK}" for r in RULE_SHAPES if rule in r)]


NUMPY_ONLY_TESTS = ("test_analysis", "test_store", "test_cli", "test_layers", "test_golden")


def test_numpy_only_tests_do_not_start_taichi():
    # conftest and these test modules must not import taichi: they test NumPy code.
    code = ("import sys; " + "; ".join(f"import {m}" for m in ("conftest", *NUMPY_ONLY_TESTS))
            + "; sys.exit('taichi' in sys.modules or 'taichi_forge' in sys.modules)")
    tests = Path(__file__).resolve().parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tests), str(PACKAGE.parent), os.environ.get("PYTHONPATH", "")])}
    assert subprocess.run([sys.executable, "-c", code], cwd=tests, env=env).returncode == 0


def test_readme_architecture_names_every_package():
    readme = (PACKAGE.parent / "docs" / "architecture.md").read_text()  # moved out of the README
    section = readme[readme.index("# Architecture"):]
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert packages == {layer for layer in LAYERS if layer and (PACKAGE / layer / "__init__.py").exists()}
    missing = [p for p in sorted(packages) if f"`taimill/{p}/`" not in section]
    assert not missing, f"docs/architecture.md does not describe {missing}"
