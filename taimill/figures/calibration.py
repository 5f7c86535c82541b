"""Figures of the calibration experiments (PNG or SVG by the file's suffix): drop
tests e(h₀), the fit against the data (thesis Fig 2.5 top right), the ±50 %
sensitivity (Fig 2.5 bottom right), and the two-sphere impacts (Fig 2.8). Matplotlib
is imported inside each function with the headless Agg backend."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from taimill.figures.layout import legend_outside
from taimill.store.output import whole_file


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path) -> Path:
    path = Path(path)
    fig.tight_layout()
    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, dpi=150, bbox_inches="tight")  # the legends outside the axes too
    finally:
        _pyplot().close(fig)
    return path


def drop_figure(results: list[dict], path) -> Path:
    """Restitution and rebound height against drop height, one marker per drop."""
    plt = _pyplot()
    h0 = np.array([r["h0"] for r in results]) * 1e3
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
    a.plot(h0, [r["e"] for r in results], "o-")
    a.set(xlabel="drop height h₀ (mm)", ylabel="restitution e = √(h*/h₀) (-)", title=f"{results[0]['pair']} on the {results[0]['target']}")
    b.plot(h0, np.array([r["rebound_height"] for r in results]) * 1e3, "o-")
    b.set(xlabel="drop height h₀ (mm)", ylabel="rebound height h* (mm)", title=results[0]["law"])
    return _save(fig, path)


def fit_figure(fit: dict, path) -> Path:
    """Measured e(h₀) with ±2σ bars against the fitted simulation, and the residuals."""
    plt = _pyplot()
    rows = fit["rows"]
    h0 = np.array([r["h0_mm"] for r in rows])
    fig, (a, b) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, gridspec_kw={"height_ratios": (2, 1)})  # legend beside
    a.errorbar(h0, [r["e_measured"] for r in rows], yerr=[2 * r["sigma_e"] for r in rows], fmt="o", capsize=3,
               label="measured ±2σ")
    a.plot(h0, [r["e_fit"] for r in rows], "s-", label=f"{fit['law']}, {fit['param']} = {fit['value']:.4g} ± {fit['uncertainty']:.2g} {fit['unit']}")
    a.set(ylabel="restitution e (-)", title=f"{fit['pair']}: fit of {fit['param']} to {Path(fit['data']).name}")
    legend_outside(a, fontsize=8)
    b.axhline(0.0, color="grey", lw=0.8)
    b.bar(h0, [r["residual_mm"] for r in rows], width=0.4 * np.min(np.diff(h0)) if len(h0) > 1 else 10.0)
    b.set(xlabel="drop height h₀ (mm)", ylabel="h*_sim − h*_meas (mm)")
    return _save(fig, path)


def sensitivity_figure(sens: dict, path) -> Path:
    """Relative change of the rebound height for each parameter at 1 ± change."""
    plt = _pyplot()
    rows = [r for r in sens["rows"] if r["parameter"] != "reference"]
    names = list(dict.fromkeys(r["parameter"] for r in rows))
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(6, 3.8))
    for shift, factor in ((-0.2, 1 - sens["change"]), (0.2, 1 + sens["change"])):
        ch = [100 * next(r["relative_change"] for r in rows if r["parameter"] == n and r["factor"] == factor) for n in names]
        ax.bar(x + shift, ch, width=0.4, label=f"× {factor:g}")
    ax.axhline(0.0, color="grey", lw=0.8)
    ax.set_xticks(x, names)
    ax.set(xlabel="parameter of the normal law", ylabel="change of rebound height h* (%)",
           title=f"{sens['pair']} ({sens['law']}), h₀ = {sens['h0'] * 1e3:g} mm")
    legend_outside(ax)
    return _save(fig, path)


def oblique_figure(obl: dict, path) -> Path:
    """Final relative velocities, normal and tangential, against the offset Δ: simulated,
    expected (head-on e at the same normal speed) and the thesis' constant-e formula."""
    plt = _pyplot()
    rows = obl["rows"]
    d = [r["offset_mm"] for r in rows]
    mm = lambda key: [1e3 * r[key] for r in rows]  # noqa: E731 (m/s → mm/s)
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.plot(d, mm("un_final"), "o", label="simulated")
    a.plot(d, mm("un_final_expected"), "-", label="−e(u̇ₙ)·u̇ₙ, head-on e")
    a.plot(d, mm("un_final_thesis"), "--", label=f"eqs 2.3/2.4, e = {obl['e_nominal']:g}")
    a.set(xlabel="offset Δ (mm)", ylabel="final normal relative velocity (mm/s)", title=f"{obl['pair']} ({obl['law']})")
    legend_outside(a, below=True, gap=0.45, fontsize=8)
    b.plot(d, mm("ut_final"), "o", label="simulated")
    b.plot(d, mm("ut"), "-", label="initial (eq 2.1: unchanged)")
    b.set(xlabel="offset Δ (mm)", ylabel="final tangential relative velocity (mm/s)",
          title=f"{obl['speed'] * 1e3:g} mm/s, {'with' if obl['friction'] else 'no'} friction")
    legend_outside(b, below=True, gap=0.45, fontsize=8)
    return _save(fig, path)
