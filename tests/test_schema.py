"""The stream's schema is declared once (taimill/schema.py): the kernel's event and
ledger records are written by column name, every schema column is written exactly
once, and the store and in-memory sinks carry exactly the schema's columns. Read
from the sources: no Taichi is started."""

import re
from pathlib import Path

import numpy as np

from taimill.schema import DERIVED_EVENT_COLUMNS, ENERGY_COLUMNS, EVENT_COLUMNS, FRAME_COLUMNS, MECHANISM_COLUMNS
from taimill.store.layout import layout
from taimill.store.sinks import MemorySink

PHYSICS = Path(__file__).resolve().parent.parent / "taimill" / "physics"


def written(path: Path, record: str) -> list[str]:
    return re.findall(rf'row\[S\.{record}\["(\w+)"\]\] =', path.read_text())


def test_kernel_writes_every_event_column_once_by_name():
    names = written(PHYSICS / "events.py", "EV")
    assert sorted(names) == sorted(k for k in EVENT_COLUMNS if k not in DERIVED_EVENT_COLUMNS)


def test_kernel_writes_every_ledger_column_once_by_name():
    # the named columns, then the mechanism block in the schema's order
    src = (PHYSICS / "snapshot.py").read_text()
    names = written(PHYSICS / "snapshot.py", "LEDGER")
    assert "row[S.LEDGER[S.MECHANISM_COLUMNS[c]]] = sums[5 + c]" in src
    assert sorted(names + list(MECHANISM_COLUMNS)) == sorted(k for k in ENERGY_COLUMNS if k != "time")


def test_derived_columns_are_the_stress_energies():
    cols = {"m_eff": np.array([2.0]), "un": np.array([3.0]), "ut": np.array([4.0])}
    assert DERIVED_EVENT_COLUMNS["se_n"](cols)[0] == 9.0  # ½ m u̇n²
    assert DERIVED_EVENT_COLUMNS["se_t"](cols)[0] == 16.0


def test_store_layout_and_memory_sink_follow_the_schema():
    lay = layout(4)
    assert list(lay["trajectory"]) == list(FRAME_COLUMNS)
    assert list(lay["events"]) == list(EVENT_COLUMNS)
    assert list(lay["energy"]) == list(ENERGY_COLUMNS)
    for table, columns in (("events", EVENT_COLUMNS), ("energy", ENERGY_COLUMNS)):
        assert {k: (c.dtype, c.units) for k, c in lay[table].items()} == {k: v[:2] for k, v in columns.items()}
    assert set(MemorySink().event_table) == set(EVENT_COLUMNS)
