"""Writing an output (run store, sweep store, recording) safely.

- **One writer per output.** `OutputLock` holds an exclusive `flock` on `PATH.lock`
  beside the output for as long as it writes; a second writer is refused with a line
  naming the holder (pid, host, start time, command), read from the lock file. flock,
  not an O_EXCL lock file: the kernel drops the lock when its holder dies however it
  dies (kill -9 included), so a stale lock can never block anyone and no guess whether
  a recorded pid is still alive (or reused) is needed. The holder removes the file when
  it is done; one left behind by a killed writer is simply locked again by the next.
  On a file system without locks the output is written unlocked.
- **Nothing good destroyed before its successor is complete.** With --overwrite an
  existing output is not touched while the new one is built beside it
  (`partial_path`: RUN.partial-PID.zarr); at the end `swap_in` exchanges the two
  (atomically where Linux' renameat2 can, else rename aside, rename in) and deletes
  the old one. If the work fails (unstable, interrupted, an error), the old output
  stays as it was and the new partial one is kept beside it under that name; the
  message says so. The next writer of the same output that finishes deletes such
  leftovers of writers no longer running (`leftovers`), naming each on stderr.
- **A single file appears whole or not at all** (`whole_file`: figures, pair files):
  it is written under a temporary name beside its place (NAME.partial-PID.SUFFIX),
  flushed to disk and renamed over it; a failure deletes the temporary file, so a
  full disk leaves neither a truncated file nor one that blocks the retry.
- **A refused write is one line.** An OSError inside `Output` or `whole_file` (a full
  disk, permissions, an I/O error) becomes `StoreWriteError` (exit code 5) naming the
  output and saying what is left of it.
- **Only our own outputs are replaced.** An existing path is replaced (--overwrite) or
  resumed only if it is an output of the kind being written that taimill wrote
  (`ours`: a run store, a sweep store, a recording) and no input of the command
  (`taimill.model.files.check_replaceable`, the one check every writing command uses).
"""

from __future__ import annotations

import asyncio
import atexit
import contextlib
import ctypes
import errno
import fcntl
import json
import os
import re
import shlex
import shutil
import socket
import sys
import time
from pathlib import Path

from taimill.errors import ConfigError, Interrupted, StoreError, StoreWriteError
from taimill.model.files import check_replaceable

NO_LOCKS = {errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL}


def lock_path(path) -> Path:
    """The lock file of an output: PATH.lock beside it."""
    p = Path(path)
    return p.with_name(p.name + ".lock")


def partial_path(path, pid: int | None = None) -> Path:
    """Where a replacement of `path` is built: RUN.zarr -> RUN.partial-PID.zarr (the
    suffix stays last, so tools that go by it still open the file)."""
    p = Path(path)
    suffix = p.suffix
    stem = p.name[: -len(suffix)] if suffix else p.name
    return p.with_name(f"{stem}.partial-{os.getpid() if pid is None else pid}{suffix}")


def _command() -> str:
    argv = list(sys.argv) or ["python"]
    if Path(argv[0]).name in ("taimill", "__main__.py"):
        argv[0] = "taimill"
    elif argv[0] == "-c":
        argv[0:1] = ["python", "-c", "…"]
    return shlex.join(argv)


def _holder(fd: int) -> str:
    """Who holds a lock, from its file: "pid P on HOST since T (COMMAND)"."""
    try:
        info = json.loads(os.pread(fd, 65536, 0).decode() or "{}")
        return f"pid {info['pid']} on {info['host']} since {info['started']} ({info['command']})"
    except (OSError, ValueError, KeyError, TypeError):
        return "another process (it has not said who yet)"


