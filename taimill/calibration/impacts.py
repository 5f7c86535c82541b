"""Validation tables from single impacts: the two-sphere impacts of thesis Fig 2.8
against eqs 2.3/2.4, and the ±50 % parameter sensitivity of the drop test (Fig 2.5,
bottom right). The runs are `taimill.calibration.runs`'s, imported when needed."""

from __future__ import annotations

import dataclasses
import math

from taimill.model.contact_sets import NormalLaw, pair_contact


def eqs_2_3_2_4(v1n: float, v2n: float, m1: float, m2: float, e: float):
    """Final normal velocities of a frictionless impact of bodies 1 and 2 (thesis eqs
    2.3, 2.4), from their initial normal velocities (m/s), masses (kg) and e."""
    v1f = v1n - (1 + e) * (m2 * v1n - m2 * v2n) / (m1 + m2)
    v2f = v2n + (1 + e) * (m1 * v1n - m1 * v2n) / (m1 + m2)
    return v1f, v2f


def _final_normal(un: float, m: float, e: float) -> float:
    """Final relative normal velocity (approach positive) of equal spheres meeting at
    normal approach speed un: eqs 2.3/2.4 in the frame of the second sphere."""
    v1f, v2f = eqs_2_3_2_4(un, 0.0, m, m, e)
    return v1f - v2f


def _error(sim: float, expected: float, scale: float) -> float:
    """(sim - expected) relative to |expected|, or to `scale` where expected is 0."""
    return (sim - expected) / (abs(expected) if expected else scale)


def oblique(pair: str, offsets, speed: float, *, law: str | None = None, friction: bool = False) -> dict:
    """Thesis Fig 2.8: two spheres at `speed` (m/s) with centre offsets Δ (m), without
    friction unless asked. Each row compares the final relative velocity on the apse
    line (see physics.calibration.two_sphere_impacts) with

    - expected: normal -e(u̇_n)·u̇_n with e(u̇_n) of a head-on run at that same normal
      speed (eqs 2.3/2.4 with that e), tangential unchanged (eq 2.1);
    - thesis: eqs 2.3/2.4 with the pair's constant nominal e (0.516 for steel).

    For a constant-e law (hertz-mindlin) both coincide. Errors are relative to the
    expected value, or to `speed` where that is 0 (grazing Δ = 2r, head-on u̇_t)."""
    from taimill.calibration.runs import FRICTIONLESS, two_sphere_impacts

    fr = None if friction else FRICTIONLESS
    runs = two_sphere_impacts(pair, [(o, speed) for o in offsets], law=law, friction=fr)
    head_on = two_sphere_impacts(pair, [(0.0, r["un"]) for r in runs if r["contacts"]], law=law, friction=fr)
    e_head = iter([-h["un_final"] / h["un"] for h in head_on])
    rows = []
    for r in runs:
        m, un, ut = r["mass"], r["un"], r["ut"]
        e = next(e_head) if r["contacts"] else math.nan
        expected = _final_normal(un, m, e) if r["contacts"] else 0.0
        thesis = _final_normal(un, m, r["e_nominal"]) if r["contacts"] else 0.0
        rows.append({
            "offset_mm": r["offset"] * 1e3, "angle_deg": math.degrees(math.asin(min(1.0, r["offset"] / (2 * r["radius"])))),
            "un": un, "ut": ut, "e_head_on": e, "contacts": r["contacts"],
            "un_final": r["un_final"], "un_final_expected": expected, "un_error": _error(r["un_final"], expected, speed),
            "un_final_thesis": thesis, "thesis_error": _error(thesis, r["un_final"], speed),
            "ut_final": r["ut_final"], "ut_error": _error(r["ut_final"], ut, speed),
            "turn_deg": math.degrees(r["turn"]),
        })
    return {"pair": pair, "law": runs[0]["law"], "speed": speed, "e_nominal": runs[0]["e_nominal"],
            "friction": friction, "rows": rows}


def vary(law: NormalLaw, name: str, factor: float) -> NormalLaw:
    """`law` with one parameter scaled. n keeps k's value in N/mm^n, as when the thesis
    varied the exponent in MSC.Adams' mm units: k_SI = k_mm·1000^n."""
    if name == "n":
        n = law.n * factor
        return dataclasses.replace(law, n=n, k=law.k * 1000.0 ** (n - law.n))
    return dataclasses.replace(law, **{name: getattr(law, name) * factor})


def sensitivity(pair: str, h0: float, *, law: str | None = None, target: str = "plate", change: float = 0.5,
                radius: float | None = None) -> dict:
    """Thesis Fig 2.5 (bottom right): the drop test from h0 (m) with each parameter of
    the normal law (k, n, c and d where its force depends on d) scaled by 1 ± change in turn.
    Rows: parameter, factor, value (SI), e, rebound height h* (m), its change from the
    reference h* (m and relative), and the thesis' Δh = (h* - h0)/h0."""
    from taimill.calibration.runs import Drop, run_drops

    ball, jar, bb, bw, fr = pair_contact(pair, radius, law)
    base = bw if target == "plate" else bb
    variants = [("reference", 1.0, base)] + [
        (name, f, vary(base, name, f)) for name in base.model.parameters for f in (1 - change, 1 + change)]
    drops = [Drop(ball, jar, bb if target == "plate" else v, v if target == "plate" else bw, fr, h0, target)
             for _, _, v in variants]
    results = run_drops(drops)
    h_ref = results[0]["rebound_height"]
    rows = [{
        "parameter": name, "factor": f, "value": getattr(v, name) if name != "reference" else None,
        "e": r["e"], "rebound_height": r["rebound_height"], "change": r["rebound_height"] - h_ref,
        "relative_change": (r["rebound_height"] - h_ref) / h_ref, "thesis_dh": (r["rebound_height"] - h0) / h0,
    } for (name, f, v), r in zip(variants, results)]
    return {"pair": pair, "law": base.law, "target": target, "h0": h0, "change": change, "rows": rows}
