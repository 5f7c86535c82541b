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

    def __init__(self, source: str, key: str, value, allowed: str):
        self.source, self.key, self.value, self.allowed = str(source), key, value, allowed
        super().__init__(one_line(f"{self.source}: {key} = {_shown(value)}: {allowed}"))


class SimulationUnstable(RuntimeError):
    """The integration produced a non-finite state or a ball left the jar."""