class OutputLock:
    """Exclusive lock of one output path (module doc); a context manager."""

    def __init__(self, path):
        self.path = Path(path)
        self.file = lock_path(path)
        self.fd: int | None = None

    def acquire(self) -> "OutputLock":
        while True:
            try:
                self.file.parent.mkdir(parents=True, exist_ok=True)  # as zarr creates a store's parents
                fd = os.open(self.file, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as err:
                raise StoreWriteError(self.path, "lock", f"cannot create {self.file} ({err.strerror})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _holder(fd)
                os.close(fd)
                raise StoreError(self.path, "in use", f"{holder} is writing it; wait for it to finish or stop it") from None
            except OSError as err:
                if err.errno not in NO_LOCKS:
                    os.close(fd)
                    raise StoreWriteError(self.path, "lock", f"cannot lock {self.file} ({err.strerror})") from None
                break  # no locks on this file system: write unlocked
            # the file may have been removed by the holder we waited for: lock the file that is there
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.file))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        self.fd = fd
        info = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                "command": _command()}
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(info).encode(), 0)
        except OSError:
            pass  # a full disk: the lock holds without its description
        return self

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            if os.path.samestat(os.fstat(self.fd), os.stat(self.file)):
                os.unlink(self.file)  # while still holding it (see acquire)
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()


def remove(path) -> None:
    """Delete a file or directory tree, if there."""
    p = Path(path)
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p)
    elif os.path.lexists(p):
        p.unlink()


def _exchange(a: Path, b: Path) -> bool:
    """Atomically exchange two paths (Linux renameat2 RENAME_EXCHANGE); False where
    the system or the file system cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    return fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


def swap_in(build, target) -> None:
    """Put the finished `build` at `target` and delete what was there. Where the
    exchange is atomic `target` is never missing; else the old output is renamed aside
    (TARGET.old-PID) for the instant between two renames."""
    build, target = Path(build), Path(target)
    if not os.path.lexists(target):
        os.rename(build, target)
    elif _exchange(build, target):
        remove(build)  # now the old output
    else:
        aside = target.with_name(f"{target.name}.old-{os.getpid()}")
        os.rename(target, aside)
        os.rename(build, target)
        remove(aside)


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process
        return True
    return True


def leftovers(path) -> list[Path]:
    """What writers of `path` that did not finish left beside it, if they are no longer
    running: partial outputs (`partial_path`) and old outputs renamed aside by a swap
    cut short (`swap_in`: PATH.old-PID)."""
    p = Path(path)
    suffix = p.suffix
    stem = p.name[: -len(suffix)] if suffix else p.name
    name = re.compile(rf"{re.escape(stem)}\.partial-(\d+){re.escape(suffix)}|{re.escape(p.name)}\.old-(\d+)")
    try:
        beside = sorted(p.absolute().parent.iterdir())
    except OSError:
        return []
    return [q for q in beside if (m := name.fullmatch(q.name)) and not _running(int(m.group(1) or m.group(2)))]


def _fsync(path) -> None:
    """Flush a finished file to the disk (a power cut after the rename must not leave it empty)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def refused(err: OSError) -> str:
    """What an OSError says, without its errno number and path: "No space left on device"."""
    return err.strerror or str(err)


@contextlib.contextmanager
def whole_file(path, what: str = "file"):
    """The name to write one file under so that `path` appears only complete (module
    doc): the block writes the yielded NAME.partial-PID.SUFFIX (the suffix kept for
    tools that go by it, matplotlib among them); at its end the file is flushed and
    renamed over `path`. On any error the temporary file is deleted and `path` is as
    it was; an OSError becomes StoreWriteError naming `path` and `what`."""
    path = Path(path)
    part = partial_path(path)
    existed = os.path.lexists(path)
    try:
        yield part
        _fsync(part)
        os.replace(part, path)
    except BaseException as err:
        with contextlib.suppress(OSError):
            remove(part)
        if isinstance(err, OSError):
            left = f"{path} is unchanged" if existed else "nothing was written"
            raise StoreWriteError(path, what, f"write failed ({refused(err)}); {left}") from None
        raise


