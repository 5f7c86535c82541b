"""Faults of `taimill design` through the real CLI (docs/designer.md, faults): one
replica's spread is unknown and nothing is compared; a damaged study database, a second
designer, a full disk, a read-only folder, SIGTERM and Ctrl-C each end in one line with
their exit code, and the study stays resumable by the same command.

Studies here are the smallest the command allows (one design, one replica, 0.3 s runs,
no references): a few seconds each, most of it Taichi's start-up."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import tmpfs

ROOT = Path(__file__).resolve().parent.parent
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}  # the subprocesses import this checkout's taimill
TINY = ("design", "presets/p4-cy-steel.toml", "--trials", 1, "--batch", 1, "--replicas", 1, "--duration", 0.3,
        "--analysis-start", 0.1, "--references", "none", "--workers", 1)
LONGER = ("--trials", 2, "--duration", 3)  # a study still running a second or two after its first batch starts


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run(command(*args), cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=timeout,
                          check=False)


def start(*args, **kw) -> subprocess.Popen:
    return subprocess.Popen(command(*args), cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kw)


def one_line(stderr: str) -> str:
    """The fault's one line; the study's progress lines (design: …) and the compile
    notice said before it aside."""
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith(
        ("[Taichi]", "taimill: warning: ", "taimill: compiling", "design: "))]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def evaluating(proc: subprocess.Popen) -> str:
    """Read the study's stderr until its first batch of designs runs; what was said."""
    said = []
    for line in proc.stderr:
        said.append(line)
        if line.startswith("design: evaluating trials"):
            return "".join(said)
    raise AssertionError(f"the study ended before it evaluated a design: {''.join(said)}")


def left_behind(out: Path) -> list[str]:
    """Files a stopped study must not leave: half-written ones and locks."""
    return sorted(str(p) for p in [*out.rglob("*"), *out.parent.glob(f"{out.name}*.lock")]
                  if ".partial-" in p.name or p.suffix in (".tmp", ".lock") or (p.is_file() and p.stat().st_size == 0))


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("design") / "study"
    res = taimill(*TINY, "--out", out)
    assert res.returncode == 0, res.stderr
    return out


# ------------------------------------------------------------------ one replica
def test_one_replica_says_its_spread_is_unknown_and_compares_nothing(tmp_path):
    out = tmp_path / "one"
    args = [str(a) for a in TINY]
    args[args.index("--references") + 1] = "CY"
    res = taimill(*args, "--reference-ratios=-2.6", "--out", out)
    assert res.returncode == 0, res.stderr
    text = res.stdout
    assert "± 0" not in text, text
    assert "| reference CY |" in text and text.count("± ?") >= 2, text
    assert "beats" not in text and "beat one" in text and "2 or more --replicas" in text, text
    res = json.loads((out / "summary.json").read_text())
    assert res["comparison"] == {} and res["spread"].startswith("unknown: one replica")
    for figs in (res["best"][0]["figures"], res["references"]["CY"]["figures"]):
        mean, spread, values = figs["impact_power_normal"]
        assert spread is None and len(values) == 1 and mean == values[0]
    jar = (out / "best" / "design-1.toml").read_text()
    assert "± ? W (spread unknown: 1 replica)" in jar and "± 0" not in jar
    docs = (ROOT / "docs" / "designer.md").read_text()  # the docs say what the summary says
    assert "± ?" in docs and "2 or more `--replicas`" in docs


# ------------------------------------------------------------------ a damaged database
def _flip(db: Path):
    data = bytearray(db.read_bytes())
    data[2 * 4096] ^= 0xFF  # page 3's page-type byte: the b-tree there no longer reads
    db.write_bytes(bytes(data))


