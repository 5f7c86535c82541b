"""Every command of README.md and docs/tutorial.md runs: the fenced `sh` blocks are read
from the files, and each command goes through the real CLI (`taimill.cli.main`, in this
process) in a fresh folder per file, in the order the page gives them, so that a page's
later commands find what its earlier ones stored. Changed only where the real thing
would take too long or cannot run here:

- simulated durations are cut (DURATION: `run` 2 s, `sweep` 1 s per point): the commands,
  options and files are the documented ones;
- `make run` and `make test` are checked with `make -n` and a throw-away VENV (the plan,
  not the installation); the `taimill run` line of `make run`'s plan is then run as
  above, so the quick start finds the store it names;
- `taimill tui` runs headless in a Textual pilot: it starts the mill, pauses, steps one
  frame and quits with `q`;
- `taimill view` runs without a display, where it says so and exits with code 4;
- a sweep both pages show alike runs once (the second page gets a copy of its store).

A command of any other kind fails the test: a page must not show a command this test
cannot run. The glossary is held to the thesis numbers the code cites."""

from __future__ import annotations

import asyncio
import os
import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

import inprocess

ROOT = Path(__file__).resolve().parent.parent
PAGES = ("README.md", "docs/tutorial.md")
DURATION = {"run": "2", "sweep": "1"}  # s of simulated time per run, per sweep point
EXIT_NO_DISPLAY = 4


def commands(page: str) -> list[str]:
    """The commands of a page's ```sh blocks, one per line (a trailing backslash joins
    lines), comments removed."""
    text = (ROOT / page).read_text()
    found = []
    for block in re.findall(r"^```sh\n(.*?)^```", text, flags=re.S | re.M):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words:
                found.append(shlex.join(words))
    return found


def shortened(words: list[str]) -> list[str]:
    """`taimill run|sweep …` with the simulated duration cut to DURATION."""
    duration = DURATION.get(words[1]) if len(words) > 1 else None
    if duration is None:
        return words
    if "--duration" in words:
        i = words.index("--duration")
        return [*words[: i + 1], duration, *words[i + 2:]]
    return [*words, "--duration", duration]


def make_plan(target: str, folder: Path) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES")}
    res = subprocess.run(["make", "--no-print-directory", "-n", target, f"VENV={folder / 'venv'}"], cwd=ROOT,
                         capture_output=True, text=True, timeout=60, env=env)
    assert res.returncode == 0, res.stderr
    return res.stdout.splitlines()


def run_make(words: list[str], folder: Path) -> None:
    assert len(words) == 2 and words[1] in ("run", "test"), f"no way to test {shlex.join(words)!r}"
    plan = make_plan(words[1], folder)
    assert any("-m venv" in line for line in plan), plan  # creates the environment if needed
    if words[1] == "test":
        assert "-m pytest" in plan[-1], plan
        return
    taimill = str(folder / "venv" / "bin" / "taimill")
    line = shlex.split(plan[-1])
    assert line[:2] == [taimill, "run"], plan
    (folder / "runs").mkdir(exist_ok=True)
    run_taimill(["taimill", *line[1:]], folder)


def run_tui(args: list[str], monkeypatch) -> tuple[int, str, str]:
    from taimill.tui.app import MillApp

    def headless(app, *_, **__):
        async def drive():
            async with app.run_test(size=(120, 40)) as pilot:
                await pilot.press("p")  # pause
                await pilot.pause()
                before = app.mill.time
                await pilot.press("s")  # one frame
                for _ in range(200):
                    if app.mill.time > before:
                        break
                    await asyncio.sleep(0.05)
                assert app.mill.time > before, "s did not advance the paused mill"
                await pilot.press("q")
                for _ in range(200):
                    if not app.is_running:
                        break
                    await asyncio.sleep(0.05)
                assert not app.is_running, "q did not quit"

        asyncio.run(drive())

    monkeypatch.setattr(MillApp, "run", headless)
    return inprocess.main(*args)


def run_taimill(words: list[str], folder: Path, monkeypatch=None) -> None:
    args = shortened(words)[1:]
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        if args[0] == "tui":
            code, out, err = run_tui(args, monkeypatch)
        elif args[0] == "view":
            for name in ("DISPLAY", "WAYLAND_DISPLAY"):
                monkeypatch.delenv(name, raising=False)
            code, out, err = inprocess.main(*args)
            assert code == EXIT_NO_DISPLAY and "no display" in err, (code, err)
            return
        else:
            code, out, err = inprocess.main(*args)
    finally:
        os.chdir(cwd)
    assert code == 0, f"`{shlex.join(args)}` exited {code}: {err.strip()[-800:]}"