@contextlib.contextmanager
def all_or_none(paths, folder=None):
    """Files one command writes together (a report's figures, a pair file and its
    figure): if the block fails, those of `paths` that were not there before it are
    deleted, and `folder` too if the block created it and left it empty, so the same
    command can simply be run again. Files that were there before stay as they are."""
    paths = [Path(p) for p in paths if p is not None]
    new = [p for p in paths if not os.path.lexists(p)]
    new_folder = folder is not None and not os.path.lexists(folder)
    try:
        yield
    except BaseException:
        for p in new:
            with contextlib.suppress(OSError):
                remove(p)
        if new_folder:
            with contextlib.suppress(OSError):
                os.rmdir(folder)
        raise


def settle_writes(timeout: float = 10.0) -> None:
    """Wait (at most `timeout` s) until the writes zarr still has in flight have ended.
    zarr writes in its own IO thread while the caller waits; an interrupt ends the
    wait, not the writes, so a store deleted at once got files back from writes that
    were still running (an interrupted `import` left a folder that blocked its rerun).
    Nothing to wait for where zarr was never imported or has written nothing."""
    sync = sys.modules.get("zarr.core.sync")
    loop = getattr(sync, "loop", [None])[0]
    if loop is None or loop.is_closed() or not loop.is_running():
        return

    async def rest():
        others = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        if others:
            await asyncio.wait(others, timeout=timeout)

    with contextlib.suppress(Exception):  # a loop stopped meanwhile: nothing is running on it
        asyncio.run_coroutine_threadsafe(rest(), loop).result(timeout + 1)


ZARR_EXIT_SECONDS = 5.0  #: how long the exit waits for zarr's IO thread to stop
_zarr_exit = {"registered": False}


def join_zarr_at_exit() -> None:
    """At exit, stop zarr's IO thread and wait for it (ZARR_EXIT_SECONDS) before zarr's
    own clean-up does: that one waits 0.2 s, and on a busy machine then prints "Cannot
    close a running event loop" with a traceback under the command's one line.
    Registered once zarr is imported, after zarr's own (atexit runs the last first)."""
    sync = sys.modules.get("zarr.core.sync")
    if sync is None or _zarr_exit["registered"]:
        return

    def stop():
        loop, thread = getattr(sync, "loop", [None])[0], getattr(sync, "iothread", [None])[0]
        if loop is None or thread is None or loop.is_closed():
            return
        with contextlib.suppress(RuntimeError):
            loop.call_soon_threadsafe(loop.stop)
        thread.join(ZARR_EXIT_SECONDS)

    atexit.register(stop)
    _zarr_exit["registered"] = True


