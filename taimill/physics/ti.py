"""The one door to Taichi. Every module of taimill reaches Taichi through `ti` here,
never by importing it: this module picks the implementation, and owns everything a
process sets for it (the environment variables, the offline kernel cache's folder and
lock, the `ti.init` settings).

Implementations (both give the same kernels and, checked by the golden runs, the same
bits): upstream `taichi` 1.7 (wheels for CPython up to 3.13; its last release) and the
maintained fork `taichi-forge` (import name `taichi_forge`, wheels up to 3.14), which
states taichi 1.7.4 as its API. pyproject.toml installs taichi on Python ≤ 3.13 and
taichi-forge on 3.14. TAIMILL_TAICHI=taichi or =taichi-forge picks one where both are
installed; unset, the first of IMPLEMENTATIONS that imports is used."""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import importlib.metadata
import io
import os
import sys
import time

from taimill.errors import ConfigError

ENV = "TAIMILL_TAICHI"  #: environment variable choosing the implementation


@dataclasses.dataclass(frozen=True)
class Implementation:
    """One Taichi that taimill runs on."""

    name: str  #: its distribution on PyPI, as users type it in ENV
    module: str  #: its import name
    python: str  #: the CPython versions it has wheels for
    stale_lock: str | None  #: the offline cache's lock file a killed process leaves behind; None: none can be left
    init_options: tuple = ()  #: (keyword, value) pairs of its own that init_taichi passes to ti.init


# taichi 1.7 takes `ticache.lock` by creating it exclusively, only while it reads or writes
# its index (milliseconds), and deletes it after. A process killed meanwhile (kill -9, a
# machine under memory pressure) leaves it behind, and from then on every process prints
# "Lock …ticache.lock failed" warnings on stderr and runs uncached. taichi-forge holds
# `ticache_<arch>_s<n>.lock` with flock(2): the file stays, the operating system drops a
# dead holder's lock, and deleting the file would break the lock of a live one.
# taichi-forge compiles at its "fast" tier by default (its own IR passes and
# advanced_optimization off, for edit-run latency): taimill's kernels then ran 9.4× slower
# (CY steel, 3 s simulated: 3.63 s wall against 0.385 s on taichi 1.7.4; 2-core AMD EPYC).
# Its "full" tier ran them in 0.38-0.42 s, with every summary key equal to taichi 1.7.4's
# and a first compile shorter than 1.7.4's (3.7 against 4.7 s wall for the command).
# Its warning on kernels unrolled beyond 1024 statements (the contact models' static loops
# are, by design) is a SyntaxWarning on stderr, which belongs to taimill's one-line errors.
IMPLEMENTATIONS = (Implementation("taichi", "taichi", "3.9-3.13", "ticache.lock"),
                   Implementation("taichi-forge", "taichi_forge", "3.10-3.14", None,
                                  (("compile_tier", "full"), ("unrolling_kernel_warning_limit", 0))))
ALIASES = {"taichi_forge": "taichi-forge", "forge": "taichi-forge"}

# Taichi prints a banner on import and on ti.init; stdout belongs to `--json`. Both
# implementations read this variable when they are imported.
os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "false")


def choose(choice: str | None) -> list[Implementation]:
    """The implementations to try, in order, for ENV's value `choice` (None or empty: all;
    a name or alias: that one). A ConfigError names the variable, the value and the names."""
    if not (choice or "").strip():
        return list(IMPLEMENTATIONS)
    choice = ALIASES.get(choice.strip().lower(), choice.strip().lower())
    found = [i for i in IMPLEMENTATIONS if i.name == choice]
    if not found:
        raise ConfigError("environment", ENV, choice,
                          f"one of {', '.join(i.name for i in IMPLEMENTATIONS)} (unset: the first installed)")
    return found