SWEEPS: dict[str, Path] = {}  # a sweep command already run on another page → its store


def run_sweep_once(words: list[str], folder: Path) -> bool:
    """README and tutorial show the same sweep: run it once and hand the second page a
    copy of its store (runs are bit-identical, so the copy is what the run would write)."""
    if words[1] != "sweep" or "--out" not in words:
        return False
    out = words[words.index("--out") + 1]
    key = shlex.join(shortened(words))
    if key in SWEEPS and SWEEPS[key].parent != folder:
        shutil.copytree(SWEEPS[key], folder / out)
        return True
    SWEEPS[key] = folder / out
    return False


def run_documented(command: str, folder: Path, monkeypatch) -> None:
    words = shlex.split(command)
    if words[0] == "make":
        run_make(words, folder)
    elif words[0] == "taimill":
        if not run_sweep_once(words, folder):
            run_taimill(words, folder, monkeypatch)
    else:
        pytest.fail(f"no way to test the documented command {command!r}")


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """One fresh folder per page, shared by its commands; `presets` and `taimill`
    (for `taimill/data/…` paths) link to the repository's."""
    made = {}
    for page in PAGES:
        folder = tmp_path_factory.mktemp(Path(page).stem)
        for name in ("presets", "jars", "taimill"):
            (folder / name).symlink_to(ROOT / name)
        made[page] = folder
    return made


CASES = [(page, i, command) for page in PAGES for i, command in enumerate(commands(page))]


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
@pytest.mark.parametrize("page, i, command", CASES, ids=[f"{p}:{i}:{c[:60]}" for p, i, c in CASES])
def test_documented_command_runs(page, i, command, folders, monkeypatch):
    run_documented(command, folders[page], monkeypatch)


def test_readme_is_short_and_shows_the_two_commands_and_a_quick_start():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 120
    found = commands("README.md")
    assert found[:2] == ["make run", "make test"]
    assert 5 <= len(found) - 2 <= 10  # the quick start
    for page in re.findall(r"\]\((docs/[^)#]+)", readme):  # the map of docs/ names real pages
        assert (ROOT / page).is_file(), page


def test_tutorial_covers_the_first_hour():
    subcommands = {shlex.split(c)[1] for c in commands("docs/tutorial.md")}
    assert {"run", "analyse", "report", "sweep", "tui", "record", "view"} <= subcommands


def test_a_broken_documented_command_fails_the_check(tmp_path, monkeypatch):
    with pytest.raises(AssertionError, match="exited 2"):
        run_documented("taimill analyse missing.zarr", tmp_path, monkeypatch)
    with pytest.raises(AssertionError, match="exited 2"):
        run_documented("taimill run p4-cy-steel --no-such-option", tmp_path, monkeypatch)
    with pytest.raises(pytest.fail.Exception):
        run_documented("ls", tmp_path, monkeypatch)


def test_durations_are_cut_and_only_where_asked():
    assert shortened(["taimill", "sweep", "p", "--duration", "12", "--out", "k.zarr"]) == \
        ["taimill", "sweep", "p", "--duration", "1", "--out", "k.zarr"]
    assert shortened(["taimill", "run", "p"]) == ["taimill", "run", "p", "--duration", "2"]
    assert shortened(["taimill", "analyse", "k.zarr"]) == ["taimill", "analyse", "k.zarr"]


def test_glossary_defines_every_thesis_number_the_code_cites():
    """Outputs, help texts and docstrings cite the thesis as "eq 3.8", "Table 5.2",
    "Figs 4.10/4.16": each number must be explained in docs/glossary.md."""
    cite = re.compile(r"\b(?:eqs?|Tables?|Figs?)\.? ?(\d+\.\d+[a-z]?(?:\s*(?:/|,|–|-|and)\s*\d+\.\d+[a-z]?)*)")
    glossary = set(re.findall(r"\d+\.\d+", (ROOT / "docs" / "glossary.md").read_text()))
    missing = {}
    for path in sorted((ROOT / "taimill").rglob("*.py")):
        for match in cite.finditer(path.read_text()):
            for number in re.findall(r"\d+\.\d+", match.group(1)):
                if number not in glossary:
                    missing.setdefault(number, path.relative_to(ROOT).as_posix())
    assert not missing, f"cited but not in docs/glossary.md: {missing}"
