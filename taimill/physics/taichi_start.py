"""Taichi's start in a taimill process: `init_taichi` runs `ti.init` once, with the
compile settings every engine relies on (f64, no fast-math, the offline kernel cache
and its size, Taichi's CFG optimisation off), after clearing a stale cache lock and
two process-wide fixes (memoised source positions for Taichi's compile, glibc's mmap
threshold for freed memory)."""

from __future__ import annotations

import contextlib
import io
import os
import sys
import time

import taichi as ti

_initialised = False
OFFLINE_CACHE_BYTES = 1 << 30  #: Taichi's offline kernel cache may grow to this (init_taichi)
# Taichi's CFG optimisation off: LLVM's own passes (O3) do the same forwarding and
# dead-store removal, and Taichi's quadratic version took most of a first compile.
# Measured with `taimill run p4-cy-steel` and a fresh kernel cache on the 2-core AMD EPYC
# machine: first compile 19.4 → 4.3 s wall; the kernels run as fast (CY steel, 3 s,
# twice each: 6.9-7.7 → 7.6-7.9× real time) and give the same bits (the golden runs).
CFG_OPTIMIZATION = False


# Taichi's offline cache takes `ticache.lock` (an exclusive-create file) only while it
# reads or writes its index, milliseconds. A process killed meanwhile (kill -9, a
# machine under memory pressure) leaves it behind, and from then on every process
# prints "Lock …ticache.lock failed" warnings on stderr and runs uncached.
STALE_LOCK_SECONDS = 600.0


def cache_folder() -> str:
    """Taichi's offline kernel cache (TI_OFFLINE_CACHE_FILE_PATH, else ~/.cache/taichi/ticache)."""
    return os.environ.get("TI_OFFLINE_CACHE_FILE_PATH") or os.path.expanduser("~/.cache/taichi/ticache")


def clear_stale_cache_lock(cache_dir: str | os.PathLike | None = None, now: float | None = None) -> bool:
    """Remove the offline cache's lock file if it is older than STALE_LOCK_SECONDS;
    True if one was removed. `cache_dir`: Taichi's cache folder, which holds the lock
    (TI_OFFLINE_CACHE_FILE_PATH, else ~/.cache/taichi/ticache)."""
    cache_dir = cache_dir or cache_folder()
    lock = os.path.join(cache_dir, "ticache.lock")
    try:
        age = (time.time() if now is None else now) - os.stat(lock).st_mtime
        if age > STALE_LOCK_SECONDS:
            os.unlink(lock)
            return True
    except OSError:  # no lock, or another process removed it first
        pass
    return False


def _memoise_source_positions():
    """Taichi 1.7 formats a source excerpt for every AST node it transforms (its
    position in error messages and debug info, textwrap at 80 columns), also when the
    kernel then comes from the offline cache, and again for each call site of a
    ti.func: ≈ 40 % of the Python-side compile time of the engine's kernels. The text
    depends only on the node's place in its file: formatted once per place (the same
    strings, so the same kernels and cache keys)."""
    from taichi.lang.ast import ast_transformer_utils as utils

    ctx = getattr(utils, "ASTTransformerContext", None)
    get = getattr(ctx, "get_pos_info", None)
    if get is None or getattr(get, "memoised", False):
        return
    memo = {}

    def get_pos_info(self, node):
        kind = type(node).__name__  # these four show their lines up to their body's (get_pos_info)
        body = node.body[0].lineno if kind in ("For", "While", "FunctionDef", "If") else None
        key = (self.file, self.lineno_offset, self.func.func.__name__, self.indent, kind, node.lineno,
               node.end_lineno, node.col_offset, node.end_col_offset, body)
        text = memo.get(key)
        if text is None:
            text = memo[key] = get(self, node)
        return text

    get_pos_info.memoised, get_pos_info.original = True, get
    ctx.get_pos_info = get_pos_info


M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter


def return_freed_memory():
    """Fix glibc's mmap threshold at its initial 128 KiB. By default the first free of a
    large block raises it (up to 32 MB), and from then on the drains' NumPy blocks
    come from the heap and stay resident after they are freed: the peak RSS of a
    `taimill run` of 10⁵ balls was 35 MB higher. Results are unaffected."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None).mallopt(M_MMAP_THRESHOLD, 128 << 10)
        except (OSError, AttributeError):  # not glibc
            pass


def init_taichi(threads: int | None = None):
    """ti.init once per process (a second call invalidates fields). Serial loops and
    f64 make results bit-identical run to run (tests/test_runs.py); without fast-math the
    compiler may not contract or reassociate, so both launch modes agree to the bit."""
    global _initialised
    if _initialised:
        return
    if threads:  # through Taichi's own variable: a kwarg beside it would print a warning
        os.environ["TI_CPU_MAX_NUM_THREADS"] = str(int(threads))
    clear_stale_cache_lock()
    _memoise_source_positions()
    return_freed_memory()
    # Taichi's offline cache evicts a quarter of its kernels (least recently used) whenever
    # it exceeds its default 100 MB. taimill's engine shapes (ball counts, batches, contact
    # models, launch modes) fill ≈ 130 MB, so with the default every run of a new shape
    # evicted kernels another shape then compiled again (≈ 20 s CPU each then, ≈ 4 s since
    # CFG_OPTIMIZATION): the test suite took 13 min on a warm cache. 1 GiB keeps them all.
    kw = {"offline_cache_max_size_of_files": OFFLINE_CACHE_BYTES}
    # Taichi's control-flow-graph pass (store-to-load forwarding and dead-store removal
    # over a whole kernel, before LLVM) is most of a first compile: see CFG_OPTIMIZATION.
    kw["cfg_optimization"] = CFG_OPTIMIZATION
    # Taichi's own warnings are about its compile cache (a lock held by another taimill
    # starting at the same moment, or left by a killed one): the run is unaffected, only
    # its start-up is uncached, and they would break the one-line error contract on
    # stderr. Shown with TAIMILL_TI_LOG=warn (docs/outputs.md).
    level = os.environ.get("TAIMILL_TI_LOG", "error")
    # ti.init prints "[Taichi] Starting on arch=…" whatever the log level: kept off stdout
    # (JSON) and off a progress bar's line, shown on stderr only when asked for (info, debug)
    quiet = level.lower() in ("warn", "warning", "error", "critical")
    with contextlib.redirect_stdout(io.StringIO() if quiet else sys.stderr):
        ti.init(arch=ti.cpu, default_fp=ti.f64, default_ip=ti.i32, offline_cache=True, fast_math=False,
                log_level=level, **kw)
    _initialised = True
