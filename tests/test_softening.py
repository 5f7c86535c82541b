"""Softened contacts (`softening = F`, --softening; docs/softening.md): the stiffness
divided by F with the damping chosen anew keeps each law's restitution at every impact
speed, lengthens the time step, and a run says it was softened."""

from __future__ import annotations

import numpy as np
import pytest

from inprocess import main
from taimill.model import laws
from taimill.model.contact_sets import soften
from taimill.model.preset import load_preset

SPEEDS = np.array([0.05, 0.2, 0.5, 1.0, 2.0, 4.0])  # m/s, the range of a planetary mill's impacts


@pytest.mark.parametrize("law", [None, "hertz-mindlin", "hunt-crossley", "kelvin-voigt"])
@pytest.mark.parametrize("factor", [3.0, 100.0])
def test_a_softened_law_rebounds_as_the_stiff_one_at_every_speed(law, factor):
    """Tolerance 2·10⁻³ in e: the damping is bisected to 1/16⁵ of its bracket and the
    impacts are integrated with 2000 RK4 steps; adams-impact (the thesis' law, whose e
    falls from 1 to 0.45 over these speeds) is the stiff law on stretched scales."""
    p = load_preset("p4-cy-steel", {"law": law} if law else {})
    for stiff in (p.ball_ball, p.ball_wall):
        soft = soften(stiff, factor)
        assert soft.k == pytest.approx(stiff.k / factor) and soft.kt == pytest.approx(stiff.kt / factor)
        e0 = laws.simulate_impact(stiff.model, stiff.k, np.full(len(SPEEDS), stiff.c), stiff.d, stiff.m_eff, SPEEDS)["e"]
        e1 = laws.simulate_impact(soft.model, soft.k, np.full(len(SPEEDS), soft.c), soft.d, soft.m_eff, SPEEDS)["e"]
        assert np.allclose(e1, e0, atol=2e-3), (e0, e1)


def test_softening_one_is_the_law_itself():
    p = load_preset("p4-cy-steel")
    assert soften(p.ball_ball, 1.0) is p.ball_ball


def test_a_softened_run_says_so_and_steps_longer(tmp_path):
    stiff = load_preset("p4-cy-steel")
    soft = load_preset("p4-cy-steel", {"softening": 10.0})
    assert soft.dt > 1.8 * stiff.dt  # a Hertz contact lasts 10^0.4 = 2.5× longer
    assert any("softened" in w for w in soft.warnings) and not any("softened" in w for w in stiff.warnings)
    out = tmp_path / "s.zarr"
    code, _, err = main("run", "p4-cy-steel", "--softening", 10, "--duration", 1.5, "--analysis-start", 0.5,
                        "--out", out, "--json")
    assert code == 0 and "taimill: warning: contacts softened: stiffness ÷ 10" in err
    from taimill.store.run import open_run

    run = open_run(out)
    assert run.summary["softening"] == 10.0 and run.config["softening"] == 10.0
    assert "softening" not in open_run_summary_of_stiff(tmp_path)


def open_run_summary_of_stiff(tmp_path):
    code, out, err = main("run", "p4-cy-steel", "--duration", 1.5, "--analysis-start", 0.5, "--json")
    assert code == 0, err
    import json

    return json.loads(out)


@pytest.mark.parametrize("value", [0.5, 0, -1, 1e5])
def test_softening_out_of_range_is_one_line(value):
    code, _, err = main("run", "p4-cy-steel", "--softening", value, "--duration", 1.0)
    assert code == 2 and "softening" in err and "allowed range [1, 10000]" in err, err
