"""User-facing errors: one line naming file, key, value and what is allowed."""

from __future__ import annotations

import re

MAX_VALUE_CHARS = 120  #: a longer value (a whole file's bytes in a key) is shortened


def one_line(text: str) -> str:
    """text with every line break and run of white space folded into one space."""
    return re.sub(r"\s*[\r\n]+\s*", " ", text).strip()


def _shown(value) -> str:
    shown = repr(value)
    return shown if len(shown) <= MAX_VALUE_CHARS else shown[: MAX_VALUE_CHARS - 1] + "…"


class ConfigError(ValueError):
    """A preset, jar, material or command-line value that cannot be simulated."""

    exit_code = 2  #: of the command line

    def __init__(self, source: str, key: str, value, allowed: str):
        self.source, self.key, self.value, self.allowed = str(source), key, value, allowed
        super().__init__(one_line(f"{self.source}: {key} = {_shown(value)}: {allowed}"))


class StoreError(ConfigError):
    """A store or output file that cannot be used: damaged, not a store, or in use by
    another writer. The message names the store, the part (`events/un`, `attrs.status`,
    `lock`) and what is wrong with it."""

    def __init__(self, store, part: str, why: str):
        self.source, self.key, self.value, self.allowed = str(store), part, None, why
        ValueError.__init__(self, f"{self.source}: {part}: {why}")


class StoreWriteError(StoreError):
    """The operating system refused a write (disk full, permissions, I/O error); what
    was committed before stays readable."""

    exit_code = 5


class WorkerDied(RuntimeError):
    """A worker process of a sweep died while it ran points (killed: out of memory,
    SIGKILL). The message names the points that were running; the points finished
    before are stored and the same command resumes the sweep."""

    exit_code = 6  #: of the command line


class SimulationUnstable(RuntimeError):
    """The integration produced a non-finite state or a ball left the jar."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM stopped the work early: handled like KeyboardInterrupt (rows
    flushed, status "interrupted"); the message says what was kept."""

    def __init__(self, message: str = "interrupted", exit_code: int = 130):
        super().__init__(message)
        self.exit_code = exit_code
