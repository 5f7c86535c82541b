"""Publication figures of one run (matplotlib, headless). Each panel is a function
drawing into axes it is given, so the single figures and the overview sheet share
the drawing code. Units on every axis; each file carries its caption in its metadata
(PNG/SVG 'Description', PDF 'Subject')."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap, LogNorm  # noqa: E402

from taimill.analysis.events import ENERGY_BINS, SPEED_BINS, log_pdf  # noqa: E402
from taimill.analysis.run import RunAnalysis  # noqa: E402
from taimill.analysis.spatial import MIN_EVENTS, uniform  # noqa: E402
from taimill.figures.layout import colorbar_beside, fit_log, legend_outside, nothing, occupied  # noqa: E402
from taimill.store.output import whole_file  # noqa: E402
from taimill.figures.spectra import drawn, spectra_figure  # noqa: E402
from taimill.figures.trajectories import draw_trajectories_section, draw_trajectories_top, outline  # noqa: E402

FORMATS = ("png", "svg", "pdf")
MM = 1e3
plt.rcParams.update({"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "legend.fontsize": 8,
                     "figure.dpi": 150, "savefig.bbox": "tight"})


def draw_gr(ax, a: RunAnalysis):
    e = a.density.edges * MM
    ax.stairs(a.density.g, e, fill=True, alpha=0.5, color="C0", label="g(r)")
    ax.axhline(1.0, color="0.4", ls="--", lw=0.8, label="uniform")
    ax.set(xlabel="distance from the jar axis r (mm)", ylabel="g(r) (–)",
           title=f"Cylindrical distribution, 1/σ = {a.density.randomness_index:.3g}")
    legend_outside(ax)


def draw_velocity_pdfs(ax, a: RunAnalysis):
    centres = np.sqrt(SPEED_BINS[1:] * SPEED_BINS[:-1]) * MM
    for hist, name, ls in ((a.event.hist_un, "normal u̇n", "-"), (a.event.hist_ut, "tangential u̇t", "--")):
        for k, kind in enumerate(("ball–ball", "ball–wall")):
            if hist[k].sum():
                ax.plot(centres, log_pdf(hist[k], SPEED_BINS), ls=ls, color=f"C{k}", label=f"{name}, {kind}")
    ax.set(xscale="log", xlabel="onset relative speed (mm/s)", ylabel="probability density (1/decade)",
           title="Onset velocity distributions")
    fit_log(ax, occupied(SPEED_BINS, a.event.hist_un, a.event.hist_ut) * MM)
    _legend_or_none(ax, "stress event")


def draw_se(ax, a: RunAnalysis):
    centres = np.sqrt(ENERGY_BINS[1:] * ENERGY_BINS[:-1]) * MM
    n = a.event.hist_se_n.sum(axis=0)
    t = a.event.hist_se_t.sum(axis=0)
    for hist, label, c in ((n, "normal", "C0"), (t, "tangential", "C1")):
        if hist.sum():
            ax.plot(centres, log_pdf(hist, ENERGY_BINS), color=c, label=label)
    r = a.event.result(a.tau)
    for key, c in (("mean_se_normal", "C0"), ("mean_se_tangential", "C1")):
        if np.isfinite(r[key]):
            ax.axvline(r[key] * MM, color=c, ls=":", lw=1)
    ax.set(xscale="log", xlabel="stress energy per event (mJ)", ylabel="probability density (1/decade)",
           title=f"Stress energy ({_estimator(a)}); dotted: means")
    fit_log(ax, occupied(ENERGY_BINS, n, t) * MM)
    _legend_or_none(ax, "stress event")


def _legend_or_none(ax, what: str):
    """The legend outside the axes, or, with nothing drawn, say so on them."""
    if ax.get_legend_handles_labels()[0]:
        legend_outside(ax)
    else:
        _nothing(ax, what)


def _nothing(ax, what: str):
    nothing(ax, f"no {what} in the analysis window")


def _number(v: float) -> str:
    return f"{v:.3g}" if np.isfinite(v) else "–"


def _estimator(a: RunAnalysis) -> str:
    return f"stress events, u̇n ≥ {a.event.min_un * MM:g} mm/s" if a.event.min_un > 0 else "all contacts"


def draw_mechanisms(ax, a: RunAnalysis):
    """Dissipated power by contact kind, class and part (the energy ledger's split)."""
    table = a.energy.get("dissipation_by_mechanism")
    if not table:
        ax.text(0.5, 0.5, "no mechanism ledger in this store", ha="center", transform=ax.transAxes)
        return
    kinds = list(table)
    bottom = np.zeros(len(kinds))
    for (cls, part), colour in zip((("impact", "normal"), ("impact", "friction"), ("persistent", "normal"),
                                    ("persistent", "friction")), ("C3", "C1", "C0", "C9")):
        p = np.array([table[k][cls][part] for k in kinds])
        ax.bar([k.replace("_", "–") for k in kinds], p, bottom=bottom, color=colour, label=f"{cls}, {part}")
        bottom += p
    m = a.energy["main_sink"]
    ax.set(ylabel="dissipated power (W)", title=f"Where the power goes: {a.energy['dissipated_power']:.3g} W; "
           f"main sink {m['mechanism']} ({m['share']:.0%})")
    ax.title.set_fontsize(9)
    legend_outside(ax)


def draw_dissipation_spectra(ax, a: RunAnalysis):
    """Distribution of the energy each stress event dissipates, normal and by friction."""
    centres = np.sqrt(ENERGY_BINS[1:] * ENERGY_BINS[:-1]) * MM
    for hist, name, ls in ((a.event.hist_diss_n, "normal", "-"), (a.event.hist_diss_t, "friction (shear)", "--")):
        for k, kind in enumerate(("ball–ball", "ball–wall")):
            if hist[k].sum():
                ax.plot(centres, log_pdf(hist[k], ENERGY_BINS), ls=ls, color=f"C{k}", label=f"{name}, {kind}")
    ax.set(xscale="log", xlabel="energy dissipated per event (mJ)", ylabel="probability density (1/decade)",
           title=f"Dissipated-energy spectra ({_estimator(a)})")
    fit_log(ax, occupied(ENERGY_BINS, a.event.hist_diss_n, a.event.hist_diss_t) * MM)
    _legend_or_none(ax, "stress event")


def draw_contact_map(ax, a: RunAnalysis, fig):
    side = a.contacts["side"]
    order = np.argsort(side["un"])
    un = np.maximum(side["un"][order], 1e-5) * MM
    sc = ax.scatter(side["arc_length"][order] * MM, side["z"][order] * MM, c=un, s=2, cmap="viridis",
                    norm=LogNorm(vmin=max(un.min(), 1e-2), vmax=max(un.max(), 1.0)) if len(un) else None)
    _wall_axes(ax, a)
    ax.set_title("Ball–jar impacts on the unrolled side wall")
    if len(un):
        colorbar_beside(fig, sc, ax, "onset normal speed u̇n (mm/s)")
    else:
        _nothing(ax, "ball–jar impact")


def _wall_axes(ax, a: RunAnalysis):
    g = a.geom
    ax.set(xlim=(0, g.perimeter * MM), ylim=(0, g.height * MM), xlabel="position along the wall (mm, CCW from +x)",
           ylabel="height z (mm)")
    top = ax.secondary_xaxis("top")
    ticks = np.linspace(0, g.perimeter, 9)
    top.set_xticks(ticks * MM, [f"{v:.0f}°" for v in g.wall_angle(ticks)])
    top.set_xlabel("polar angle in the jar frame")


SPARSE_GREY = "0.82"  # wall-map cells with too few events to show (MIN_EVENTS)
HOT_COLOUR = "c"


def draw_wear_map(axes, a: RunAnalysis, fig):
    """axes: (side, floor, lid). Cells with fewer than MIN_EVENTS events are grey (their
    power per area is counting noise); the hot spot (WallMap.hot_spot) is marked by a
    cross, or, when no cell stands out of its band, that band is outlined."""
    tau, w = a.tau, a.wall
    power = {s: w.power(s, tau) for s in ("side", "floor", "lid")}
    shown = {s: np.where(w.sampled(s) & (power[s] > 0), power[s], np.nan) for s in power}
    vals = np.concatenate([v[np.isfinite(v)] for v in shown.values()])
    norm = LogNorm(vmin=vals.min(), vmax=vals.max()) if len(vals) else None
    hot = w.hot_spot(tau)
    band = hot.get("band", {})
    ax = axes[0]
    _grey(ax, w.s_edges * MM, w.z_edges * MM, np.ones_like(w.side_area, bool), shown["side"])
    im = ax.pcolormesh(w.s_edges * MM, w.z_edges * MM, np.ma.masked_invalid(shown["side"].T), norm=norm, cmap="inferno")
    _wall_axes(ax, a)
    ax.set_title("Wear indicator: impact + friction power per area, side wall")
    if hot.get("kind", "spot") == "spot" and hot.get("surface") == "side":
        ax.plot(hot["arc_length"] * MM, hot["z"] * MM, "+", color=HOT_COLOUR, ms=12, mew=2)
    elif "z_range" in band:
        lo, hi = np.array(band["z_range"]) * MM
        ax.add_patch(plt.Rectangle((0, lo), w.s_edges[-1] * MM, hi - lo, fill=False, ec=HOT_COLOUR, lw=1.5))
    e = w.xy_edges * MM
    for ax, s in zip(axes[1:], ("floor", "lid")):
        _clip_to_jar(ax, a, _grey(ax, e, e, w.disc_area > 0, shown[s]),
                     ax.pcolormesh(e, e, np.ma.masked_invalid(shown[s].T), norm=norm, cmap="inferno"))
        outline(ax, a)
        if hot.get("kind", "spot") == "spot" and hot.get("surface") == s:
            ax.plot(hot["x"] * MM, hot["y"] * MM, "+", color=HOT_COLOUR, ms=12, mew=2)
        elif band.get("surface") == s:
            for r in np.array(band["r_range"]) * MM:
                ax.add_patch(plt.Circle((0, 0), r, fill=False, ec=HOT_COLOUR, lw=1.2))
        ax.set(xlabel="x (mm)", ylabel="y (mm)", title=s)
    label = "W/m² (impact ½mu̇n² + friction work)"
    if norm is not None:
        colorbar_beside(fig, im, axes[0], label)
        colorbar_beside(fig, im, axes[2], label)
    else:
        _nothing(axes[0], f"wall cell with {MIN_EVENTS} events or more")
    handles = [plt.Rectangle((0, 0), 1, 1, fc=SPARSE_GREY, ec="none", label=f"fewer than {MIN_EVENTS} events: not shown")]
    if hot.get("kind", "spot") == "spot" and hot.get("surface"):
        handles.append(plt.Line2D([], [], ls="none", marker="+", color=HOT_COLOUR, ms=10, mew=2,
                                  label=f"hot spot, {hot['over_band']:.3g}× the rest of its band" if "over_band" in hot
                                  else "hot spot"))
    elif band:
        around = "wall" if band["surface"] == "side" else "axis"
        why = (f"uniform around the {around}, no hot spot" if uniform(hot) else
               f"no hot spot found; {band['sampled_share']:.0%} of its cells with ≥ {MIN_EVENTS} events")
        handles.append(plt.Rectangle((0, 0), 1, 1, fill=False, ec=HOT_COLOUR, lw=1.5, label=f"most wear: this band ({why})"))
    legend_outside(axes[0], handles=handles, below=True, gap=0.45, ncol=2, frameon=False)


def _grey(ax, xe, ye, inside: np.ndarray, shown: np.ndarray):
    """Grey the cells inside the jar that are not shown (too few events)."""
    sparse = inside & ~np.isfinite(shown)
    return ax.pcolormesh(xe, ye, np.ma.masked_where(~sparse.T, np.ones(sparse.T.shape)),
                         cmap=ListedColormap([SPARSE_GREY]), vmin=0, vmax=2)


def _clip_to_jar(ax, a: RunAnalysis, *meshes):
    """Floor and lid cells cut by the wall are drawn only inside the jar's profile."""
    jar = plt.Polygon(a.geom.profile.outline * MM, closed=True, transform=ax.transData, fc="none", ec="none")
    for m in meshes:
        m.set_clip_path(jar)


def draw_energy(ax, a: RunAnalysis):
    en = a.store.energy
    t = en["time"]
    mech = en["kinetic"] + en["potential"] + en["elastic"]
    ax.plot(t, en["drive_work"], label="drive work (walls on balls)")
    ax.plot(t, en["dissipated"], label="dissipated by contacts")
    ax.plot(t, mech - mech[0] if len(mech) else mech, label="kinetic + potential + elastic − initial")
    ax.axvline(a.t0, color="0.5", ls=":", lw=1, label=f"analysis start ({a.t0:g} s)")
    ax.set(xlabel="simulated time (s)", ylabel="energy (J)", title="Energy budget")
    axes = [ax]
    if len(t):
        bal = (mech + en["dissipated"]) - (mech[0] + en["drive_work"])
        scale = max(float(np.abs(en["drive_work"]).max()), 1e-300)
        ax2 = ax.twinx()
        ax2.plot(t, 100 * bal / scale, color="0.4", lw=0.7, label="balance error (right axis)")
        ax2.set_ylabel("balance error (% of drive work)", color="0.4")
        axes.append(ax2)  # drawn on top: the legend goes there, not hidden by its curve
    handles = [h for axis in axes for h in axis.get_legend_handles_labels()[0]]
    legend_outside(axes[-1], handles=handles, below=True, gap=0.5, ncol=2)


def _caption(a: RunAnalysis, what: str) -> str:
    g = a.geom
    return (f"{what}. Run {a.store.group.store}; K = {g.ratio:.3g}, Ω = {g.drive.plate_rpm:.4g} rpm, "
            f"{g.n_balls} balls; window {a.t0:g}–{a.t1:g} s; {_estimator(a)}.")


def _save(fig, path: Path, caption: str, title: str):
    fmt = path.suffix.lstrip(".")
    meta = {"Title": title, "Subject" if fmt == "pdf" else "Description": caption}
    try:
        with whole_file(path, "figure") as part:
            fig.savefig(part, metadata=meta)
    finally:
        plt.close(fig)


FIGURES = {
    "trajectories": "Ball trajectories in the jar frame: top view and section; dots: the stored frames, joined by "
                    "a curve only where it departs less than half a ball radius from the straight step between them, "
                    "else left as points",
    "g_r": "Cylindrical distribution function g(r) (thesis eq 3.9) and randomness index 1/σ",
    "velocities": "Probability densities of the onset normal and tangential relative speeds (log bins)",
    "stress_energy": "Distribution of the stress energy per collision event, normal and tangential",
    "contact_map": "Ball–jar contact map: impact points on the unrolled side wall coloured by onset normal speed",
    "wear_map": "Wear map: normal impact energy plus friction work per unit wall area and time; grey: cells with "
                f"fewer than {MIN_EVENTS} events (too few to show); cross: a hot spot standing out of its band, "
                "or outlined: the band with most wear when none does",
    "energy": "Energy budget over time: drive work, dissipation, mechanical energy, balance error",
    "mechanisms": "Dissipated power by contact kind, class (impact or persistent) and part (normal or friction)",
    "dissipation_spectra": "Distribution of the energy dissipated per stress event, normal and by friction, per kind",
    "energy_spectra": "Collisions per second per decade of energy: dissipated (normal, friction) and kinematic (normal, tangential)",
    "overview": "Overview of the run",
}


# Figures drawn from the event estimator's distributions (a.event): one curve per
# stress event class, nothing else on them.
EVENT_FIGURES = ("velocities", "stress_energy", "dissipation_spectra")


def left_out(a: RunAnalysis) -> dict[str, str]:
    """The figures of FIGURES this run has nothing to draw in, each with why: the event
    distributions of a window without a stress event (a friction-led charge: a pinned
    ring, a bed sliding on the wall) or of a run that kept no event rows, and the energy
    spectra without an event of 1 pJ or more. A figure of nothing but "no data" text
    says less than `report`'s one line naming it; the overview sheet keeps its panels,
    which say so."""
    out = {}
    if not a.event.count.sum():
        if not a.events_stored:
            why = 'the run kept no event rows (outputs.events = "spectra")'
        else:
            what = f"stress event (onset u̇n ≥ {a.event.min_un * MM:g} mm/s)" if a.event.min_un > 0 else "event"
            why = f"no {what} in the analysis window {a.t0:.4g}–{a.t1:.4g} s"
        out.update(dict.fromkeys(EVENT_FIGURES, why))
    sp = a.summary.last_spectra
    if sp is None:
        out["energy_spectra"] = "no energy spectra in the store"
    elif not drawn(sp):
        out["energy_spectra"] = "no event of 1 pJ or more in the window"
    return out


def left_out_text(left: dict[str, str]) -> str:
    """One line naming the figures left out, grouped by why; "" if none."""
    by_why: dict[str, list[str]] = {}
    for name, why in left.items():
        by_why.setdefault(why, []).append(name)
    return "; ".join(f"{', '.join(names)} left out: {why}" for why, names in by_why.items())


def write_report(a: RunAnalysis, out_dir, fmt: str = "png", leave_out: dict[str, str] | None = None) -> list[Path]:
    """Write every figure of FIGURES into out_dir as fmt but those of `leave_out`
    (default: left_out(a)); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    skip = left_out(a) if leave_out is None else leave_out
    paths = []

    def save(name, fig):
        p = out / f"{name}.{fmt}"
        _save(fig, p, _caption(a, FIGURES[name]), FIGURES[name])
        paths.append(p)

    fig, (t1, t2) = plt.subplots(1, 2, figsize=(9, 4), layout="constrained")
    draw_trajectories_top(t1, a)
    draw_trajectories_section(t2, a)
    save("trajectories", fig)
    for name, draw in (("g_r", draw_gr), ("velocities", draw_velocity_pdfs), ("stress_energy", draw_se),
                       ("energy", draw_energy), ("mechanisms", draw_mechanisms),
                       ("dissipation_spectra", draw_dissipation_spectra)):
        if name in skip:
            continue
        fig, ax = plt.subplots(figsize=(5.5, 4), layout="constrained")
        draw(ax, a)
        save(name, fig)
    fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
    draw_contact_map(ax, a, fig)
    save("contact_map", fig)
    fig = plt.figure(figsize=(9, 6.5), layout="constrained")
    gs = fig.add_gridspec(2, 2, height_ratios=(1, 1.4))
    draw_wear_map((fig.add_subplot(gs[0, :]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[1, 1])), a, fig)
    save("wear_map", fig)
    if "energy_spectra" not in skip:
        save("energy_spectra", spectra_figure([("this run", a.summary.last_spectra)],
                                              f"Energy spectra of the collision events, {a.t0:g}–{a.t1:g} s"))
    save("overview", overview(a))
    return paths


def overview(a: RunAnalysis):
    fig = plt.figure(figsize=(16, 23), layout="constrained")
    gs = fig.add_gridspec(6, 3, height_ratios=(1, 1, 0.8, 0.9, 1, 0.9))
    draw_trajectories_top(fig.add_subplot(gs[0, 0]), a)
    draw_gr(fig.add_subplot(gs[0, 1]), a)
    draw_velocity_pdfs(fig.add_subplot(gs[0, 2]), a)
    draw_se(fig.add_subplot(gs[1, 0]), a)
    draw_energy(fig.add_subplot(gs[1, 1]), a)
    draw_trajectories_section(fig.add_subplot(gs[1, 2]), a)
    draw_contact_map(fig.add_subplot(gs[2, :]), a, fig)
    draw_wear_map((fig.add_subplot(gs[3, :]), fig.add_subplot(gs[4, 0]), fig.add_subplot(gs[4, 1])), a, fig)
    draw_dissipation_spectra(fig.add_subplot(gs[4, 2]), a)
    draw_mechanisms(fig.add_subplot(gs[5, :]), a)
    q = a.quantities()
    e = q["event_estimator"]
    sink = f" (main sink: {q['main_sink']['mechanism']})" if q.get("main_sink") else ""
    fig.suptitle(f"K = {a.geom.ratio:.3g}, Ω = {q['plate_rpm']:.4g} rpm — {q['regime']} "
                 f"(confidence {q['regime_confidence']:.2f}); ⟨SE⟩ = {_number(e['mean_se'] * MM)} mJ, "
                 f"E_I/τ = {e['impact_power']:.3g} W, {e['collision_rate']:.4g} /s ({_estimator(a)}); "
                 f"dissipated {q['dissipated_power']:.3g} W{sink}", fontsize=11)
    return fig
