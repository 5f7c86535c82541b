"""Where the kernels run: the backend, chosen once per process before Taichi starts.

    cpu  — the CPU's cores (the default: what every result so far was computed on)
    cuda — the first CUDA device the driver shows (CUDA_VISIBLE_DEVICES chooses it)
    auto — cuda where a CUDA device is found, else cpu, without a word

The choice comes from the command line (`--backend` on run, sweep, design and tui),
else from the environment variable TAIMILL_BACKEND, else the default. The command
line's choice is written into the variable, so that the processes a sweep or a
design study spawns run where their parent was told to. `physics.ti.init_taichi`
asks `arch()` which Taichi arch to start; `physics.ti.compute()` then says what runs
(the summary's `compute`).

The kernels are the same on every backend and each ball sums its own contacts in
list order, so results agree across backends to the rounding of the device's
arithmetic (a GPU contracts multiply-adds) and across thread counts to the bit."""

from __future__ import annotations

import functools
import os

from taimill.errors import ConfigError

ENV = "TAIMILL_BACKEND"  #: environment variable choosing the backend
OPTION = "--backend"  #: the command line's option
DEFAULT = "cpu"
NAMES = ("cpu", "cuda", "auto")
ALLOWED = "one of cpu (the default), cuda (the first CUDA device), auto (cuda where a CUDA device is found, else cpu)"
NO_DEVICE = "no CUDA device was found (no NVIDIA driver, or none visible: CUDA_VISIBLE_DEVICES); use --backend cpu or auto"

_told = None  # (source, key) of a choice the command line made in this process (select)


def choose(value, source: str = "environment", key: str = ENV) -> str:
    """The backend named by `value` (None or blank: the default); a ConfigError naming
    `source`, `key`, the value and the names otherwise."""
    if value is None or not str(value).strip():
        return DEFAULT
    name = str(value).strip().lower()
    if name not in NAMES:
        raise ConfigError(source, key, value, ALLOWED)
    return name


def requested() -> tuple[str, str, str]:
    """(backend, source, key) this process was asked for: the command line's (select),
    else TAIMILL_BACKEND's, else the default."""
    source, key = _told or ("environment", ENV)
    return choose(os.environ.get(ENV), source, key), source, key


def select(option: str | None) -> str:
    """The command line's choice: `option` (--backend; None: not given, then the
    environment's), checked now, before anything runs or is written (a name that is
    none, cuda without a device), and written into TAIMILL_BACKEND for the processes
    this one spawns."""
    global _told
    if option is None:
        name, source, key = requested()
    elif not option.strip():  # given, but blank: no choice at all (a blank variable is unset)
        raise ConfigError("command line", OPTION, option, ALLOWED)
    else:
        name, source, key = choose(option, "command line", OPTION), "command line", OPTION
    if name == "cuda" and not cuda_devices():
        raise ConfigError(source, key, name, NO_DEVICE)
    if option is not None:
        os.environ[ENV] = name
        _told = (source, key)
    return name


def arch() -> str:
    """"cpu" or "cuda": what Taichi is to start on for the requested backend (auto
    resolved). A ConfigError for cuda without a device."""
    name, source, key = requested()
    if name == "cuda" and not cuda_devices():
        raise ConfigError(source, key, name, NO_DEVICE)
    if name == "auto":
        return "cuda" if cuda_devices() else "cpu"
    return name


@functools.lru_cache(maxsize=1)
def cuda_devices() -> tuple[str, ...]:
    """The names of the CUDA devices the driver shows this process, in its order (Taichi
    runs on the first); () without a driver or a device. Asked of the driver (libcuda)
    itself, not of Taichi: nothing starts Taichi, and a test can ask before it decides
    whether to run (Taichi only warns and falls back to the CPU where it finds none)."""
    import ctypes

    for name in ("libcuda.so.1", "libcuda.so", "nvcuda.dll"):
        try:
            cuda = ctypes.CDLL(name)
            break
        except OSError:
            continue
    else:
        return ()
    count = ctypes.c_int(0)
    try:
        if cuda.cuInit(0) != 0 or cuda.cuDeviceGetCount(ctypes.byref(count)) != 0:
            return ()
        names = []
        for i in range(count.value):
            device, text = ctypes.c_int(0), ctypes.create_string_buffer(256)
            ok = cuda.cuDeviceGet(ctypes.byref(device), i) == 0 and cuda.cuDeviceGetName(text, 256, device) == 0
            names.append(text.value.decode(errors="replace") if ok else f"CUDA device {i}")
        return tuple(names)
    except (AttributeError, OSError):  # a library of that name without the driver API
        return ()


@functools.lru_cache(maxsize=1)
def cpu_model() -> str:
    """The processor's model name (/proc/cpuinfo on Linux; platform.processor() elsewhere)."""
    import platform

    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"