DAMAGE = {
    "truncated": (lambda db: db.write_bytes(db.read_bytes()[: db.stat().st_size // 3]),
                  "damaged (database disk image is malformed)"),
    "bit-flipped": (_flip, "damaged ("),
    "text": (lambda db: db.write_text("my notes, saved over the study\n"), "not an SQLite database"),
    "folder": (lambda db: (db.unlink(), db.mkdir()), "is a folder, not an SQLite file"),
}


@pytest.mark.parametrize("name", sorted(DAMAGE))
def test_a_damaged_study_database_is_refused_in_one_line_saying_how_to_recover(study, tmp_path, name):
    damage, words = DAMAGE[name]
    out = tmp_path / "study"
    shutil.copytree(study, out)
    db = out / "study.db"
    damage(db)
    before = db.read_bytes() if db.is_file() else None
    res = taimill(*TINY, "--trials", 2, "--out", out)  # resumed with more trials
    line = one_line(res.stderr)
    assert res.returncode == 2 and res.stdout == "", res.stderr
    assert line.startswith(f"taimill: error: {db}: study database: {words}"), line
    assert ("move it away to start a new study, or restore it from a copy "
            f"(the designs already written are in {out / 'jars'}") in line
    assert "design: evaluating" not in res.stderr  # refused before anything ran
    assert (db.read_bytes() if db.is_file() else None) == before and left_behind(out) == []


# ------------------------------------------------------------------ two designers
def test_a_second_designer_on_a_running_study_is_refused_naming_the_first(tmp_path):
    out = tmp_path / "study"
    first = start(*TINY, *LONGER, "--out", out)
    try:
        evaluating(first)
        second = taimill(*TINY, *LONGER, "--out", out)
        line = one_line(second.stderr)
        assert second.returncode == 2 and second.stdout == "", second.stderr
        assert line.startswith(f"taimill: error: {out / 'study.db'}: in use: pid {first.pid} on "), line
        assert "(taimill design presets/p4-cy-steel.toml --trials 1" in line and "--out " + str(out) in line, line
        _, err = first.communicate(timeout=300)
    finally:
        first.kill()
    assert first.returncode == 0, err  # the refused one changed nothing
    assert json.loads((out / "summary.json").read_text())["evaluated"] == 2 and left_behind(out) == []


def test_two_designers_started_together_one_runs_the_other_is_refused(tmp_path):
    out = tmp_path / "study"
    procs = [start(*TINY, "--out", out) for _ in range(2)]
    said = [p.communicate(timeout=300) for p in procs]
    done = [(p.returncode, stdout, stderr) for p, (stdout, stderr) in zip(procs, said)]
    codes = sorted(code for code, _, _ in done)
    assert codes == [0, 2], done
    (refused,) = [err for code, _, err in done if code == 2]
    assert f"{out / 'study.db'}: in use: pid " in one_line(refused)
    assert json.loads((out / "summary.json").read_text())["evaluated"] == 1 and left_behind(out) == []


# ------------------------------------------------------------------ a full disk, a read-only folder
@pytest.fixture
def small_disk(tmp_path):
    with tmpfs(tmp_path / "disk", "size=1m") as mnt:
        yield mnt


# free space left: 60 kB fills the database while the study is created (SQLite's
# "database or disk is full"), 200 kB the report page after the designs ran (ENOSPC)
@pytest.mark.parametrize("free_kb", [60, 200])
def test_a_full_disk_exits_5_saying_the_study_is_kept_and_resumes(small_disk, free_kb):
    filler = small_disk / "filler"
    st = os.statvfs(small_disk)
    filler.write_bytes(b"\0" * (st.f_bavail * st.f_frsize - free_kb * 1024))
    out = small_disk / "study"
    res = taimill(*TINY, "--out", out)
    line = one_line(res.stderr)
    assert res.returncode == 5, res.stderr
    assert line.startswith(f"taimill: error: {out}/"), line
    assert "database or disk is full" in line or "No space left on device" in line, line
    assert line.endswith(f"the study so far is in {out / 'study.db'}; the same command resumes it"), line
    assert [p for p in left_behind(out) if not p.endswith(".toml")] == []  # an empty jar file is the disk's doing
    filler.unlink()
    again = taimill(*TINY, "--out", out)
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "summary.json").read_text())["evaluated"] == 1


@pytest.fixture
def read_only(tmp_path, study):
    """A copy of the study on a read-only bind mount (root ignores chmod)."""
    src, mnt = tmp_path / "src", tmp_path / "ro"
    shutil.copytree(study, src / "study")
    mnt.mkdir()
    res = subprocess.run(["mount", "--bind", str(src), str(mnt)], capture_output=True, text=True, check=False)
    if res.returncode != 0:
        pytest.skip(f"cannot bind-mount here ({res.stderr.strip() or res.returncode})")
    try:
        res = subprocess.run(["mount", "-o", "remount,ro,bind", str(mnt)], capture_output=True, text=True, check=False)
        if res.returncode != 0:
            pytest.skip(f"cannot remount read-only here ({res.stderr.strip() or res.returncode})")
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.mark.parametrize("which", ["the study's folder", "a new folder"])
def test_a_read_only_out_folder_is_refused_before_anything_runs(read_only, which):
    out = read_only / ("study" if which == "the study's folder" else "new")
    before = sorted(p.name for p in read_only.rglob("*"))
    res = taimill(*TINY, "--trials", 2, "--out", out)
    line = one_line(res.stderr)
    assert res.returncode == 2 and res.stdout == "", res.stderr
    assert line.startswith(f"taimill: error: command line: --out = '{out}': ") and "not writable" in line, line
    assert "design: evaluating" not in res.stderr and sorted(p.name for p in read_only.rglob("*")) == before


# ------------------------------------------------------------------ SIGTERM, Ctrl-C
@pytest.mark.parametrize("sig, code, said", [(signal.SIGTERM, 143, "terminated (SIGTERM)"),
                                             (signal.SIGINT, 130, "interrupted")], ids=["SIGTERM", "Ctrl-C"])
def test_a_stopped_study_says_so_in_one_line_and_the_same_command_resumes_it(tmp_path, sig, code, said):
    out = tmp_path / "study"
    # Ctrl-C reaches the whole process group (the workers too), SIGTERM the designer alone
    proc = start(*TINY, *LONGER, "--out", out, start_new_session=True)
    try:
        before = evaluating(proc)
        time.sleep(1.0)
        if sig == signal.SIGINT:
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == code, before + err
    assert one_line(err) == f"taimill: {said}; the study so far is in {out / 'study.db'}; the same command resumes it"
    assert left_behind(out) == []  # no lock, no half-written file
    again = taimill(*TINY, *LONGER, "--out", out)
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "summary.json").read_text())["evaluated"] == 2
