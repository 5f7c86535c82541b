"""Faults of `taimill kinetics fit` and `taimill kinetics predict`, through the real CLI
(docs/outcome.md, files and commands): outputs replaced only with --overwrite and only
over taimill's own fit file or figure, never over an input; every output checked
before the fit and written all or none (a full disk, Ctrl-C, SIGTERM leave nothing
that blocks the rerun); fit files validated on load; measured values outside the
model's range (percent for a fraction) refused.

The inputs are the shipped synthetic example (examples/outcome): a fit takes about a
second, each case one or two subprocesses."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import tmpfs

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "outcome"
USER_PICTURE = b"\x89PNG\r\n\x1a\n a picture the user made"


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def taimill(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run(command(*args), cwd=cwd, capture_output=True, text=True, timeout=300, check=False,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith("taimill: warning: ")]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def refused(res, *words, code=2) -> str:
    """The one-line refusal of `res` (exit `code`, nothing on stdout) holding `words`."""
    line = one_line(res.stderr)
    assert res.returncode == code, res.stderr
    assert line.startswith("taimill: error: ") and res.stdout == "", (res.stdout, line)
    for w in words:
        assert w in line, (w, line)
    return line


def files(folder: Path) -> dict:
    """name -> bytes of every file in `folder` (links as their target's name)."""
    return {p.name: (os.readlink(p) if p.is_symlink() else p.read_bytes()) for p in sorted(folder.iterdir())
            if not p.is_dir() or p.is_symlink()}


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> Path:
    """The example's inputs and a fit file and figures taimill wrote from them."""
    d = tmp_path_factory.mktemp("kin")
    for name in ("points.csv", "condition-a.json", "condition-b.json", "condition-c.json"):
        shutil.copy(EXAMPLE / name, d / name)
    res = taimill("kinetics", "fit", "points.csv", "--out", "fit.toml", "--figure", "fit.png", cwd=d)
    assert res.returncode == 0, res.stderr
    return d


@pytest.fixture
def work(fitted, tmp_path) -> Path:
    """A fresh copy of `fitted` for a case that writes."""
    d = tmp_path / "w"
    shutil.copytree(fitted, d)
    return d


# ------------------------------------------------------------------ --overwrite
@pytest.mark.parametrize("out, overwrite, words", [
    ("points.csv", False, ("--out", "points.csv", "exists; pass --overwrite")),
    ("points.csv", True, ("--out", "points.csv", "is an input of this command", "not replaced")),
    ("link.toml", True, ("--out", "link.toml", "is an input of this command")),  # a link to the points
])
def test_fit_never_writes_over_its_own_measurements(work, out, overwrite, words):
    (work / "link.toml").symlink_to("points.csv")
    before = files(work)
    res = taimill("kinetics", "fit", "points.csv", "--out", out, *(["--overwrite"] if overwrite else []), cwd=work)
    refused(res, *words)
    assert files(work) == before


def test_an_existing_fit_is_replaced_only_with_overwrite_and_only_if_taimill_wrote_it(work):
    old = (work / "fit.toml").read_bytes()
    refused(taimill("kinetics", "fit", "points.csv", "--out", "fit.toml", cwd=work), "--out", "--overwrite")
    assert (work / "fit.toml").read_bytes() == old
    (work / "fit.toml").write_bytes(old.replace(b"kappa_g\" = 2", b"kappa_g\" = 3"))
    res = taimill("kinetics", "fit", "points.csv", "--out", "fit.toml", "--overwrite", cwd=work)
    assert res.returncode == 0, res.stderr
    assert (work / "fit.toml").read_bytes() == old  # replaced by the same fit
    (work / "notes.toml").write_text("# my lab notes\nkappa = 1\n")
    refused(taimill("kinetics", "fit", "points.csv", "--out", "notes.toml", "--overwrite", cwd=work),
            "--out", "notes.toml", "not a fit file written by taimill", "not replaced")
    assert (work / "notes.toml").read_text() == "# my lab notes\nkappa = 1\n"
    assert sorted(files(work)) == sorted(["points.csv", "condition-a.json", "condition-b.json", "condition-c.json",
                                          "fit.toml", "fit.png", "notes.toml"])  # no partial, no lock


@pytest.mark.parametrize("argv", [
    ["predict", "fit.toml", "condition-c.json", "--figure", "mine.png"],
    ["fit", "points.csv", "--out", "new.toml", "--figure", "mine.png"],
    ["fit", "points.csv", "--out", "new.toml", "--stress-figure", "mine.png"],
])
def test_a_picture_the_user_made_is_never_overwritten(work, argv):
    (work / "mine.png").write_bytes(USER_PICTURE)
    refused(taimill("kinetics", *argv, cwd=work), "mine.png", "exists; pass --overwrite")
    refused(taimill("kinetics", *argv, "--overwrite", cwd=work), "mine.png", "not a figure written by taimill",
            "not replaced")
    assert (work / "mine.png").read_bytes() == USER_PICTURE
    assert not (work / "new.toml").exists()


def test_predict_replaces_a_figure_taimill_drew_with_overwrite(work):
    old = (work / "fit.png").read_bytes()
    refused(taimill("kinetics", "predict", "fit.toml", "condition-c.json", "--figure", "fit.png", cwd=work),
            "--figure", "--overwrite")
    assert (work / "fit.png").read_bytes() == old
    res = taimill("kinetics", "predict", "fit.toml", "condition-c.json", "--figure", "fit.png", "--overwrite", cwd=work)
    assert res.returncode == 0, res.stderr
    assert (work / "fit.png").read_bytes() != old and (work / "fit.png").read_bytes().startswith(b"\x89PNG")


# ------------------------------------------------------------------ fit files validated on load
def _edit(text: str, key: str, value: str) -> str:
    """The fit file with the line of `key` (top level or "table.name") given `value`."""
    table, _, name = key.rpartition(".")
    pattern = rf'^("{name}"|{name}) = .*$'
    if table:
        head, sep, rest = text.partition(f"[{table}]\n")
        body, nxt, tail = rest.partition("\n[")
        body, n = re.subn(pattern, lambda m: f"{m.group(1)} = {value}", body, count=1, flags=re.MULTILINE)
        assert n == 1, key
        return head + sep + body + nxt + tail
    text, n = re.subn(pattern, lambda m: f"{m.group(1)} = {value}", text, count=1, flags=re.MULTILINE)
    assert n == 1, key
    return text


NEGATIVE_VARIANCE = "[[-0.0012, 0.0007], [0.0007, 0.0005]]"
ASYMMETRIC = "[[0.0012, 0.0007], [-0.0007, 0.0005]]"
NOT_PSD = "[[0.0012, 0.0009], [0.0009, 0.0005]]"  # |r| > 1


@pytest.mark.parametrize("key, value, words", [
    ("covariance", NEGATIVE_VARIANCE, ("covariance[0][0]", "-0.0012", "[0, ∞)", "variance of kappa_g")),
    ("parameters.kappa_g", "nan", ("parameters.kappa_g", "nan", "(0, ∞)")),
    ("parameters.kappa_g", "-2e-05", ("parameters.kappa_g", "-2e-05", "(0, ∞)")),
    ("parameters.e_star_J", "inf", ("parameters.e_star_J", "inf", "finite")),
    ("covariance", ASYMMETRIC, ("covariance[0][1]", "symmetric")),
    ("covariance", NOT_PSD, ("covariance", "positive semi-definite")),
    ("covariance", "[[0.001, nan], [nan, 0.0005]]", ("covariance[0][1]", "nan", "finite")),
    ("covariance", "[[0.001]]", ("covariance", "2 × 2")),
    ("level", "95", ("level", "95", "[0.5, 1)")),
    ("goodness.dof", "0", ("goodness.dof", "0", "[1, ∞)")),
    ("goodness.p_value", "1.5", ("goodness.p_value", "1.5", "[0, 1]")),
    ("intervals.kappa_g", "[3e-05, 1e-05]", ("intervals.kappa_g", "lower ≤ upper")),
    ("correlation.kappa_g:e_star_J", "1.7", ("correlation.kappa_g:e_star_J", "1.7", "[-1, 1]")),
    ("sigma", '"roughly"', ("sigma", "roughly", "'given'")),
])
def test_a_damaged_fit_file_is_one_line_naming_file_key_value_and_range(fitted, tmp_path, key, value, words):
    good = (fitted / "fit.toml").read_text()
    bad = tmp_path / "edited.toml"
    bad.write_text(_edit(good, key, value))
    res = taimill("kinetics", "predict", bad, fitted / "condition-c.json", cwd=tmp_path)
    line = refused(res, *words)
    assert line.startswith(f"taimill: error: {bad}: "), line


# ------------------------------------------------------------------ values outside the model's range
@pytest.mark.parametrize("value", ["95", "1.2", "-0.2"])
def test_a_conversion_outside_0_1_is_refused_naming_line_and_range(work, value):
    lines = (work / "points.csv").read_text().splitlines()
    n = next(i for i, ln in enumerate(lines) if ln.startswith("condition-b.json")) + 1
    lines[n - 1] = re.sub(r",[0-9.]+,0\.03$", f",{value},0.03", lines[n - 1])
    (work / "p.csv").write_text("\n".join(lines) + "\n")
    res = taimill("kinetics", "fit", "p.csv", "--out", "p.toml", cwd=work)
    refused(res, f"p.csv:{n}", "column 3 (value)", value.rstrip("0"), "[0, 1] (a fraction; percent? divide by 100)")
    assert not (work / "p.toml").exists()
    res = taimill("kinetics", "predict", "fit.toml", "condition-c.json", "--points", "p.csv", cwd=work)
    refused(res, f"p.csv:{n}", "column 3 (value)", "percent? divide by 100")


# ------------------------------------------------------------------ outputs checked before the work
@pytest.mark.parametrize("argv, words", [
    (["fit", "points.csv", "--out", "new.toml", "--figure", "x.json"], ("--figure", "x.json", ".png or .svg")),
    (["fit", "points.csv", "--out", "new.toml", "--stress-figure", "x.pdf"], ("--stress-figure", ".png or .svg")),
    (["fit", "points.csv", "--out", "new.toml", "--figure", "nope/x.png"], ("--figure", "does not exist")),
    (["fit", "points.csv", "--out", "new.toml", "--figure", "a.png", "--stress-figure", "a.png"],
     ("--stress-figure", "is also --figure")),
    (["predict", "fit.toml", "condition-c.json", "--figure", "x.json"], ("--figure", "x.json", ".png or .svg")),
])
def test_a_bad_figure_path_is_refused_before_the_fit(work, argv, words):
    before = files(work)
    refused(taimill("kinetics", *argv, cwd=work), *words)
    assert files(work) == before  # no new.toml: nothing was fitted and written first


@pytest.fixture
def read_only(tmp_path):
    """A read-only folder: a read-only tmpfs (root ignores chmod)."""
    with tmpfs(tmp_path / "ro", "ro", "size=1m") as mnt:
        yield mnt


@pytest.mark.parametrize("option", ["--out", "--figure", "--stress-figure"])
def test_a_read_only_folder_is_refused_before_the_fit(work, read_only, option):
    outs = {"--out": "new.toml", option: str(read_only / ("new.toml" if option == "--out" else "fig.png"))}
    before = files(work)
    argv = ["kinetics", "fit", "points.csv"] + [x for kv in outs.items() for x in kv]
    refused(taimill(*argv, cwd=work), option, "not writable")
    assert files(work) == before


def test_predict_refuses_a_read_only_figure_folder(work, read_only):
    refused(taimill("kinetics", "predict", "fit.toml", "condition-c.json", "--figure", read_only / "p.png", cwd=work),
            "--figure", "not writable")


# ------------------------------------------------------------------ full disk, signals
@pytest.fixture
def full_disk(tmp_path):
    """A 2 MB tmpfs filled but for about 12 kB: room for a fit file, not for a figure."""
    with tmpfs(tmp_path / "disk", "size=2m", free_bytes=12 * 1024) as mnt:
        yield mnt


def test_a_full_disk_is_exit_5_one_line_and_leaves_nothing_half_written(work, full_disk):
    argv = ["kinetics", "fit", "points.csv", "--out", full_disk / "fit.toml", "--figure", full_disk / "fit.png"]
    res = taimill(*argv, cwd=work)
    line = refused(res, "No space left on device", code=5)
    assert str(full_disk / "fit.png") in line or str(full_disk / "fit.toml") in line
    assert sorted(p.name for p in full_disk.iterdir()) == ["filler"]  # no fit without its figure, no partial, no lock
    (full_disk / "filler").unlink()
    res = taimill(*argv, cwd=work)  # the same command, once there is room
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in full_disk.iterdir()) == ["fit.png", "fit.toml"]


