"""Energy spectra accumulated in the kernel at each event's close (taimill.model.spectra,
physics/events.py): the same to the bit as the spectra binned from the stored event
rows, in both launch modes; their integrals are the run's event counts and energies;
stored with the run, read back by taimill and by xarray; and on a bed sliding on the
wall they show what the kinematic stress energy hides (docs/outcome.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from inprocess import main
from taimill.analysis import spectra as A
from taimill.model.preset import load_preset
from taimill.model.spec import from_preset
from taimill.model.spectra import EDGES, MEASURES, SCALE, Spectra, bin_index, event_energies, from_rows, to_fixed
from taimill.physics.runner import Runner
from taimill.store.run import open_run
from taimill.store.sinks import MemorySink


def simulate(preset: str, mode: str | None = None, **overrides):
    p = load_preset(preset, overrides)
    spec = from_preset(p)
    sink = MemorySink()
    sink.start({}, spec.n, spec.radius)
    Runner([spec], mode=mode).run([sink])
    return spec, sink


@pytest.fixture(scope="module")
def cy_steel():
    return simulate("p4-cy-steel", duration=2.0, analysis_start=0.5, ratio=-2.6)


def test_kernel_spectra_are_the_rows_binned_to_the_bit(cy_steel):
    """(Both launch modes give the same spectra: the 10⁴-ball test below; the parallel
    mode's launch per phase makes 12 balls over 2 s cost minutes.)"""
    spec, sink = cy_steel
    got = sink.last_spectra
    rows = sink.event_table
    assert got.start == spec.spectra_from == 0.5 and got.count.sum() > 1000
    assert got == from_rows(rows, got.start, got.end, got.stress_un)


def test_the_integrals_are_the_events_and_their_energies(cy_steel):
    spec, sink = cy_steel
    sp, rows = sink.last_spectra, sink.event_table
    window = rows["t_start"] >= sp.start
    stress = window & (rows["un"] >= spec.stress_min_un)
    energies = event_energies(rows)
    for q, m in enumerate(MEASURES):
        assert sp.count[:, :, q].sum() == window.sum()  # every event in the window, once per measure
        assert sp.count[:, 0, q].sum() == stress.sum()
        for kind in (0, 1):
            sel = stress & (rows["kind"] == kind)
            total = energies[m][sel].sum()
            # fixed point: each event off by at most 2⁻²⁵ of its bin's lower edge
            assert sp.energy()[kind, 0, q].sum() == pytest.approx(total, rel=1e-7, abs=1e-18)
    assert spec.stress_min_un == sp.stress_un
    assert A.mean(sp, "se_normal") == pytest.approx(energies["se_normal"][stress].mean(), rel=1e-7)


def test_binning_is_numpy_searchsorted_and_the_fixed_point_is_exact_at_edges():
    e = np.array([0.0, EDGES[0] * 0.999, EDGES[0], EDGES[5], EDGES[5] * 1.0001, EDGES[-1], 1e9])
    assert list(bin_index(e)) == [0, 0, 1, 6, 6, len(EDGES), len(EDGES)]
    assert to_fixed(np.array([EDGES[5]]), np.array([6]))[0] == 1 << 24
    assert SCALE[0] == SCALE[1]  # the underflow bin counts in units of the first edge


def test_rate_and_quantile_of_a_known_spectrum():
    """Energies spread evenly in log E over four decades: the rate above a threshold
    and the quantiles are known to the sampling error (1e5 events: ≤ 1 %)."""
    rng = np.random.default_rng(3)
    n = 100_000
    e = 10 ** rng.uniform(-6, -2, n)
    rows = {"t_start": np.ones(n), "kind": np.zeros(n), "un": np.ones(n), "ut": np.zeros(n), "m_eff": 2 * e,
            "dissipated_normal": e, "dissipated_friction": e}
    sp = from_rows(rows, 0.0, 2.0, 0.01)
    assert A.rate_above(sp, 1e-4, "se_normal") == pytest.approx((e >= 1e-4).sum() / 2, rel=0.01)
    assert A.rate_above(sp, 3e-5, "dissipated_normal") == pytest.approx((e >= 3e-5).sum() / 2, rel=0.01)
    assert A.quantile(sp, 0.5, "se_normal") == pytest.approx(1e-4, rel=0.02)
    assert A.quantile(sp, 0.9, "se_normal") == pytest.approx(10 ** -2.4, rel=0.02)
    assert A.rate_above(sp, 1e-4, "se_normal", stress_only=False) == A.rate_above(sp, 1e-4, "se_normal")
    assert A.rate_above(sp, 1e-4, "se_normal", kind="ball_wall") == 0.0
    assert math.isnan(A.quantile(Spectra(0, 1, 0.01), 0.5, "se_normal"))


def test_a_run_stores_its_spectra_readable_by_xarray(tmp_path):
    xr = pytest.importorskip("xarray")
    out = tmp_path / "r.zarr"
    code, _, err = main("run", "p4-cy-steel", "--duration", 1.5, "--analysis-start", 0.5, "--out", out)
    assert code == 0, err
    run = open_run(out)
    sp = run.spectra
    assert sp == from_rows(run.events, sp.start, sp.end, sp.stress_un) and sp.count.sum() > 0
    ds = xr.open_zarr(out, group="spectra", consolidated=False)
    assert ds["count"].dims == ("kind", "class", "measure", "bin")
    sel = ds["energy"].sel(kind="ball_wall", measure="se_normal").sum()
    assert float(sel) == pytest.approx(sp.energy()[1, :, 2].sum(), rel=1e-12)
    assert run.summary["spectra"]["se_normal"]["events"] == int(sp.count[:, 0, 2].sum())
    for group in ("events", "energy", "trajectory"):  # the other groups open the same way
        assert len(xr.open_zarr(out, group=group, consolidated=False).data_vars) > 0


def test_a_bed_sliding_on_the_wall_dissipates_a_hundredth_of_its_kinematic_impact_power():
    """CY, steel–fluorite, K = −3, 8 s (window 4–8 s): the thesis' kinematic stress
    energy counts grazing re-contacts at full slip speed, 14.6 W of "impact power",
    while those events dissipate 0.15 W. The cataracting steel charge at K = −2.6
    dissipates a large part of its kinematic power in its impacts. Bounds: the measured
    ratios are 95 (fluorite) and < 10 (steel); 50 and 10 keep them apart with margin."""
    _, bed = simulate("p4-cy-fluorite", ratio=-3.0, duration=8.0, analysis_start=4.0)
    _, cat = simulate("p4-cy-steel", ratio=-2.6, duration=8.0, analysis_start=4.0)

    def ratio(sp):
        kinematic = A.power_above(sp, 0.0, "se_normal") + A.power_above(sp, 0.0, "se_tangential")
        dissipated = A.power_above(sp, 0.0, "dissipated_normal") + A.power_above(sp, 0.0, "dissipated_friction")
        return kinematic, kinematic / dissipated

    kin_bed, r_bed = ratio(bed.last_spectra)
    kin_cat, r_cat = ratio(cat.last_spectra)
    assert kin_bed == pytest.approx(14.6, rel=0.05)
    assert r_bed > 50 and r_cat < 10, (r_bed, r_cat)


def test_statistics_mode_of_a_large_mill_stores_the_spectra_the_rows_would_give():
    """10⁴ balls of 1 mm on a simple-cubic lattice, each pair overlapping by 1 µm: every
    neighbour opens a contact at the first step and closes it as the lattice springs
    apart. The kernel's spectra equal those binned from the rows, in both launch modes
    (the parallel mode adds from both threads at once)."""
    p = load_preset("p4-cy-steel", {"balls.count": 10_000, "balls.diameter_mm": 1.0, "duration": 1.0,
                                    "analysis_start": 0.0})
    assert p.events_output == "rows"  # 10⁴ balls: still rows by default (rules.EVENT_ROWS_UP_TO)
    d = 2 * p.balls.radius * (1 - 1e-3)
    grid = np.stack(np.meshgrid(*(np.arange(22),) * 3, indexing="ij"), -1).reshape(-1, 3)[:10_000]
    x = (grid - [10.5, 10.5, 0]) * d + [0, 0, p.balls.radius]
    spec = from_preset(p).replace(position=x, steps=400)
    results = []
    for mode in ("fused", "parallel"):
        sink = MemorySink()
        sink.start({}, spec.n, spec.radius)
        Runner([spec], mode=mode).run([sink])
        sp = sink.last_spectra
        assert sp.count.sum() > 10_000 and sp == from_rows(sink.event_table, sp.start, sp.end, sp.stress_un)
        results.append(sp)
    assert results[0] == results[1]


def test_outputs_events_chooses_rows_or_spectra_and_a_spectra_store_is_small(tmp_path):
    preset = tmp_path / "cy.toml"
    text = Path(load_preset("p4-cy-steel").source).read_text()
    preset.write_text(text.replace("[outputs]", '[outputs]\nevents = "spectra"'))
    rows, spectra = tmp_path / "rows.zarr", tmp_path / "spectra.zarr"
    for source, out in (("p4-cy-steel", rows), (preset, spectra)):
        code, _, err = main("run", source, "--duration", 1.5, "--analysis-start", 0.5, "--out", out)
        assert code == 0, err
    a, b = open_run(rows), open_run(spectra)
    assert b.config["events_output"] == "spectra" and len(b.events["t_start"]) == 0 < len(a.events["t_start"])
    assert a.spectra == b.spectra
    keep = lambda s: {k: v for k, v in s.items() if k not in ("wall_seconds", "realtime_factor")}  # noqa: E731
    assert keep(a.summary) == keep(b.summary)  # the summary sees every event in both modes
    code, out, err = main("analyse", spectra, "--json")  # the event statistics from the spectra, the same numbers
    assert code == 0, err
    import json

    got = json.loads(out)["event_estimator"]
    assert got["events"] == a.summary["events"] and got["mean_se"] == pytest.approx(a.summary["mean_se"], rel=1e-7)
    code, out, err = main("report", spectra, "--out", tmp_path / "report")
    assert code == 0 and (tmp_path / "report" / "energy_spectra.png").stat().st_size > 10_000, err
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("[outputs]", '[outputs]\nevents = "some"'))
    code, _, err = main("run", bad, "--duration", 1.0)
    assert code == 2 and "outputs.events" in err and "rows, spectra" in err


def test_a_run_with_powder_reports_its_dose_per_gram_and_the_shear_view():
    import json

    code, out, err = main("run", "p4-cy-steel", "--duration", 1.5, "--analysis-start", 0.5, "--powder-mass", 5, "--json")
    assert code == 0, err
    s = json.loads(out)
    assert s["powder_mass_g"] == 5.0
    assert s["specific_power_W_per_g"] == pytest.approx(s["dissipated_power"] / 5.0)
    assert s["specific_power_impact_W_per_g"] == pytest.approx(s["dissipated_power_impact"] / 5.0)
    rate = s["spectra"]["dissipated_normal"]["rate_above"]["0.001"]
    assert rate > 0 and s["rate_above_per_g"]["dissipated_normal"]["0.001"] == pytest.approx(rate / 5.0)
    assert 0 <= s["shear_share"] <= 1 and s["units"]["shear_power_persistent_wall_W_per_m2"] == "W/m²"
    code, out, _ = main("run", "p4-cy-steel", "--duration", 1.5, "--analysis-start", 0.5, "--json")
    assert "specific_power_W_per_g" not in json.loads(out)  # no powder, no dose
