"""Where the power goes: the dissipation ledger by contact kind, class (impact or
persistent) and part of the law sums to the dissipated power, and the headline
stress-energy figures count stress events, so that a bed riding the wall is read as
persistent friction and the thesis' steel case keeps its figures."""

from pathlib import Path

import numpy as np
import pytest

from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.model.preset import load_preset
from taimill.runs.simulation import run
from taimill.schema import MECHANISM_CLASSES
from taimill.store.sinks import MemorySink

ROOT = Path(__file__).resolve().parent.parent
PRESETS = sorted(ROOT.glob("presets/*.toml"))
CY = ROOT / "presets" / "p4-cy-steel.toml"


def parts(summary: dict) -> float:
    return sum(p for kind in summary["dissipation_by_mechanism"].values() for cls in kind.values() for p in cls.values())


RATIOS = (0.0, -2.6, -3.4)
# CI: the CY jar with steel and with fluorite at every K (tests/test_runs.py checks
# every preset at its own K over 1.5 s); `pytest -m full`: every preset at every K.
CI_PRESETS = [p for p in PRESETS if p.stem in ("p4-cy-steel", "p4-cy-fluorite")]
CASES = ([pytest.param(p, k, id=f"{p.stem}-{k}") for p in CI_PRESETS for k in RATIOS]
         + [pytest.param(p, k, id=f"{p.stem}-{k}", marks=pytest.mark.full) for p in PRESETS if p not in CI_PRESETS
            for k in RATIOS])


@pytest.mark.parametrize("path, ratio", CASES)
def test_mechanisms_sum_to_the_dissipated_power(path, ratio):
    # 0.3 s each (window 0.05-0.3 s). Each contact's per-step dissipation is added to
    # the total and to exactly one mechanism (the mechanisms one step earlier, see
    # physics/events.book_mechanism), so the two differ by rounding and one step's
    # dissipation at the window's ends; 1 % is the stated bound.
    s = run(load_preset(path, {"ratio": ratio, "duration": 0.3}))
    assert s["dissipated_power"] > 0
    assert parts(s) == pytest.approx(s["dissipated_power"], rel=0.01)
    assert sum(s[f"dissipated_power_{c}"] for c in MECHANISM_CLASSES) == pytest.approx(s["dissipated_power"], rel=0.01)


def window_events(sink: MemorySink, summary: dict) -> dict:
    e = sink.event_table
    keep = e["t_start"] >= summary["analysis_window"][0]
    return {k: v[keep] for k, v in e.items()}


def test_a_bed_riding_the_wall_reads_as_persistent_friction():
    # CY, steel-fluorite, K = -3.0, 8 s (window 4-8 s): the charge rides the wall; its
    # closed contacts are grazing re-contacts at sub-mm/s onset speeds with large slip.
    # Whether the bed rides cleanly by 4 s is chaotic at this K: of seeds 1-3 one does
    # (98 % of the contacts grazing), the others keep some ball-ball collisions (5-24 %
    # grazing, persistent friction 59-99 % of the power); which one changes with the
    # last bits of the arithmetic (seed 1 did before the stored-1/m and ψ-recurrence
    # change, seed 2 does since; tests/test_ensemble.py).
    preset = load_preset(CY, {"ratio": -3.0, "pair": "steel-fluorite", "duration": 8.0, "seed": 2})
    sink = MemorySink()
    s = run(preset, sink)
    assert s["main_sink"]["mechanism"] == "friction in persistent contacts with the side"
    assert s["dissipated_power_persistent"] > 0.9 * s["dissipated_power"]
    e = window_events(sink, s)
    grazing = e["un"] < 1e-3
    assert grazing.sum() > 0.9 * len(e["un"])  # the all-contacts statistics are theirs
    assert s["events"] == int((e["un"] >= STRESS_MIN_UN).sum())  # the headline is not
    assert s["all_contacts"]["events"] == len(e["un"])
    if s["events"] == 0:
        assert s["impact_power"] == 0.0 and np.isnan(s["mean_se"])


def test_the_steel_case_keeps_its_figures():
    # CY steel at K = -2.6: its impacts are real, so counting stress events only moves
    # the headline by less than 5 % from the all-contacts figures of the same run.
    s = run(load_preset(CY, {"duration": 4.0}))
    a = s["all_contacts"]
    assert s["events"] > 0.95 * a["events"]
    for key in ("mean_se", "mean_se_normal", "impact_power", "normal_fraction"):
        assert s[key] == pytest.approx(a[key], rel=0.05), key
    assert s["dissipated_power_impact"] > 0.5 * s["dissipated_power"]
