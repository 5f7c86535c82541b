"""The two commands of the README: `make run` installs only what running needs, `make
test` adds the test extra; each has its own stamp, so either works first or after the
other (checked with `make -n`, which prints the recipe without running it)."""

import os
import shutil
import subprocess
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
