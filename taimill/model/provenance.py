"""Where a data file's numbers come from. A mill or bowl file gives every number either
a source (a document and the page, table or section) in `[sources]` or the reason it
is only an estimate in `[estimates]` (docs/mills.md):

    plate_radius_mm = 70.5
    [estimates]
    plate_radius_mm = "141 mm effective sun-wheel diameter, the figure commonly quoted ..."

A number in neither table, in both, or a note for a key the file does not set is an
error naming the file and the key: an unsourced figure must never pass as a sourced one."""

from __future__ import annotations

from dataclasses import dataclass

from taimill.errors import ConfigError
from taimill.model.tables import Table

TABLES = ("sources", "estimates")


@dataclass(frozen=True)
class Origin:
    """The origin of one number of a data file."""

    key: str  #: the number's key in the file
    text: str  #: the source (document, page/table), or why it is an estimate and whence
    estimate: bool  #: True: not verified against a source


def read_origins(t: Table, numbers) -> tuple[Origin, ...]:
    """The origin of each of `numbers` (the keys of t that hold numbers and are set), in
    that order, from t's `[sources]` and `[estimates]` tables; both tables are marked used."""
    notes = {}
    for name in TABLES:
        sub = t.table(name, required=False)
        if sub is None:
            continue
        for key in sub.data:
            text = sub.get(key, kind=str)
            if key not in numbers:
                raise ConfigError(t.source, sub.key(key), text, f"names no number of the file; allowed: {', '.join(numbers)}")
            if key in notes:
                raise ConfigError(t.source, sub.key(key), text, "is in both [sources] and [estimates]; give one")
            if not text.strip():
                raise ConfigError(t.source, sub.key(key), text, "must say where the number comes from, not be empty")
            notes[key] = Origin(key, text.strip(), name == "estimates")
        sub.done()
    missing = [k for k in numbers if k not in notes]
    if missing:
        raise ConfigError(t.source, missing[0], t.data.get(missing[0]),
                          "has no origin: give its source in [sources] or mark it in [estimates] (never an unsourced figure)")
    return tuple(notes[k] for k in numbers)
