"""Readers of the energy spectra check what they read (docs/outputs.md, the energy
spectra): a missing or damaged part of a store's `spectra` group is named, never read
as zero events; a statistics-mode store (`[outputs] events = "spectra"`) without its
spectra is damaged; a store from before spectra existed is read from its event rows,
and one with neither refuses in one line. And a store read while `taimill run` writes
it reads whole at every moment: the writer deletes journal segments and rewrites the
spectra at every commit.

The stores are real: written once per module by `taimill run` through the CLI, then
damaged copies read through the CLI (`analyse`, `kinetics predict`)."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zarr

from inprocess import main
from taimill.errors import StoreError
from taimill.store.run import open_run
from taimill.store.writer import ZarrSink

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "presets" / "p4-cy-steel.toml"
FIT = ROOT / "examples" / "outcome" / "fit.toml"  # critical-collisions on the dissipated_normal spectra
RUN = ("--duration", 2.5, "--analysis-start", 1.0, "--powder-mass", 5, "--json")


def command(*args) -> list[str]:
    return [sys.executable, "-m", "taimill", *map(str, args)]


def environment() -> dict:
    """This checkout's taimill in the subprocess, whatever the caller's PYTHONPATH."""
    return os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}


def taimill(*args, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run(command(*args), cwd=ROOT, env=environment(), capture_output=True, text=True, timeout=timeout)


def start(*args) -> subprocess.Popen:
    return subprocess.Popen(command(*args), cwd=ROOT, env=environment(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def one_line(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines()
             if ln.strip() and not ln.startswith(("[Taichi]", "taimill: warning: ", "taimill: compiling"))]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def statistics_preset(folder: Path, trajectory_rate: int = 100) -> Path:
    """The CY preset keeping spectra instead of event rows."""
    text = PRESET.read_text().replace("trajectory_rate = 100", f'trajectory_rate = {trajectory_rate}\nevents = "spectra"')
    assert 'events = "spectra"' in text
    path = folder / "cy-spectra.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def stores(tmp_path_factory) -> dict[str, Path]:
    """A statistics-mode store and a rows store of the same run."""
    folder = tmp_path_factory.mktemp("stores")
    out = {"spectra": folder / "spectra.zarr", "rows": folder / "rows.zarr"}
    for kind, source in (("spectra", statistics_preset(folder)), ("rows", PRESET)):
        res = taimill("run", source, *RUN, "--out", out[kind])
        assert res.returncode == 0, res.stderr
    return out


def copy(stores, kind: str, tmp_path: Path) -> Path:
    path = tmp_path / f"{kind}.zarr"
    shutil.copytree(stores[kind], path)
    return path


def edit_attrs(path: Path, drop=(), **values) -> None:
    meta = path / "zarr.json"
    doc = json.loads(meta.read_text())
    for key in drop:
        doc["attributes"].pop(key, None)
    doc["attributes"].update(values)
    meta.write_text(json.dumps(doc))


def analysed(path) -> dict:
    code, out, err = main("analyse", path, "--json")
    assert code == 0, err
    return json.loads(out)


def predicted(path) -> float:
    code, out, err = main("kinetics", "predict", FIT, path, "--json")
    assert code == 0, err
    t = json.loads(out)["conditions"][0]["time_to_target_s"]
    assert t is not None and math.isfinite(t), f"{path}: time to target {t}"
    return t


def refused(path, *words) -> None:
    """analyse and kinetics predict each refuse the store in one line naming it and `words`."""
    for args in (["analyse", path, "--json"], ["kinetics", "predict", FIT, path]):
        code, out, err = main(*args)
        assert code == 2, (args, out, err)
        line = one_line(err)
        assert str(path) in line and all(w in line for w in words), line
        assert "never" not in out


def test_the_intact_stores_read_the_same_events(stores):
    a, b = analysed(stores["spectra"]), analysed(stores["rows"])
    assert a["event_estimator"]["events"] == b["event_estimator"]["events"] > 0
    assert predicted(stores["spectra"]) == pytest.approx(predicted(stores["rows"]), rel=1e-12)


# ---------------------------------------------------------------- damaged spectra
def _flip(path: Path) -> None:
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    path.write_bytes(bytes(raw))


CHUNK = {name: Path("spectra", name, "c", "0", "0", "0", "0") for name in ("count", "fixed", "energy")} | {
    name: Path("spectra", name, "c", "0") for name in ("lower", "upper", "kind", "measure")}
DAMAGE = {
    **{f"{name} chunk deleted": (lambda p, c=c: (p / c).unlink(), f"spectra/{name}: chunk 0 missing")
       for name, c in CHUNK.items()},
    "count chunk flipped": (lambda p: _flip(p / CHUNK["count"]), "spectra/count: chunk 0 fails its checksum"),
    "fixed array deleted": (lambda p: shutil.rmtree(p / "spectra" / "fixed"), "spectra/fixed: missing"),
    "count metadata garbage": (lambda p: (p / "spectra" / "count" / "zarr.json").write_text("{no"),
                               "spectra/count: metadata unreadable"),
}


@pytest.mark.parametrize("name", sorted(DAMAGE))
def test_a_damaged_spectra_chunk_or_array_is_named_never_read_as_zero(stores, tmp_path, name):
    """Before: one spectra chunk deleted, `analyse` said complete with 0 events (the
    intact store has hundreds) and `kinetics predict` "never"."""
    damage, words = DAMAGE[name]
    path = copy(stores, "spectra", tmp_path)
    damage(path)
    refused(path, words)
    with pytest.raises(StoreError, match=words):
        _ = open_run(path).spectra


def test_a_statistics_mode_store_without_its_spectra_group_is_damaged(stores, tmp_path):
    """Before: `analyse` reported impact power 0, `predict` "never"."""
    path = copy(stores, "spectra", tmp_path)
    shutil.rmtree(path / "spectra")
    refused(path, "spectra: missing")


def test_a_finished_rows_store_without_its_spectra_group_is_damaged(stores, tmp_path):
    path = copy(stores, "rows", tmp_path)
    shutil.rmtree(path / "spectra")
    refused(path, "spectra: missing")


def test_a_store_from_before_spectra_is_read_from_its_event_rows(stores, tmp_path):
    """A store of a taimill before spectra: event rows, no spectra group, no spectra in
    its summary or events_output in its config. Before: `predict` said "never"."""
    path = copy(stores, "rows", tmp_path)
    shutil.rmtree(path / "spectra")
    doc = json.loads((path / "zarr.json").read_text())["attributes"]
    del doc["summary"]["spectra"]
    del doc["config"]["events_output"]
    edit_attrs(path, summary=doc["summary"], config=doc["config"])
    assert predicted(path) == pytest.approx(predicted(stores["rows"]), rel=1e-12)
    assert analysed(path)["event_estimator"] == analysed(stores["rows"])["event_estimator"]
    assert open_run(path).spectra == open_run(stores["rows"]).spectra


def test_a_store_with_neither_spectra_nor_event_rows_refuses_in_one_line(stores, tmp_path):
    """A statistics-mode run killed before it committed its spectra: no spectra, no
    rows to bin them from. Before: `analyse` counted 0 events, `predict` said "never"."""
    path = copy(stores, "spectra", tmp_path)
    shutil.rmtree(path / "spectra")
    edit_attrs(path, drop=("summary", "analysis_window"), status="running")
    refused(path, "spectra: missing", "run it again")


def test_spectra_over_no_time_are_refused_not_never(stores, tmp_path):
    """A statistics-mode run killed before its analysis window: its spectra cover no
    time. Before: `predict` divided by zero seconds."""
    path = copy(stores, "spectra", tmp_path)
    edit_attrs(path, drop=("summary", "analysis_window"), status="running")
    edit_attrs(path / "spectra", end=1.0)
    code, out, err = main("kinetics", "predict", FIT, path)
    assert code == 2 and "never" not in out, (out, err)
    assert "cover no time" in one_line(err) and "run it longer" in one_line(err)


# ---------------------------------------------------------------- a store being written
def test_a_journal_segment_deleted_between_listing_and_reading_is_not_damage(tmp_path, monkeypatch):
    """The race, made deterministic: the writer folds the journal into the arrays and
    deletes it after the reader listed it. Before: "journal/00000001.npz: unreadable"."""
    from taimill.store import run
    from test_store import N_BALLS, energy_block, event_block, frame_block

    path = tmp_path / "run.zarr"
    sink = ZarrSink(path)
    sink.start({}, N_BALLS, np.full(N_BALLS, 0.005))
    rng = np.random.default_rng(0)
    for t in (0.0, 1.0):
        frames = frame_block(rng, 3)
        frames["time"] = t + np.arange(3) * 0.1
        sink.events(event_block(rng, 5))
        sink.frames(frames)
        sink.energy({**energy_block(rng, 3), "time": frames["time"]})
    assert len(list((path / "journal").glob("*.npz"))) == 2
    listed = run._stored_keys

    def listing_then_flush(store, prefix):
        keys = listed(store, prefix)
        if "journal" in prefix and sink.seq:
            sink.flush()  # rows into the arrays, journal deleted: the listing is stale
        return keys

    monkeypatch.setattr(run, "_stored_keys", listing_then_flush)
    store = open_run(path)
    assert store.rows == {"trajectory": 6, "events": 10, "energy": 6}
    np.testing.assert_array_equal(store.frames["time"], [0.0, 0.1, 0.2, 1.0, 1.1, 1.2])


def test_a_store_read_while_taimill_run_writes_it_reads_whole_every_time(tmp_path):
    """Reads of a statistics-mode store while the CLI writes it: its writer rewrites the
    spectra at every commit and, its chunks filling every launch or so, deletes journal
    segments. Every read succeeds, and what it reads only grows. Before: the spectra of
    some reads were missing (zero events, or unreadable), or a segment unreadable."""
    out = tmp_path / "live.zarr"
    proc = start("run", statistics_preset(tmp_path, trajectory_rate=1500), "--duration", 20,
                 "--analysis-start", 1.0, "--out", out, "--json")
    reads, frames, events, failures = 0, 0, 0, []
    try:
        deadline = time.monotonic() + 300
        while not (out / "spectra" / "zarr.json").exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read() if proc.poll() else "timeout"
            time.sleep(0.01)
        while proc.poll() is None and time.monotonic() < deadline:
            try:
                store = open_run(out)
                n, sp = store.rows.get("trajectory", 0), store.spectra
            except StoreError as err:
                failures.append(str(err))
                continue
            reads += 1
            if n < frames or int(sp.count.sum()) < events:
                failures.append(f"read {reads}: {n} frames, {int(sp.count.sum())} events after {frames}, {events}")
            frames, events = max(frames, n), max(events, int(sp.count.sum()))
    finally:
        if proc.poll() is None:
            proc.kill()
        _, err = proc.communicate()
    assert proc.returncode == 0, err
    assert not failures, f"{len(failures)} of {reads + len(failures)} reads failed, e.g. {failures[:3]}"
    assert reads > 20 and events > 0
    store = open_run(out)
    assert store.status == "complete" and int(store.spectra.count.sum()) >= events


def test_spectra_met_mid_rewrite_are_read_once_rewritten_and_a_killed_rewrite_stays_readable(tmp_path, monkeypatch):
    """The other race, made deterministic: a reader meets the spectra while their
    writer rewrites them (count of the new commit, fixed of the old: no events give
    them). It reads them again once the writer is done; a writer killed mid-rewrite
    leaves its generation odd, and the reader then takes them as they are."""
    from taimill.model.spectra import Spectra
    from taimill.store import run
    from taimill.store.layout import CODECS
    from taimill.store.spectra import Busy, SpectraWriter, read_spectra

    def spectra(events: int) -> Spectra:
        sp = Spectra(1.0, 2.0 + events, 0.01)
        sp.count[0, 0, 0, 60] = events
        sp.fixed[0, 0, 0, 60] = events * (1 << 24)
        return sp

    group = zarr.open_group(tmp_path / "s.zarr", mode="w")
    writer = SpectraWriter(group, CODECS)
    writer.write(spectra(3))
    assert read_spectra(group, "s.zarr") == spectra(3)
    half = zarr.open_group(tmp_path / "s.zarr", mode="r+")["spectra"]  # the writer, stopped mid-rewrite
    half.attrs["generation"] = writer.generation + 1
    half["count"][...] = spectra(5).count
    with pytest.raises(Busy):
        read_spectra(group, "s.zarr")
    store = run.RunStore(group)
    monkeypatch.setattr(run.time, "sleep", lambda s: writer.write(spectra(5)))  # the writer goes on meanwhile
    assert store._stored_spectra() == spectra(5)
    half.attrs["generation"] = writer.generation + 1  # killed mid-rewrite: odd for good
    half["count"][...] = spectra(7).count
    monkeypatch.setattr(run.time, "sleep", lambda s: None)
    got = store._stored_spectra()
    assert int(got.count.sum()) == 7 and int(got.fixed.sum()) == 5 << 24
