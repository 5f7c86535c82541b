"""Damaged stores caught on read (issue 36, docs/outputs.md): every array of a new store
carries a CRC-32C per chunk, so a flipped byte is named instead of decoding into other
numbers; the arrays are checked against the stored config; a stale journal is named.
Stores written before the checksums still read. The store is a real run's, through the
CLI in a subprocess."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import zarr

from inprocess import main
from taimill.errors import StoreError
from taimill.store.chunks import put_npz
from taimill.store.layout import COMPRESSOR
from taimill.store.run import open_run

ROOT = Path(__file__).resolve().parent.parent
PRESET = "presets/p4-cy-steel.toml"


@pytest.fixture(scope="module")
def run_store(tmp_path_factory):
    """A complete 0.3 s run (31 frames of 12 balls of 6 mm at 100 frames/s)."""
    out = tmp_path_factory.mktemp("crc") / "run.zarr"
    res = subprocess.run([sys.executable, "-m", "taimill", "run", PRESET, "--duration", "0.3", "--out", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    return out


def copy(src: Path, tmp_path: Path) -> Path:
    path = tmp_path / "run.zarr"
    shutil.copytree(src, path)
    return path


def arrays(path: Path) -> list[str]:
    """Every array of a run store, as its path inside the store."""
    return sorted(str(m.parent.relative_to(path)) for m in path.rglob("zarr.json")
                  if json.loads(m.read_text())["node_type"] == "array")


def test_every_array_of_a_new_store_ends_its_codecs_with_crc32c(run_store):
    names = arrays(run_store)
    assert {"radii", "trajectory/position", "events/un", "energy/kinetic"} <= set(names)
    for name in names:
        codecs = json.loads((run_store / name / "zarr.json").read_text())["codecs"]
        # names (the spectra's coordinates) are variable-length strings: zarr's vlen-utf8 in place of bytes
        assert [c["name"] for c in codecs][1:] == ["blosc", "crc32c"], name
        assert codecs[0]["name"] == ("vlen-utf8" if name.startswith("spectra/") and "/" in name and
                                     name.split("/")[1] in ("kind", "class", "measure") else "bytes"), name


def flip(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x10
    path.write_bytes(bytes(data))


# one array of each group, and the radii; chunk 0 is the only chunk of a 0.3 s run
CHUNKS = {"radii": "radii/c/0", "trajectory/position": "trajectory/position/c/0/0/0",
          "trajectory/time": "trajectory/time/c/0", "events/un": "events/un/c/0", "energy/kinetic": "energy/kinetic/c/0"}


@pytest.mark.parametrize("array", sorted(CHUNKS))
def test_a_flipped_byte_in_any_group_is_named_on_read(run_store, tmp_path, array):
    path = copy(run_store, tmp_path)
    flip(path / CHUNKS[array])
    code, _, err = main("analyse", path)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0] == f"taimill: error: {path}: {array}: chunk 0 fails its checksum (its bytes changed after they were written)"
    with pytest.raises(StoreError, match=f"{array}: chunk 0 fails its checksum"):
        store = open_run(path)
        store.column(*array.split("/"))


def test_a_store_without_checksums_still_reads(run_store, tmp_path):
    # a store written before the checksums: every array rewritten by plain zarr with the
    # codecs of then (bytes, Blosc LZ4)
    path = copy(run_store, tmp_path)
    root = zarr.open_group(path, mode="r+")
    for name in arrays(path):
        old = root[name]
        data, attrs, dims = old[:], old.attrs.asdict(), old.metadata.dimension_names
        new = root.create_array(name, shape=data.shape, chunks=old.chunks, dtype=data.dtype, fill_value=old.fill_value,
                                dimension_names=dims, attributes=attrs, compressors=COMPRESSOR, overwrite=True)
        new[:] = data
    assert all("crc32c" not in (path / n / "zarr.json").read_text() for n in arrays(path))
    got, want = open_run(path), open_run(run_store)
    for table in ("frames", "events", "energy"):
        for k, v in getattr(want, table).items():
            np.testing.assert_array_equal(getattr(got, table)[k], v, err_msg=f"{table}/{k}")
    code, out, err = main("analyse", path)
    assert code == 0 and not err.strip(), err
    assert out == main("analyse", run_store)[1]


def _edit_config(path: Path, **balls_or_top):
    meta = path / "zarr.json"
    doc = json.loads(meta.read_text())
    config = doc["attributes"]["config"]
    for key, value in balls_or_top.items():
        if key.startswith("balls_"):
            config["balls"][key[len("balls_"):]] = value
        else:
            config[key] = value
    meta.write_text(json.dumps(doc))


CONTRADICTIONS = {
    "radius": ({"balls_radius": 0.005}, "radii: ball 0 has radius 0.006 m, but the stored config's balls are 0.005 m (12 balls differ)"),
    "count": ({"balls_count": 13}, "attrs.n_balls: 12 balls, but the stored config has 13"),
    "more frames": ({"duration": 0.1}, "trajectory: 31 committed frames, but the stored config's 0.1 s at 100 frames/s"),
    "complete with fewer": ({"duration": 0.6}, "trajectory: 31 committed frames in a complete run, but the stored config's 0.6 s"),
}


@pytest.mark.parametrize("name", sorted(CONTRADICTIONS))
def test_a_store_contradicting_its_config_is_named(run_store, tmp_path, name):
    edits, words = CONTRADICTIONS[name]
    path = copy(run_store, tmp_path)
    _edit_config(path, **edits)
    with pytest.raises(StoreError, match=words.replace("(", r"\(").replace(")", r"\)")):
        open_run(path)
    code, _, err = main("analyse", path)
    assert code == 2 and err.startswith(f"taimill: error: {path}: ") and words in err, err


def test_a_killed_run_with_fewer_frames_than_its_config_reads(run_store, tmp_path):
    # a killed run never reaches its duration: fewer frames are not damage
    path = copy(run_store, tmp_path)
    _edit_config(path, duration=0.6)
    doc = json.loads((path / "zarr.json").read_text())
    doc["attributes"]["status"] = "running"
    del doc["attributes"]["summary"], doc["attributes"]["analysis_window"]
    (path / "zarr.json").write_text(json.dumps(doc))
    assert len(open_run(path).frames["time"]) == 31


def test_a_stale_journal_is_named_in_a_warning_and_not_read(run_store, tmp_path):
    path = copy(run_store, tmp_path)
    store = open_run(path)
    start = len(store.frames["time"])
    # rows beyond n_valid, as a writer's journal would hold them: left behind by a finished writer
    segment = {"trajectory/start": np.asarray(start, dtype=np.int64),
               **{f"trajectory/{k}": v[-2:] for k, v in store.frames.items()}}
    (path / "journal").mkdir()
    put_npz(zarr.open_group(path, mode="r").store, "journal/00000007.npz", segment)
    code, out, err = main("analyse", path)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 0 and len(lines) == 1, err
    assert lines[0].startswith(f"taimill: warning: {path}: journal/00000007.npz: stale journal"), lines[0]
    assert out == main("analyse", run_store)[1]
    assert len(open_run(path).frames["time"]) == start
