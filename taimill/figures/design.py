"""The report page of a jar design study (`taimill design`, docs/designer.md), from the
study's plain results (taimill.design.report.results) and the profiles' outlines:
the profiles side by side, the objective history with the references' bands, and the
Pareto front (several objectives) or the objective against K (one)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from taimill.schema import SUMMARY_UNITS


def _unit(key: str) -> str:
    return SUMMARY_UNITS.get(key.rpartition(".")[2], "")


def _fmt(fig) -> str:
    return f"{fig[0]:.4g} ± {fig[1]:.2g}" if fig[1] is not None else f"{fig[0]:.4g} ± ?"


def _s(fig) -> float:
    """The spread for a band or error bar: none drawn where it is unknown (one replica)."""
    return fig[1] if fig[1] is not None else 0.0


def draw_report(res: dict, outlines: dict, radius_mm: float, path) -> Path:
    """Save the page to `path`. res: the study's results (objectives "KEY:max|min",
    best, references at their best K, reference_grid {name: {K: figures}}, history);
    outlines: {"design N" or reference name: (M, 2) outline in mm}; figures are
    [mean, spread, replica values], the spread None for one replica (no band drawn)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = [o.rpartition(":")[0] for o in res["objectives"]]
    maximise = res["objectives"][0].endswith(":max")
    key = keys[0]
    panels = [(f"design {i} (trial {r['trial']})\nK {r['ratio']:.3g}: {_fmt(r['figures'][key])}", f"design {i}", True)
              for i, r in enumerate(res["best"][:5], 1)]
    panels += [(f"{n}\nK {ref['ratio']:.3g}: {_fmt(ref['figures'][key])}", n, False) for n, ref in res["references"].items()]
    cols = max(len(panels), 2)
    fig = plt.figure(figsize=(max(12, 2.4 * cols), 9), constrained_layout=True)
    grid = fig.add_gridspec(2, cols, height_ratios=[1, 1.5])
    spread = ("1 replica: spread unknown (± ?), nothing compared" if res["spread"].startswith("unknown")
              else "mean ± replicas' s.d.")
    fig.suptitle(f"Jar design ({res['family']} family): {', '.join(res['objectives'])}; {res['evaluated']} designs, "
                 f"{res['pruned']} pruned; {spread}")
    lim = 1.1 * radius_mm
    for i, (title, name, designed) in enumerate(panels):
        ax = fig.add_subplot(grid[0, i])
        ring = np.vstack([outlines[name], outlines[name][:1]])
        ax.fill(*ring.T, color="tab:blue" if designed else "0.8", alpha=0.6)
        ax.plot(*ring.T, color="k", lw=1)
        ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", xticks=[], yticks=[])
        ax.set_title(title, fontsize=8)
    half = cols // 2
    ax = fig.add_subplot(grid[1, :half])
    hist = res["history"]
    n = [h["trial"] for h in hist]
    y = [h[key] for h in hist]
    ax.scatter(n, y, s=10, c=["tab:blue" if h["feasible"] else "0.6" for h in hist], label="designs (grey: infeasible)")
    running, best = [], None
    for h in hist:
        v = h[key]
        if h["feasible"] and math.isfinite(v) and (best is None or (v > best if maximise else v < best)):
            best = v
        running.append(best if best is not None else math.nan)
    ax.plot(n, running, color="k", label="best so far")
    for j, (name, ref) in enumerate(res["references"].items()):
        m, s, _ = ref["figures"][key]
        if s is not None:
            ax.axhspan(m - s, m + s, color=f"C{j + 2}", alpha=0.2)
        band = " ± s" if s is not None else ""
        ax.axhline(m, color=f"C{j + 2}", lw=1, label=f"{name} (K {ref['ratio']:.3g}){band}")
    ax.set(xlabel="trial", ylabel=f"{key} ({_unit(key)})", title="objective history")
    ax.legend(fontsize=7)
    ax = fig.add_subplot(grid[1, half:])
    if len(keys) > 1:
        a, b = keys[0], keys[1]
        ax.scatter([h[a] for h in hist], [h[b] for h in hist], s=10, color="0.6", label="designs")
        front = sorted(res["best"], key=lambda r: r["figures"][a][0])
        ax.errorbar([r["figures"][a][0] for r in front], [r["figures"][b][0] for r in front],
                    xerr=[_s(r["figures"][a]) for r in front], yerr=[_s(r["figures"][b]) for r in front],
                    color="tab:red", marker="o", label="Pareto front ± s")
        for j, (name, by_k) in enumerate(res["reference_grid"].items()):
            ax.scatter([f[a][0] for f in by_k.values()], [f[b][0] for f in by_k.values()], marker="s",
                       color=f"C{j + 2}", label=f"{name} (each K)")
        ax.set(xlabel=f"{a} ({_unit(a)})", ylabel=f"{b} ({_unit(b)})", title="Pareto front")
    else:
        ax.scatter([h["ratio"] for h in hist], y, s=10, color="tab:blue", label="designs")
        for j, (name, by_k) in enumerate(res["reference_grid"].items()):
            ks = sorted(by_k, key=float)
            ax.errorbar([float(k) for k in ks], [by_k[k][key][0] for k in ks], yerr=[_s(by_k[k][key]) for k in ks],
                        color=f"C{j + 2}", marker="s", ms=3, label=f"{name} ± s")
        ax.set(xlabel="K = ω/Ω + 1", ylabel=f"{key} ({_unit(key)})", title="objective against K")
    ax.legend(fontsize=7)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
