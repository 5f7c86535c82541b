"""Chunk-level I/O of taimill's stores: whole chunks encoded and stored by the writer
itself (the bytes zarr would store, without zarr's cost per chunk), files written
atomically (chunks and journal segments), and rows read with a damaged chunk named.
Used by the run writer (taimill.store.writer), its reader (taimill.store.run) and
sweep stores (taimill.store.sweep)."""

from __future__ import annotations

import asyncio
import io
import os
import uuid
import zipfile
from contextlib import contextmanager
from pathlib import Path

import google_crc32c  # zarr's own dependency (its Crc32cCodec): the writer appends the same checksum
import numcodecs.blosc
import numpy as np
import zarr
from zarr.codecs import BloscCodec, BytesCodec, Crc32cCodec
from zarr.core.buffer import default_buffer_prototype
from zarr.core.sync import sync
from zarr.storage import LocalStore

from taimill.errors import StoreError
from taimill.store.layout import CODECS, TABLE_DESCRIPTIONS, Column, check_columns

class _TableWriter:
    """Appends row blocks to the arrays of one table group, committing through `n_valid`.

    Each array has a buffer of one chunk: rows are copied into it once, and a full
    buffer is encoded and stored as that chunk (`_ChunkWriter`), so at most one chunk of
    rows per array waits between calls. A block holding whole chunks from the start of
    one (a dense trajectory's launch) is encoded straight from the block. A flush
    stores the partial chunk too; its buffer stays, and the rows that follow complete
    the same chunk.

    The arrays are created as long as the rows expected (`expected_frames`), and grow
    ahead of their rows, to twice the rows (in whole chunks), whenever a chunk lands
    beyond their shape: a resize rewrites the array's metadata (≈ 1 ms
    each in zarr 3.1, for every array of the table), so a run does a few per array
    instead of one per chunk. Rows past `n_valid` are not data (readers slice to it);
    `flush` leaves each array exactly `n_valid` rows long."""

    def __init__(self, parent: zarr.Group, name: str, columns: dict[str, Column], chunk: int, rows: int = 0):
        """`rows`: the rows expected, in whole chunks: the arrays are created that long
        (no chunk is written), so a run that delivers them resizes only at `flush`."""
        self.name, self.columns, self.chunk = name, columns, chunk
        self.initial_rows = -(-rows // chunk) * chunk
        # every_chunk_stored: chunks equal to the fill value are written too, so a
        # missing chunk below n_valid is damage, not zeros (RunStore.check)
        self.group = parent.create_group(
            name, overwrite=True,
            attributes={"n_valid": 0, "description": TABLE_DESCRIPTIONS[name], "every_chunk_stored": True}
        )
        self.arrays = {k: self._create(k, c) for k, c in columns.items()}
        self.writer = _ChunkWriter.for_arrays(self.arrays)
        self.committed = 0  #: rows in the arrays and counted by n_valid
        self.written = 0  #: rows in the arrays
        self.start = 0  #: table row of the buffers' first row (a multiple of `chunk`)
        self.fill = 0  #: rows in the buffers
        self.buffers: dict[str, np.ndarray] | None = None

    @property
    def n_pending(self) -> int:
        return self.start + self.fill - self.committed

    def _create(self, name: str, c: Column) -> zarr.Array:
        return self.group.create_array(
            name,
            shape=(self.initial_rows, *c.row_shape),
            chunks=(self.chunk, *c.row_shape),
            dtype=c.dtype,
            fill_value=np.nan if c.dtype.startswith("f") else 0,
            dimension_names=c.dims,
            attributes={"units": c.units, "description": c.description},
            config={"write_empty_chunks": True},
            compressors=CODECS,
        )

    def add(self, block: dict) -> None:
        """Validate and buffer one block; write every chunk it completes."""
        rows = self._validated(block)
        n = len(next(iter(rows.values())))
        if self.buffers is None:
            self.buffers = {k: np.empty((self.chunk, *c.row_shape), dtype=c.dtype) for k, c in self.columns.items()}
        done = 0
        while done < n:
            if self.fill == 0 and n - done >= self.chunk:  # a whole chunk: stored from the block, not copied first
                self._store({k: np.ascontiguousarray(v[done:done + self.chunk], dtype=self.columns[k].dtype)
                             for k, v in rows.items()}, self.chunk)
                self.start += self.chunk
                done += self.chunk
                continue
            m = min(n - done, self.chunk - self.fill)
            for k, v in rows.items():
                np.copyto(self.buffers[k][self.fill:self.fill + m], v[done:done + m], casting="same_kind")
            self.fill += m
            done += m
            if self.fill == self.chunk:
                self._write_buffers()
        self._commit()

    def flush(self) -> None:
        """Write and commit every buffered row (a partial chunk stays buffered); the
        arrays are then exactly the committed rows long."""
        if self.n_pending:
            self._write_buffers()
        self._commit(exact=True)

    def tail(self, start: int) -> dict[str, np.ndarray]:
        """The buffered rows from row `start` (counted from the table's first row, at
        least `committed`) on: views of the buffers, valid until the next add."""
        if self.buffers is None:
            return {k: np.zeros((0, *c.row_shape), dtype=c.dtype) for k, c in self.columns.items()}
        return {k: b[start - self.start:self.fill] for k, b in self.buffers.items()}

    def _validated(self, block: dict) -> dict[str, np.ndarray]:
        """The block's columns as arrays, checked against the table (all before any row
        is buffered, so a bad block leaves the table as it was)."""
        check_columns(block, self.columns, self.name)
        rows = {}
        for k, c in self.columns.items():
            v = np.asarray(block[k])
            if not np.can_cast(v.dtype, c.dtype, casting="same_kind"):
                raise ValueError(f"{self.name} column {k!r}: Cannot cast array data from {v.dtype!r} to "
                                 f"{np.dtype(c.dtype)!r} according to the rule 'same_kind'")
            if v.ndim != 1 + len(c.row_shape) or v.shape[1:] != c.row_shape:
                expected = ("rows", *c.row_shape)
                raise ValueError(f"{self.name} column {k!r}: shape {v.shape}, expected {expected}")
            rows[k] = v
        if len({v.shape[0] for v in rows.values()}) > 1:
            lengths = {k: v.shape[0] for k, v in rows.items()}
            raise ValueError(f"{self.name} block: columns differ in length {lengths}")
        return rows

    def _write_buffers(self) -> None:
        """Store the buffers as chunk start // chunk of every array (a partial chunk
        padded with the fill value, as zarr pads it), the arrays grown to hold it.
        The rows are committed by `_commit`, after their data: a writer killed
        meanwhile leaves the last commit readable."""
        if self.fill < self.chunk:
            for k, b in self.buffers.items():
                b[self.fill:] = self.arrays[k].fill_value
        self._store(self.buffers, self.fill)
        if self.fill == self.chunk:
            self.start, self.fill = self.start + self.chunk, 0

    def _store(self, data: dict[str, np.ndarray], rows: int) -> None:
        """Store `data` (one chunk of rows per array, the first `rows` of them data) as
        chunk start // chunk, the arrays grown to hold it."""
        end = self.start + rows
        shape = self.arrays[next(iter(self.arrays))].shape[0]
        if end > shape:
            self._resize(max(end, -(-2 * end // self.chunk) * self.chunk))
        self.writer.write(self.arrays, data, self.start // self.chunk, rows)
        self.written = end

    def _commit(self, exact: bool = False) -> None:
        """Record the rows stored by `_write_buffers` as committed (n_valid); `exact`:
        shrink the arrays to them."""
        if exact and self.arrays[next(iter(self.arrays))].shape[0] != self.written:
            self._resize(self.written)
        if self.written != self.committed:
            self.committed = self.written
            self.group.attrs["n_valid"] = self.committed

    def _resize(self, rows: int) -> None:
        """Every array of the table to `rows` rows, their metadata written concurrently."""
        async def resize_all():
            await asyncio.gather(*(arr.async_array.resize((rows, *arr.shape[1:])) for arr in self.arrays.values()))

        sync(resize_all())


class _ChunkWriter:
    """Stores whole chunks of the table arrays. Arrays whose codecs are this module's
    (little-endian bytes, then `COMPRESSOR`, then optionally `CHECKSUM`) get their chunks encoded here, in one call
    to Blosc each, and stored under their keys (`put_all`): the bytes zarr itself
    stores for that chunk (tests/test_store.py), without zarr's per-chunk cost (≈ 2.5 ms
    of Python per chunk in zarr 3.1, and fresh copies of every chunk). Other arrays
    go through zarr."""

    def __init__(self, encoders):
        self.encoders = encoders  #: per array (its Blosc encoder, checksum?), or None: through zarr

    @classmethod
    def for_arrays(cls, arrays: dict[str, zarr.Array]) -> "_ChunkWriter":
        return cls({k: _blosc_encoder(arr) for k, arr in arrays.items()})

    def write(self, arrays: dict[str, zarr.Array], buffers: dict[str, np.ndarray], index: int, rows: int) -> None:
        """Chunk `index` of every array from its buffer, of which the first `rows` rows
        are data (the rest is the fill value, as zarr pads a partial last chunk)."""
        puts = []
        for k, arr in arrays.items():
            enc, data = self.encoders[k], buffers[k]
            if enc is None:
                lo = index * data.shape[0]
                if arr.shape[0] < lo + rows:
                    arr.resize((lo + rows, *arr.shape[1:]))
                arr[lo:lo + rows] = data[:rows]
                continue
            blosc, checksum = enc
            raw = data if data.dtype.byteorder != ">" else data.astype(data.dtype.newbyteorder("<"))
            chunk = _encode_serial(blosc, raw.reshape(-1).view(np.uint8))
            if checksum:  # what Crc32cCodec appends: the CRC-32C of the bytes before it, little-endian
                chunk += np.uint32(google_crc32c.value(chunk)).astype("<u4").tobytes()
            puts.append((arr.store, _chunk_key(arr, index), chunk))
        put_all(puts)


def _encode_serial(enc, data: np.ndarray) -> bytes:
    """enc.encode(data) by one thread, as zarr encodes (in its worker threads).
    numcodecs lets Blosc use its own threads when called from the main thread, and
    their blocks land in the output in the order they finish: the same data, other
    bytes from run to run (measured on a 17 MB chunk)."""
    saved = numcodecs.blosc.use_threads
    numcodecs.blosc.use_threads = False
    try:
        return enc.encode(data)
    finally:
        numcodecs.blosc.use_threads = saved


def _blosc_encoder(arr: zarr.Array):
    """(the numcodecs Blosc that zarr uses for the chunks of `arr`, whether a CRC-32C
    follows) if its codecs are the bytes codec (little-endian), one BloscCodec and
    optionally Crc32cCodec; else None."""
    try:
        codecs = list(arr.metadata.codecs)
        checksum = bool(codecs) and isinstance(codecs[-1], Crc32cCodec)
        if checksum:
            codecs.pop()
        ok = (len(codecs) == 2 and isinstance(codecs[0], BytesCodec) and isinstance(codecs[1], BloscCodec)
              and (codecs[0].endian is None or codecs[0].endian.value == "little"))
        return (codecs[1]._blosc_codec, checksum) if ok else None
    except Exception:  # another zarr's metadata: let zarr write
        return None


def _local_path(store, key: str) -> Path | None:
    """The file of `key` if `store` is a local directory store, else None."""
    root = getattr(store, "root", None)
    if not isinstance(store, LocalStore) or root is None:
        return None
    return Path(root) / key


@contextmanager
def _atomic_file(path: Path):
    """A new file that replaces `path` once written whole (as zarr's LocalStore does:
    a reader or a killed writer sees the old file or the new one). Its directory is
    made if missing (a new chunk row of a 3-D array): asking first would cost a
    system call per file."""
    tmp = path.with_name(f"{path.name}.{uuid.uuid4().hex}.partial")
    try:
        try:
            f = open(tmp, "wb")
        except FileNotFoundError:
            path.parent.mkdir(parents=True, exist_ok=True)
            f = open(tmp, "wb")
        with f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def put_all(items: list[tuple[object, str, bytes]]) -> None:
    """Store each (store, key, bytes). A local store's files are written here, each
    atomically: through zarr each costs ≈ 1 ms of event-loop and thread hand-over
    (measured with 16384-row chunks); others go through zarr, concurrently."""
    remote = []
    for store, key, data in items:
        path = _local_path(store, key)
        if path is None:
            remote.append(store.set(key, default_buffer_prototype().buffer.from_bytes(data)))
            continue
        with _atomic_file(path) as f:
            f.write(data)
    if remote:
        async def gather():
            await asyncio.gather(*remote)

        sync(gather())


def put_npz(store, key: str, arrays: dict[str, np.ndarray]) -> None:
    """Store `arrays` under `key` as a NumPy .npz (what np.savez writes, read by np.load),
    atomically. In a local store the file is written in place of a temporary one,
    each C-contiguous array straight from its memory: np.savez into memory would copy
    every array three times (a journal segment of a dense trajectory is ≈ 20 MB)."""
    path = _local_path(store, key)
    if path is None:
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        sync(store.set(key, default_buffer_prototype().buffer.from_bytes(buf.getvalue())))
        return
    with _atomic_file(path) as raw:
        with zipfile.ZipFile(raw, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, a in arrays.items():
                a = np.asarray(a)
                with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                    header = np.lib.format.header_data_from_array_1_0(a)
                    if a.flags.c_contiguous and not a.dtype.hasobject and len(repr(header)) < 60000:
                        np.lib.format.write_array_header_1_0(f, header)
                        f.write(a.reshape(-1).view(np.uint8))
                    else:
                        np.lib.format.write_array(f, a, allow_pickle=False)


def location(group: zarr.Group) -> str:
    """Where a group is, for messages: its store's directory and its path inside it."""
    root = getattr(group.store, "root", None)
    base = str(root) if root is not None else str(group.store)
    return str(Path(base) / group.path) if group.path else base


def why(err: BaseException) -> str:
    text = " ".join(f"{type(err).__name__}: {err}".split())
    return text if len(text) <= 160 else text[:157] + "..."


def _chunk_key(arr: zarr.Array, i: int) -> str:
    return f"{arr.path}/{arr.metadata.encode_chunk_key((i,) + (0,) * (arr.ndim - 1))}"


def read_rows(arr: zarr.Array, n: int, where: str, part: str) -> np.ndarray:
    """arr[:n]; a chunk that does not decode raises StoreError naming it."""
    try:
        return arr[:n]
    except Exception:
        size = arr.chunks[0]
        for i in range(-(-n // size)):
            try:
                arr[i * size:min(n, (i + 1) * size)]
            except Exception as err:
                # zarr's Crc32cCodec raises ValueError("Stored and computed checksum do not match ...")
                if "checksum" in str(err):
                    raise StoreError(where, part, f"chunk {i} fails its checksum (its bytes changed after "
                                                  "they were written)") from None
                raise StoreError(where, part, f"chunk {i} unreadable ({why(err)})") from None
        raise
