"""Messages that explain a wait or a choice, and the catalog tables as JSON, all
through the real command line: `taimill presets/jars/mills/materials --json`, the
compile notice, the speed without compilation, the analysis window of a short run,
the LIGGGHTS import's own run time."""

from __future__ import annotations

import json

import pytest

from tests.inprocess import main


def table_and_json(*argv):
    code, text, err = main(*argv)
    assert code == 0, err
    code, out, err = main(*argv, "--json")
    assert code == 0, err
    return text, json.loads(out)


def test_presets_table_and_json_have_the_same_columns():
    text, rows = table_and_json("presets")
    head = text.splitlines()[0].split()
    assert head[:3] == ["preset", "mill", "jar"] and "duration" in head
    cy = next(r for r in rows if r["name"] == "p4-cy-steel")
    assert cy == {"name": "p4-cy-steel", "mill": "fritsch-p4", "jar": "CY", "balls": 12, "radius_mm": 6.0,
                  "pair": "steel-steel", "ratio_K": -2.6, "plate_rpm": 200.0, "duration_s": 24.0}
    line = next(x for x in text.splitlines() if x.startswith("p4-cy-steel "))
    assert line.split() == ["p4-cy-steel", "fritsch-p4", "CY", "12", "6", "steel-steel", "-2.6", "200", "24"]
    # aligned: every row's jar column starts where the heading's does
    col = text.splitlines()[0].index(" jar ") + 1
    assert all(r[col - 1] == " " and r[col] != " " for r in text.splitlines()[1:len(rows) + 1])


def test_mills_json_lists_every_mill_with_units_in_keys():
    text, rows = table_and_json("mills")
    assert [r["name"] for r in rows] == [x.split()[0] for x in text.splitlines()[1:len(rows) + 1]]
    p4 = next(r for r in rows if r["name"] == "fritsch-p4")
    assert p4["plate_radius_mm"] == 125.0 and "bowls_ml" in p4 and "estimates" in p4
    code, out, err = main("mills", "fritsch-p4", "--json")
    assert code == 0 and json.loads(out) == [p4]


@pytest.mark.parametrize("command", ["jars", "materials"])
def test_jars_and_materials_json(command):
    text, rows = table_and_json(command)
    assert rows and all("name" in r for r in rows)
    assert rows[0]["name"] in text
