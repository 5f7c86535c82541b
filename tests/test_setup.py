"""The two commands of the README: `make run` installs only what running needs, `make
test` adds the test extra; each has its own stamp, so either works first or after the
other (checked with `make -n`, which prints the recipe without running it). And the
interpreter `make` builds the environment with: taimill runs on CPython 3.10-3.14 (taichi
1.7.4 up to 3.13, the fork taichi-forge on 3.14), so with an unsupported `python3` make
takes a supported `python3.1x` from PATH or stops with one line (checked with a fake
interpreter folder as the whole PATH). And which Taichi pyproject.toml installs on which
Python (its environment markers, evaluated as pip evaluates them)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="needs make")


def planned(target: str, venv: Path) -> list[str]:
    # under `make test` the parent make's variables would make this one print
    # "Entering/Leaving directory" lines around its plan: run it as a user would
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES")}
    res = subprocess.run(["make", "--no-print-directory", "-n", target, f"VENV={venv}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=60, env=env)
    assert res.returncode == 0, res.stderr
    return res.stdout.splitlines()


def installs(lines: list[str]) -> list[str]:
    return [line for line in lines if "pip install" in line and "--upgrade pip" not in line]


def test_make_run_on_a_fresh_clone_installs_the_package_without_the_test_extra(tmp_path):
    lines = planned("run", tmp_path / "venv")
    assert any("-m venv" in line for line in lines)
    pip = installs(lines)
    assert len(pip) == 1 and pip[0].endswith("-e .")
    assert not any("[test]" in line or "-m pytest" in line for line in lines)
    assert "taimill run" in lines[-1]


def test_make_test_alone_installs_the_test_extra(tmp_path):
    lines = planned("test", tmp_path / "venv")
    assert any("-m venv" in line for line in lines)
    assert [line.split()[-1] for line in installs(lines)] == ["'.[test]'"]
    assert "-m pytest" in lines[-1]


def test_make_test_after_make_run_adds_the_test_extra_and_make_run_after_it_installs_nothing(tmp_path):
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").touch()
    (venv / ".installed-run").touch()  # as `make run` leaves it
    assert not installs(planned("run", venv))
    lines = planned("test", venv)
    assert not any("-m venv" in line for line in lines)
    assert [line.split()[-1] for line in installs(lines)] == ["'.[test]'"]
    (venv / ".installed-test").touch()
    assert not installs(planned("test", venv)) and not installs(planned("run", venv))


MAKE = shutil.which("make")
EXPLANATION = "taimill needs Python 3.10 to 3.14"
UNSUPPORTED = (3, 15)  #: a CPython neither taichi nor taichi-forge has wheels for


def fake_interpreters(folder: Path, *, supported: bool, version: tuple = UNSUPPORTED) -> Path:
    """A PATH folder whose `python3` reports `version` and, with `supported`, a `python3.1x`
    running this very interpreter. The fake runs only `python3 -c CODE` (the Makefile's
    version checks): asked to build a virtual environment it fails, so a Makefile without
    the check can never install anything here."""
    folder.mkdir()
    fake = folder / "python3"
    fake.write_text(f"""#!{sys.executable}
import sys
if sys.argv[1:2] != ["-c"] or len(sys.argv) < 3:
    sys.exit("fake python3 {version[0]}.{version[1]}: only -c CODE runs here, not " + " ".join(sys.argv[1:]))
