"""A TOML table being read, for every file the model loads (presets, jars, materials,
pair files): keys are checked against the known ones, values against their type and
allowed range, and every error names the file (or the command line), the key path, the
value and what is allowed."""

from __future__ import annotations

import difflib
import math
from pathlib import Path

from taimill.errors import ConfigError
from taimill.model import files


class Table:
    """A TOML table being read: remembers the file and key path for error messages,
    and reports keys it does not know (typos must not pass silently, nor be reported
    as a missing key: `known` is checked first, with the nearest known key suggested)."""

    def __init__(self, data: dict, source: str, prefix: str = "", overridden=frozenset(), known=None):
        if not isinstance(data, dict):
            raise ConfigError(source, prefix.rstrip(".") or "file", data, "must be a table")
        self.data, self.source, self.prefix, self.used = data, source, prefix, set()
        self.overridden = overridden
        if known is not None:
            self.expect(known)

    def expect(self, known):
        """Refuse any key not in `known`."""
        extra = [k for k in self.data if k not in known]
        if extra:
            raise self.unknown(extra[0], known)

    def unknown(self, k, known) -> ConfigError:
        close = difflib.get_close_matches(str(k), sorted(known), n=1, cutoff=0.6)
        hint = f" (did you mean '{close[0]}'?)" if close else f"; allowed: {', '.join(sorted(known))}"
        return ConfigError(self.where(k), self.key(k), self.data[k], f"unknown key '{k}'{hint}")

    def key(self, k):
        return f"{self.prefix}{k}"

    def where(self, k):
        """The file, or the command line if the value was given there."""
        return "command line" if self.key(k) in self.overridden else self.source

    def has(self, k):
        return k in self.data

    def get(self, k, default=..., *, kind=float, lo=None, hi=None, lo_open=False, allowed=None):
        self.used.add(k)
        if k not in self.data:
            if default is ...:
                raise ConfigError(self.source, self.key(k), None, "missing (required key)")
            return default
        v = self.data[k]
        src = self.where(k)
        if allowed is not None:
            if v not in allowed:
                raise ConfigError(src, self.key(k), v, f"must be one of {', '.join(map(str, allowed))}")
            return v
        if kind is str:
            if not isinstance(v, str):
                raise ConfigError(src, self.key(k), v, "must be a string")
            return v
        if kind is int and (isinstance(v, bool) or not isinstance(v, int)):
            raise ConfigError(src, self.key(k), v, "must be an integer")
        if kind is float and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ConfigError(src, self.key(k), v, "must be a number")
        if kind is float and isinstance(v, int) and abs(v) > 1e300:
            raise ConfigError(src, self.key(k), v, "must be finite")
        if isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(src, self.key(k), v, "must be finite")
        bad_lo = lo is not None and (v <= lo if lo_open else v < lo)
        if bad_lo or (hi is not None and v > hi):
            lo_s = "-inf" if lo is None else f"{lo:g}"
            hi_s = "inf" if hi is None else f"{hi:g}"
            raise ConfigError(src, self.key(k), v, f"allowed range {'(' if lo_open else '['}{lo_s}, {hi_s}]")
        return kind(v)

    def table(self, k, required=True, known=None):
        self.used.add(k)
        v = self.data.get(k)
        if v is None and not required:
            return None
        if v is None:
            raise ConfigError(self.source, self.key(k), v, "missing (required table)")
        if not isinstance(v, dict):
            raise ConfigError(self.where(k), self.key(k), v, "must be a table")
        return Table(v, self.source, f"{self.prefix}{k}.", self.overridden, known)

    def sources(self, numbers, required=True) -> dict:
        """{key: source text} from the `source` sub-table: one non-empty text for each of
        `numbers` this table gives, no other keys. A text starting with "estimate" marks
        a number no source was found for (`is_estimate`)."""
        st = self.table("source", required=required, known=[k for k in numbers if k in self.data])
        if st is None:
            return {}
        out = {}
        for k in numbers:
            if k in self.data:
                text = st.get(k, kind=str)
                if not text.strip():
                    raise ConfigError(st.source, st.key(k), text, "the number's source, or 'estimate: …' saying where it comes from")
                out[k] = text.strip()
        st.done()
        return out

    def done(self):
        extra = sorted(set(self.data) - self.used, key=str)
        if extra:
            raise self.unknown(extra[0], self.used)


def is_estimate(source_text: str) -> bool:
    """Whether a number's source text (Table.sources) marks it as an estimate."""
    return source_text.lower().startswith("estimate")


def read_toml(path: Path, what: str, source=None) -> dict:
    """A TOML file; `source` (default: the file) is who named it, for read errors."""
    return files.read_toml(path, path if source is None else source, what)
