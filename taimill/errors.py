"""User-facing errors: one line naming file, key, value and what is allowed."""

from __future__ import annotations


class ConfigError(ValueError):
    """A preset, jar, material or command-line value that cannot be simulated."""

    def __init__(self, source: str, key: str, value, allowed: str):
        self.source, self.key, self.value, self.allowed = str(source), key, value, allowed
        super().__init__(f"{self.source}: {key} = {value!r}: {allowed}")


class SimulationUnstable(RuntimeError):
    """The integration produced a non-finite state or a ball left the jar."""