code = sys.argv[2]
sys.argv = ["-c", *sys.argv[3:]]
sys.version_info = ({version[0]}, {version[1]}, 0, "final", 0)
exec(compile(code, "<string>", "exec"), {{"__name__": "__main__"}})
""")
    fake.chmod(0o755)
    if supported:
        real = folder / f"python3.{sys.version_info[1]}"
        real.write_text(f'#!/bin/sh\nexec {sys.executable} "$@"\n')
        real.chmod(0o755)
    return folder


def make_with_path(folder: Path, *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items()
           if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES", "PYTHON", "VENV", "PATH")}
    env["PATH"] = str(folder)  # nothing else: no system python3 can answer for the fake
    return subprocess.run([MAKE, "--no-print-directory", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=60, env=env)


def test_fake_python3_reports_its_version(tmp_path):
    folder = fake_interpreters(tmp_path / "bin", supported=False)
    res = subprocess.run([folder / "python3", "-c", "import sys; print(sys.version_info[:2])"], capture_output=True,
                         text=True, timeout=30)
    assert res.stdout.strip() == str(UNSUPPORTED)


def test_make_run_with_only_an_unsupported_python3_explains_in_one_line_and_stops(tmp_path):
    venv = tmp_path / "venv"
    res = make_with_path(fake_interpreters(tmp_path / "bin", supported=False), "run", f"VENV={venv}")
    assert res.returncode != 0
    lines = [line for line in res.stderr.splitlines() if EXPLANATION in line]
    assert len(lines) == 1, res.stderr
    assert "3.15" in lines[0] and "make run PYTHON=python3.12" in lines[0]
    assert not venv.exists()  # stopped before creating anything


def test_make_run_takes_a_supported_python3_1x_beside_an_unsupported_python3(tmp_path):
    folder = fake_interpreters(tmp_path / "bin", supported=True)
    chosen = f"python3.{sys.version_info[1]}"
    res = make_with_path(folder, "-n", "run", f"VENV={tmp_path / 'venv'}")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    check = next(line for line in lines if EXPLANATION in line)
    assert check.lstrip("@").startswith(f"{chosen} -c ")
    assert any(line.startswith(f"{chosen} -m venv ") for line in lines), res.stdout
    assert not any(line.startswith("python3 ") for line in lines)
    # the check make would run with it passes: the same line, same PATH
    ran = subprocess.run(["/bin/sh", "-c", check.lstrip("@")], capture_output=True, text=True, timeout=30,
                         env={"PATH": str(folder)})
    assert ran.returncode == 0, ran.stderr


def test_make_builds_the_environment_with_a_python3_that_is_3_14(tmp_path):
    """Python 3.14 is supported (through taichi-forge): make takes it as it is."""
    folder = fake_interpreters(tmp_path / "bin", supported=True, version=(3, 14))
    res = make_with_path(folder, "-n", "run", f"VENV={tmp_path / 'venv'}")
    assert res.returncode == 0, res.stderr
    assert any(line.startswith("python3 -m venv ") for line in res.stdout.splitlines()), res.stdout


def taichis_for(python: str, extras: tuple[str, ...] = ()) -> list[str]:
    """The Taichi distributions pyproject.toml's dependencies (and `extras`) install on
    CPython `python` ("3.12"), their markers evaluated as pip evaluates them there."""
    import tomllib

    from packaging.requirements import Requirement

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [(r, "") for r in project["dependencies"]]
    reqs += [(r, e) for e in extras for r in project["optional-dependencies"][e]]
    env = {"python_version": python, "python_full_version": python + ".0"}
    wanted = [(Requirement(r), extra) for r, extra in reqs]
    return sorted(req.name for req, extra in wanted
                  if req.name.startswith("taichi") and (req.marker is None or req.marker.evaluate({**env, "extra": extra})))


@pytest.mark.parametrize("python, expected", [("3.10", ["taichi"]), ("3.11", ["taichi"]), ("3.13", ["taichi"]),
                                              ("3.14", ["taichi-forge"])])
def test_each_python_gets_one_taichi(python, expected):
    assert taichis_for(python) == expected


def test_the_forge_extra_adds_the_fork_beside_taichi():
    assert taichis_for("3.11", ("forge",)) == ["taichi", "taichi-forge"]


def test_requires_python_admits_3_10_to_3_14():
    import tomllib

    from packaging.specifiers import SpecifierSet

    spec = SpecifierSet(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["requires-python"])
    assert [v for v in ("3.9", "3.10", "3.13", "3.14", "3.15") if spec.contains(v + ".0")] == ["3.10", "3.13", "3.14"]