class Output:
    """One output path written by this process (module doc):

        with Output("RUN.zarr", overwrite=True, what="run", kind="run store", ours=is_run_store) as out:
            ...write into out.build...
            out.commit()

    `out.build` is the path itself for a new output (or one reused: `reuse=True`, a
    sweep resumed in place), RUN.partial-PID.zarr when it replaces an existing one.
    `whole=True` builds a new output beside its path too, so that the path appears only
    complete (a recording). Leaving the block without commit() (an error, an interrupt)
    keeps an existing output unchanged; what was built (the partial one beside it, or
    a new output) stays if `keep(build)` says it holds anything worth keeping (default:
    it exists), else it is deleted: a failure then leaves nothing that blocks the
    retry. An OSError inside the block becomes StoreWriteError naming the output. An interrupt
    leaves as an `Interrupted` whose message says where things are. An existing path
    is replaced or reused only if `ours(path)` says it is an output of this kind and it
    is none of `inputs` (the files the command reads): check_replaceable, whose refusal
    calls it a `kind` (default: `what`)."""

    def __init__(self, path, *, ours, overwrite: bool = False, reuse: bool = False, option: str = "--out",
                 what: str = "output", kind: str | None = None, keep=None, inputs=(), whole: bool = False):
        self.path = Path(path)
        self.overwrite, self.reuse, self.option, self.what = overwrite, reuse, option, what
        self.ours, self.kind, self.inputs = ours, kind or what, tuple(inputs)
        self.keep = keep or os.path.lexists
        self.lock = OutputLock(path)
        self.whole = whole
        self.build = self.path
        self.replacing = self.existed = self.committed = False

    def __enter__(self) -> "Output":
        join_zarr_at_exit()  # a store's writer has imported zarr by now
        if self.overwrite or self.reuse:  # before the lock: a refusal leaves no trace beside a user's file
            check_replaceable(self.path, self.option, self.kind, self.ours, inputs=self.inputs)
        self.lock.acquire()
        try:
            exists = os.path.lexists(self.path)
            if exists and not (self.overwrite or self.reuse):
                raise ConfigError("command line", self.option, str(self.path), "exists; pass --overwrite to replace it")
            self.existed, self.replacing = exists, exists and self.overwrite
            if self.replacing or (self.whole and not exists):
                self.build = partial_path(self.path)
                remove(self.build)
        except BaseException:
            self.lock.release()
            raise
        return self

    def commit(self) -> None:
        """The work is complete: the new output takes the path, and leftovers of earlier
        writers of it that did not finish are deleted (module doc)."""
        if self.build != self.path:
            try:
                swap_in(self.build, self.path)
            except OSError as err:
                raise StoreWriteError(self.path, "replace", f"could not put {self.build} in its place ({err}); "
                                      f"{self.path} is unchanged or beside it as {self.path.name}.old-{os.getpid()}") from None
        self.committed = True
        for q in leftovers(self.path):
            if self.ours(q):  # a user's file that happens to match the name stays
                try:
                    remove(q)
                except OSError:
                    continue
                print(f"taimill: removed {q}, left by an earlier writer of {self.path} that did not finish",
                      file=sys.stderr)

    def kept(self) -> str:
        """Where the output of unfinished work is, for the one-line message."""
        if self.build == self.path:
            return f"the {self.what} so far is in {self.path}" if os.path.lexists(self.path) else f"nothing was written to {self.path}"
        old = f"{self.path} is unchanged" if self.existed else f"nothing was written to {self.path}"
        if os.path.lexists(self.build):
            return f"{old}; the partial {self.what} is in {self.build}"
        return old

    def __exit__(self, exc_type, err, tb):
        try:
            if err is None or self.committed:
                return
            settle_writes()  # writes an interrupt cut short end first: a store deleted under them got files back
            mine = self.build != self.path or not self.existed  # never an output resumed in place
            removed = mine and os.path.lexists(self.build) and not self.keep(self.build)
            if removed:
                with contextlib.suppress(OSError):
                    remove(self.build)
            if isinstance(err, KeyboardInterrupt):
                raise Interrupted(f"{str(err) or 'interrupted'}; {self.kept()}", getattr(err, "exit_code", 130)) from err
            if isinstance(err, OSError):
                raise StoreWriteError(self.path, self.kind, f"write failed ({refused(err)}); {self.kept()}") from err
            if isinstance(err, StoreWriteError) and (self.build != self.path or removed):
                source = self.path if err.source == str(self.build) else err.source  # the name the user gave
                why = err.allowed.split("; ")[0] if removed else err.allowed  # not "what was committed is readable"
                raise StoreWriteError(source, err.key, f"{why}; {self.kept()}") from err
        finally:
            self.lock.release()


class Outputs(contextlib.ExitStack):
    """Several `Output`s of one command entered together (a run's store and recording):
    `add` enters one and returns where to write it, `commit` swaps every one in,
    `kept` says where the outputs of unfinished work are."""

    def __init__(self):
        super().__init__()
        self.items: list[Output] = []

    def add(self, path, **kw) -> Path:
        out = self.enter_context(Output(path, **kw))
        self.items.append(out)
        return out.build

    def commit(self) -> None:
        for out in self.items:
            out.commit()

    def kept(self) -> str:
        return "; ".join(out.kept() for out in self.items)
