"""The two commands of the README: `make run` installs only what running needs, `make
test` adds the test extra; each has its own stamp, so either works first or after the
other (checked with `make -n`, which prints the recipe without running it). And the
interpreter `make` builds the environment with: taichi 1.7.4 has wheels for CPython 3.9-3.13
only, so with an unsupported `python3` make takes a supported `python3.1x` from PATH or
stops with one line (checked with a fake interpreter folder as the whole PATH)."""

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
EXPLANATION = "taimill needs Python 3.10 to 3.13"


def fake_interpreters(folder: Path, *, supported: bool) -> Path:
    """A PATH folder whose `python3` reports 3.14 and, with `supported`, a `python3.1x`
    running this very interpreter. The fake runs only `python3 -c CODE` (the Makefile's
    version checks): asked to build a virtual environment it fails, so a Makefile without
    the check can never install anything here."""
    folder.mkdir()
    fake = folder / "python3"
    fake.write_text(f"""#!{sys.executable}
import sys
if sys.argv[1:2] != ["-c"] or len(sys.argv) < 3:
    sys.exit("fake python3 3.14: only -c CODE runs here, not " + " ".join(sys.argv[1:]))
code = sys.argv[2]
sys.argv = ["-c", *sys.argv[3:]]
sys.version_info = (3, 14, 0, "final", 0)
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


def test_fake_python3_reports_3_14(tmp_path):
    folder = fake_interpreters(tmp_path / "bin", supported=False)
    res = subprocess.run([folder / "python3", "-c", "import sys; print(sys.version_info[:2])"], capture_output=True,
                         text=True, timeout=30)
    assert res.stdout.strip() == "(3, 14)"


def test_make_run_with_only_an_unsupported_python3_explains_in_one_line_and_stops(tmp_path):
    venv = tmp_path / "venv"
    res = make_with_path(fake_interpreters(tmp_path / "bin", supported=False), "run", f"VENV={venv}")
    assert res.returncode != 0
    lines = [line for line in res.stderr.splitlines() if EXPLANATION in line]
    assert len(lines) == 1, res.stderr
    assert "3.14" in lines[0] and "make run PYTHON=python3.12" in lines[0]
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
