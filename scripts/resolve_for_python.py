"""Would taimill install on another CPython? Resolves the project's dependencies (and
extras) for CPython VERSION with pip, wheels only, without installing anything:

    python scripts/resolve_for_python.py 3.14 [--extra test] [--extra forge]

pip's `--python-version` picks wheels for that version but evaluates the environment
markers of a project's dependencies with the interpreter it runs on, so a plain
`pip install --dry-run --python-version 3.14 .` on 3.11 asks for taichi, which has no
3.14 wheel. This script evaluates pyproject.toml's markers for VERSION first (as pip
would on that interpreter) and hands pip the resulting requirements. Prints pip's
"Would install …" line and the Taichi it chose; exits with pip's status. Needs the
package index (PyPI)."""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parent.parent


def requirements_for(version: str, extras: list[str]) -> list[str]:
    """pyproject.toml's dependencies and `extras` that apply on CPython `version` on
    Linux, markers evaluated there and dropped."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    lines = [(r, "") for r in project["dependencies"]]
    lines += [(r, e) for e in extras for r in project["optional-dependencies"][e]]
    env = {"python_version": version, "python_full_version": f"{version}.0", "implementation_name": "cpython",
           "platform_python_implementation": "CPython", "sys_platform": "linux", "platform_system": "Linux",
           "os_name": "posix"}
    out = []
    for line, extra in lines:
        req = Requirement(line)
        if req.marker is None or req.marker.evaluate({**env, "extra": extra}):
            req.marker = None
            out.append(str(req))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("version", help="CPython version, e.g. 3.14")
    ap.add_argument("--extra", action="append", default=[], help="an optional-dependencies group (test, forge)")
    args = ap.parse_args(argv)
    reqs = requirements_for(args.version, args.extra)
    print("requirements on CPython", args.version + ":", ", ".join(reqs))
    with tempfile.TemporaryDirectory() as tmp:
        listing = Path(tmp) / "requirements.txt"
        listing.write_text("\n".join(reqs) + "\n")
        res = subprocess.run([sys.executable, "-m", "pip", "install", "--dry-run", "--python-version", args.version,
                              "--only-binary=:all:", "--target", str(Path(tmp) / "target"), "-r", str(listing)],
                             capture_output=True, text=True)
    lines = [ln for ln in (res.stdout + res.stderr).splitlines() if "is ignored: it is neither" not in ln]
    print("\n".join(ln for ln in lines if not ln.lstrip().startswith(("Collecting", "Downloading", "Using cached", "Obtaining"))))
    would = next((ln for ln in lines if ln.startswith("Would install")), "")
    print("Taichi:", " ".join(w for w in would.split() if w.startswith("taichi")) or "none")
    return res.returncode


if __name__ == "__main__":
    sys.exit(main())