def _import(choice: str | None):
    """(the Taichi module, its Implementation) for ENV's value `choice`."""
    tried = choose(choice)
    for impl in tried:
        try:
            return importlib.import_module(impl.module), impl
        except ImportError:
            pass
    wanted = " or ".join(f"{i.name} (Python {i.python})" for i in tried)
    how = (f"pip install {tried[0].name}, or unset {ENV}" if choice else
           "`pip install -e .` in the repository installs the one for this Python")
    raise ConfigError("environment", ENV, choice or None, f"{wanted} is not installed in this environment "
                      f"({sys.executable}, Python {sys.version.split()[0]}): {how}")


ti, IMPLEMENTATION = _import(os.environ.get(ENV))


def version() -> str:
    """The installed version of the implementation in use (its distribution's)."""
    return importlib.metadata.version(IMPLEMENTATION.name)


def describe() -> str:
    """'taichi 1.7.4' or 'taichi-forge 0.7.0': for bench logs and version lines."""
    return f"{IMPLEMENTATION.name} {version()}"


def internal(path: str):
    """A submodule of the implementation in use, by its path below the package
    ('lang.kernel_impl'): for the few places that patch or inspect Taichi's internals."""
    return importlib.import_module(f"{ti.__name__}.{path}")


_initialised = False
OFFLINE_CACHE_BYTES = 1 << 30  #: Taichi's offline kernel cache may grow to this (init_taichi)
# Taichi's CFG optimisation off: LLVM's own passes (O3) do the same forwarding and
# dead-store removal, and Taichi's quadratic version took most of a first compile.
# Measured with `taimill run p4-cy-steel` and a fresh kernel cache on the 2-core AMD EPYC
# machine: first compile 19.4 → 4.3 s wall; the kernels run as fast (CY steel, 3 s,
# twice each: 6.9-7.7 → 7.6-7.9× real time) and give the same bits (the golden runs).
CFG_OPTIMIZATION = False


# a lock file older than this (s) was left by a killed process (Implementation.stale_lock)
STALE_LOCK_SECONDS = 600.0


def cache_folder() -> str:
    """Taichi's offline kernel cache (TI_OFFLINE_CACHE_FILE_PATH, else ~/.cache/taichi/ticache)."""
    return os.environ.get("TI_OFFLINE_CACHE_FILE_PATH") or os.path.expanduser("~/.cache/taichi/ticache")


def clear_stale_cache_lock(cache_dir: str | os.PathLike | None = None, now: float | None = None) -> bool:
    """Remove the offline cache's lock file if the implementation in use can leave one
    behind (Implementation.stale_lock) and it is older than STALE_LOCK_SECONDS; True if
    one was removed. `cache_dir`: Taichi's cache folder, which holds the lock (cache_folder)."""
    if IMPLEMENTATION.stale_lock is None:
        return False
    lock = os.path.join(cache_dir or cache_folder(), IMPLEMENTATION.stale_lock)
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
    utils = internal("lang.ast.ast_transformer_utils")

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


# Taichi's CUDA backend keeps every field in one buffer it reserves at ti.init: 1 GB by
# default (device_memory_GB), or device_memory_fraction of the device's whole memory
# when that is set (taichi 1.7's LlvmRuntimeExecutor::materialize_runtime; a field that
# does not fit stops the kernel with "Out of CUDA pre-allocated memory"). A large mill's
# fields take about 1.6 kB a ball (docs/performance.md, memory): 1.6 GB at 10⁶ balls,
# which 1 GB does not hold, and 16 GB at 10⁷. A fraction scales with the device where a
# fixed size cannot: 0.8 of an 80 GB device (64 GB) holds 10⁷ balls four times over and
# 0.8 of a 4 GB one still holds 10⁶ balls, while the fifth left over keeps room for
# the CUDA context, the copies of the frames and events a drain reads back, and a
# display. A sweep's or a study's worker processes share one device: each takes its
# share of the fraction (init_taichi's `share`).
DEVICE_MEMORY_FRACTION = 0.8