@pytest.mark.parametrize("sig, code, words", [(signal.SIGTERM, 143, "terminated (SIGTERM)"),
                                              (signal.SIGINT, 130, "interrupted")])
def test_an_interrupted_fit_keeps_the_old_fit_and_leaves_nothing_that_blocks_the_rerun(work, sig, code, words):
    old = {n: (work / n).read_bytes() for n in ("fit.toml", "fit.png")}
    argv = command("kinetics", "fit", "points.csv", "--out", "fit.toml", "--figure", "fit.png", "--overwrite")
    proc = subprocess.Popen(argv, cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    lock = work / "fit.toml.lock"  # taken once the outputs are checked, before the fit
    end = time.monotonic() + 120
    while not lock.exists() and proc.poll() is None and time.monotonic() < end:
        time.sleep(0.002)
    assert lock.exists(), "the fit never held its output"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    line = one_line(err)
    assert proc.returncode == code, err
    assert line.startswith(f"taimill: {words}") and "fit.toml is unchanged" in line, line
    assert {n: (work / n).read_bytes() for n in old} == old
    assert sorted(p.name for p in work.iterdir()) == sorted(["points.csv", "condition-a.json", "condition-b.json",
                                                             "condition-c.json", "fit.toml", "fit.png"])
    res = subprocess.run(argv, cwd=work, capture_output=True, text=True, timeout=300, check=False,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert res.returncode == 0, res.stderr