def init_taichi(threads: int | None = None, share: int = 1):
    """ti.init once per process (a second call invalidates fields), on the backend the
    process was asked for (physics.backend: TAIMILL_BACKEND, the command line's
    --backend). Serial loops and f64 make results bit-identical run to run
    (tests/test_runs.py); without fast-math the compiler may not contract or
    reassociate, so both launch modes agree to the bit. `share`: processes that run on
    one CUDA device at once (a sweep's workers), each reserving DEVICE_MEMORY_FRACTION
    / share of its memory. Asked for cuda where Taichi finds no device, a ConfigError
    (Taichi itself would only warn and run on the CPU)."""
    global _initialised
    if _initialised:
        return
    from taimill.physics import backend

    arch = backend.arch()  # a ConfigError for cuda without a device, before Taichi starts
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
    kw.update(IMPLEMENTATION.init_options)
    # Taichi's own warnings are about its compile cache (a lock held by another taimill
    # starting at the same moment, or left by a killed one): the run is unaffected, only
    # its start-up is uncached, and they would break the one-line error contract on
    # stderr. Shown with TAIMILL_TI_LOG=warn (docs/outputs.md).
    level = os.environ.get("TAIMILL_TI_LOG", "error")
    # ti.init prints "[Taichi] Starting on arch=…" whatever the log level: kept off stdout
    # (JSON) and off a progress bar's line, shown on stderr only when asked for (info, debug)
    quiet = level.lower() in ("warn", "warning", "error", "critical")
    if arch == "cuda":
        kw["device_memory_fraction"] = DEVICE_MEMORY_FRACTION / max(1, int(share))
    os.environ.pop("TI_ARCH", None)  # Taichi's own choice of arch would override the backend's
    asked, source, key = backend.requested()

    def start(arch):
        with contextlib.redirect_stdout(io.StringIO() if quiet else sys.stderr):
            ti.init(arch=getattr(ti, arch), default_fp=ti.f64, default_ip=ti.i32, offline_cache=True,
                    fast_math=False, log_level=level, **kw)

    try:
        start(arch)
    except Exception as err:  # the device's memory taken by other processes, a driver too old (not seen yet)
        if arch != "cuda":
            raise
        if asked != "auto":
            raise ConfigError(source, key, asked, f"Taichi could not start on {backend.cuda_devices()[0]} ({err}); "
                              "use --backend cpu") from None
        start("cpu")  # auto: the CPU, without a word
    if asked == "cuda" and internal("lang.impl").current_cfg().arch != ti.cuda:  # a Taichi built without CUDA
        raise ConfigError(source, key, asked, f"{describe()} did not start on the CUDA device "
                          f"{backend.cuda_devices()[0]} (built without CUDA?); use --backend cpu")
    _initialised = True


def where() -> tuple[str, int]:
    """("cpu" or "cuda", CPU threads) this process's kernels run on, or will once Taichi
    starts (the backend asked for; TI_CPU_MAX_NUM_THREADS, else every core)."""
    if _initialised:
        c = compute()
        return c["backend"], c["threads"]
    from taimill.physics import backend

    return backend.arch(), int(os.environ.get("TI_CPU_MAX_NUM_THREADS") or 0) or os.cpu_count() or 1


def compute() -> dict:
    """What runs this process's kernels, once Taichi has started (init_taichi):
    {"backend": "cpu" or "cuda", "device": the processor's or the GPU's name,
    "threads": the CPU threads Taichi may use}. Recorded with every run (the summary's
    `compute`); it describes the machine, not the run, so equal runs on other machines
    or thread counts differ in it alone."""
    from taimill.physics import backend

    cfg = internal("lang.impl").current_cfg()
    on_cuda = cfg.arch == ti.cuda
    device = (backend.cuda_devices() or ("CUDA device",))[0] if on_cuda else backend.cpu_model()
    return {"backend": "cuda" if on_cuda else "cpu", "device": device, "threads": int(cfg.cpu_max_num_threads)}
