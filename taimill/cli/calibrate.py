"""`taimill calibrate …`: drop tests, the fit of a contact parameter to drop data, the
±50 % sensitivity (thesis Fig 2.5) and the two-sphere impacts (Fig 2.8). Each prints a
table, or with --json one JSON value on stdout and nothing else; --figure FILE draws it
(PNG or SVG). Bad input: one line on stderr, exit 2; a fit that cannot match the data:
one line, exit 1."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from taimill.cli.common import LAW_HELP, name_text, number, path_text, plain as _plain  # JSON-safe values, one definition

EXIT_NO_MATCH = 1
MAX_H0_MM = 10_000.0
MAX_OFFSETS = 1000  #: oblique impacts of one call
FIGURE_SUFFIXES = (".png", ".svg")


def _check_figure(a, inputs=()) -> None:
    """--figure: checked before anything runs (suffix, folder, an existing file: only
    a figure taimill drew is replaced, and none of `inputs`)."""
    if a.figure:
        from taimill.figures import is_figure
        from taimill.model.files import check_output

        check_output(a.figure, "--figure", overwrite=a.overwrite, suffixes=FIGURE_SUFFIXES, what="figure",
                     ours=is_figure, inputs=inputs)


def _emit(a, value, text, figure=None):
    if figure and a.figure:
        path = figure(value, a.figure)
        text += f"\nfigure: {path}"
    print(json.dumps(_plain(value), ensure_ascii=False) if a.json else text)


def announced(command):
    """The command, saying on stderr when its simulations compile kernels (a first
    drop test takes ≈ 4 s, a later one ≈ 1 s: physics.runner.CompilePlan)."""
    def run(a) -> int:
        from taimill.cli.run import say
        from taimill.runs.simulation import announcing

        with announcing(lambda plan: say(plan.text())):
            return command(a)

    return run


def _check(value, name, lo, hi, unit, lo_open=True):
    from taimill.errors import ConfigError

    if value is None or not math.isfinite(value) or value > hi or (value <= lo if lo_open else value < lo):
        raise ConfigError("command line", name, value, f"allowed range {'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}")
    return value


# ------------------------------------------------------------------ drop
def cmd_drop(a) -> int:
    from taimill.figures.calibration import drop_figure
    from taimill.model.contact_sets import pair_contact

    heights = [_check(h, "--h0", 0, MAX_H0_MM, "mm (drop height)") for h in a.h0]
    if a.radius_mm is not None:
        _check(a.radius_mm, "--radius-mm", 0, 100, "mm")
    media = dict(ball_material=a.ball_material, wall_material=a.wall_material)
    radius = None if a.radius_mm is None else a.radius_mm * 1e-3
    notes = []
    pair_contact(a.pair, radius, law=a.law, notes=notes, **media)  # bad input is reported before taichi starts
    _check_figure(a)
    for w in notes:
        print(f"taimill: warning: {w}", file=sys.stderr)
    from taimill.calibration.runs import drop_tests

    rs = drop_tests(a.pair, [h * 1e-3 for h in heights], target=a.target, law=a.law, radius=radius, **media)
    r = rs[0]
    head = (f"{r['pair']} ({r['law']}), {r['ball_material']} ball of {r['ball_radius'] * 1e3:g} mm radius on the "
            f"{r['target']}" + (f" of {r['wall_material']}" if r["target"] == "plate" else ""))
    if len(rs) == 1:
        text = "\n".join([
            f"{head}, from h0 = {heights[0]:g} mm ({r['impact_speed']:.3f} m/s):",
            f"  restitution e            {r['e']:.4f}",
            f"  rebound height h*        {r['rebound_height'] * 1e3:.1f} mm",
            f"  contact duration         {r['contact_duration'] * 1e6:.1f} µs",
            f"  peak force               {r['peak_force']:.0f} N",
            f"  peak penetration         {r['peak_penetration'] * 1e6:.2f} µm"])
    else:
        lines = [f"{head}:", f"{'h0 mm':>8} {'v m/s':>7} {'e':>7} {'h* mm':>8} {'t_c µs':>7} {'F_max N':>8} {'u_max µm':>8}"]
        lines += [f"{x['h0'] * 1e3:8g} {x['impact_speed']:7.3f} {x['e']:7.4f} {x['rebound_height'] * 1e3:8.1f} "
                  f"{x['contact_duration'] * 1e6:7.1f} {x['peak_force']:8.0f} {x['peak_penetration'] * 1e6:8.2f}" for x in rs]
        text = "\n".join(lines)
    _emit(a, rs[0] if len(rs) == 1 else rs, text, lambda v, p: drop_figure(rs, p))
    return 0


# ------------------------------------------------------------------ fit
def cmd_fit(a) -> int:
    from taimill.calibration.data import load_drop_data
    from taimill.figures.calibration import fit_figure
    from taimill.calibration.fit import FitError, fit_drops
    from taimill.calibration.pairfile import is_fitted_pair_file, write_pair_file
    from taimill.errors import ConfigError
    from taimill.model.files import check_output, reads
    from taimill.model.contact_sets import pair_contact
    from taimill.store.output import all_or_none

    _check(a.scatter, "--scatter", 0, 1, "(1 s.d. of e)")
    if a.out and not a.out.endswith(".toml"):
        raise ConfigError("command line", "--out", a.out, "a pair file must end in .toml")
    with reads() as inputs:  # the pair file and the data: --out must not replace them
        pair_contact(a.pair, law=a.law)
        data = load_drop_data(a.data)
    if a.out:
        check_output(a.out, "--out", overwrite=a.overwrite, what="fitted pair file",
                     ours=is_fitted_pair_file, inputs=inputs)
    _check_figure(a, inputs)
    try:
        fit = fit_drops(a.pair, data, param=a.param, law=a.law, scatter=a.scatter)
    except FitError as err:
        print(f"taimill: fit failed: {err}", file=sys.stderr)
        return EXIT_NO_MATCH
    p, u = fit["param"], fit["unit"]
    lines = [
        f"{fit['pair']} ({fit['law']}): {p} fitted to {fit['data']} ({len(fit['rows'])} drop height(s), {fit['evaluations']} simulated batches)",
        f"  {p} = {fit['value']:.5g} ± {fit['uncertainty']:.2g} {u}   (start {fit['start']:.4g} {u}: {fit['start_from']}; "
        f"the pair has {fit['pair_value']:.4g} {u})",
        f"  rms e residual {fit['rms_e']:.4f}, χ² = {fit['chi2']:.2f}"
        + (f", χ²/dof = {fit['chi2_per_dof']:.2f}" if fit["chi2_per_dof"] is not None else ""),
        f"{'h0 mm':>8} {'e meas':>7} {'e sim':>7} {'Δe':>8} {'h* meas':>8} {'h* sim':>8} {'Δh* mm':>7}  within 2σ",
    ]
    lines += [f"{r['h0_mm']:8g} {r['e_measured']:7.4f} {r['e_fit']:7.4f} {r['residual_e']:+8.4f} {r['rebound_measured_mm']:8.1f} "
              f"{r['rebound_fit_mm']:8.1f} {r['residual_mm']:+7.1f}  {'yes' if r['within_scatter'] else 'NO'}" for r in fit["rows"]]
    if any(r["rebound_measured_from"] != "rebound_mm" for r in fit["rows"]):
        lines.append("h* meas: e²·h0 where the data give no rebound_mm")
    outside = [f"{r['h0_mm']:g}" for r in fit["rows"] if not r["within_scatter"]]
    lines.append("all heights within the scatter" if not outside else
                 f"outside the scatter (|Δe| > 2σ) at h0 = {', '.join(outside)} mm: the law's e(h0) does not follow the data there")
    with all_or_none([a.out, a.figure]):  # a figure that fails takes the new pair file with it: run again as it was
        if a.out:
            write_pair_file(a.out, a.pair, law=fit["law"], override=fit["override"], name=a.name, comments=[
                f"{p} = {fit['value']:.6g} ± {fit['uncertainty']:.2g} {u} fitted to {fit['data']};",
                f"rms e residual {fit['rms_e']:.4f}; use it in a preset as pair = \"{Path(a.out).name}\"."])
            fit["pair_file"] = str(a.out)
            lines.append(f"pair file: {a.out} (in a preset: pair = \"PATH/{Path(a.out).name}\", PATH relative to the preset file)")
        _emit(a, fit, "\n".join(lines), fit_figure)
    return 0


# ------------------------------------------------------------------ sensitivity
def cmd_sensitivity(a) -> int:
    from taimill.figures.calibration import sensitivity_figure
    from taimill.calibration.impacts import sensitivity

    from taimill.model.contact_sets import pair_contact

    h0 = _check(a.h0, "--h0", 0, MAX_H0_MM, "mm (drop height)")
    change = _check(a.change, "--change", 0, 99, "% (kept below 100: parameters stay positive)") / 100.0
    pair_contact(a.pair, law=a.law)  # bad input is reported before taichi starts
    _check_figure(a)
    s = sensitivity(a.pair, h0 * 1e-3, law=a.law, target=a.target, change=change)
    ref = s["rows"][0]
    lines = [f"{s['pair']} ({s['law']}), drop on the {s['target']} from h0 = {h0:g} mm: reference e = {ref['e']:.4f}, "
             f"h* = {ref['rebound_height'] * 1e3:.1f} mm",
             f"{'parameter':>9} {'factor':>6} {'value (SI)':>12} {'e':>7} {'h* mm':>8} {'Δh* mm':>8} {'Δh*/h*':>8} {'(h*-h0)/h0':>10}"]
    lines += [f"{r['parameter']:>9} {r['factor']:6.2f} {'' if r['value'] is None else format(r['value'], '.4g'):>12} {r['e']:7.4f} "
              f"{r['rebound_height'] * 1e3:8.1f} {r['change'] * 1e3:+8.1f} {100 * r['relative_change']:+7.1f}% {r['thesis_dh']:+10.3f}"
              for r in s["rows"][1:]]
    lines.append("n is varied with k held in N/mm^n (MSC.Adams' units, as in the thesis)")
    _emit(a, s, "\n".join(lines), sensitivity_figure)
    return 0


# ------------------------------------------------------------------ oblique
def _offsets(text: str) -> list[float]:
    """'A:B:STEP' (mm, B included) or 'A,B,C'."""
    from taimill.errors import ConfigError

    try:
        if ":" in text:
            lo, hi, step = (float(x) for x in text.split(":"))
            if not (step > 0 and math.isfinite(lo) and math.isfinite(hi) and math.isfinite(step)):
                raise ValueError
        else:
            values = [float(x) for x in text.split(",")]
    except ValueError:
        raise ConfigError("command line", "--offsets", text, "A:B:STEP or a comma list, in mm (STEP > 0)") from None
    if ":" in text:
        if (hi - lo) / step + 1 > MAX_OFFSETS:
            raise ConfigError("command line", "--offsets", text, f"{(hi - lo) / step + 1:.3g} offsets; at most {MAX_OFFSETS}")
        values = [round(float(x), 9) for x in np.arange(lo, hi + 0.5 * step, step)]
    if not values or len(values) > MAX_OFFSETS:
        raise ConfigError("command line", "--offsets", text, f"1 to {MAX_OFFSETS} offsets")
    return values


def cmd_oblique(a) -> int:
    from taimill.figures.calibration import oblique_figure
    from taimill.calibration.impacts import oblique
    from taimill.model.contact_sets import pair_contact

    ball = pair_contact(a.pair, law=a.law)[0]
    grazing = 2e3 * ball.radius
    offsets = [_check(o, "--offsets", 0, grazing, f"mm ({grazing:g} mm = 2r: grazing)", lo_open=False) for o in _offsets(a.offsets)]
    speed = _check(a.speed, "--speed", 0, 100_000, "mm/s")
    _check_figure(a)
    o = oblique(a.pair, [x * 1e-3 for x in offsets], speed * 1e-3, law=a.law, friction=a.friction)
    lines = [f"{o['pair']} ({o['law']}), two spheres at {speed:g} mm/s, {'with' if o['friction'] else 'no'} friction; "
             f"velocities of sphere 0 relative to 1 on the apse line, mm/s, approach > 0",
             f"{'Δ mm':>5} {'u̇n':>7} {'u̇t':>7} {'e head-on':>9} {'u̇n final':>9} {'expected':>9} {'err':>7} "
             f"{'e=' + format(o['e_nominal'], 'g') + ' eq2.3':>11} {'off by':>7} {'u̇t final':>9} {'err':>7}"]
    lines += [f"{r['offset_mm']:5g} {1e3 * r['un']:7.1f} {1e3 * r['ut']:7.1f} {r['e_head_on']:9.4f} {1e3 * r['un_final']:9.1f} "
              f"{1e3 * r['un_final_expected']:9.1f} {100 * r['un_error']:+6.2f}% {1e3 * r['un_final_thesis']:11.1f} "
              f"{100 * r['thesis_error']:+6.1f}% {1e3 * r['ut_final']:9.1f} {100 * r['ut_error']:+6.2f}%" for r in o["rows"]]
    lines.append("expected: -e(u̇n)·u̇n with e of a head-on run at u̇n, tangential unchanged (eqs 2.1-2.4); "
                 "'off by': the thesis' constant-e formula against the simulation")
    _emit(a, o, "\n".join(lines), oblique_figure)
    return 0


def register(sub):
    c = sub.add_parser("calibrate", help="contact-parameter calibration and validation: drop, fit, sensitivity, oblique")
    csub = c.add_subparsers(dest="experiment", required=True)

    def common(p, figure_help, overwrite_help="replace an existing --figure file"):
        p.add_argument("--pair", required=True, type=name_text, help="friction/contact pair, e.g. steel-steel, or a pair file NAME.toml")
        p.add_argument("--law", help=f"{LAW_HELP}; default: the pair's")
        p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
        p.add_argument("--figure", metavar="FILE", type=path_text, help=f"draw {figure_help} (.png or .svg)")
        p.add_argument("--overwrite", action="store_true", help=overwrite_help)

    d = csub.add_parser("drop", help="drop tests: restitution and rebound height for one or more heights")
    common(d, "e and h* against h0")
    d.add_argument("--h0", type=number, nargs="+", required=True, metavar="MM", help="drop height(s) (mm)")
    d.add_argument("--target", choices=("plate", "ball"), default="plate")
    d.add_argument("--radius-mm", type=number, help="ball radius (default: the pair's fitted balls)")
    d.add_argument("--ball-material", type=name_text, help="ball material other than the pair's contact set's: its derived set (docs/media.md)")
    d.add_argument("--wall-material", type=name_text, help="plate material other than the pair's contact set's: its derived set")
    d.set_defaults(fn=announced(cmd_drop))

    f = csub.add_parser("fit", help="fit d (or c_max; e for other laws) to measured drop tests, write a pair file")
    common(f, "measured and fitted e(h0) and the residuals", "replace an existing --out or --figure file")
    f.add_argument("--data", required=True, type=path_text, help="CSV with h0_mm and rebound_mm or e (taimill/data/zirconia_drop_table2_1.csv)")
    f.add_argument("--param", choices=("d", "c_max", "e"), help="fitted parameter (default: e for laws whose damping comes from e, d otherwise)")
    f.add_argument("--scatter", type=number, default=0.02, help="1 s.d. of a measured e where the data give none (default 0.02)")
    f.add_argument("--out", type=path_text, help="pair file to write (NAME.toml), usable as pair = \"NAME.toml\" in presets")
    f.add_argument("--name", type=name_text, help="pair name inside the file (default PAIR-fit)")
    f.set_defaults(fn=announced(cmd_fit))

    s = csub.add_parser("sensitivity", help="thesis Fig 2.5: change each contact parameter by ±50 %%, rebound height")
    common(s, "the change of rebound height per parameter")
    s.add_argument("--h0", type=number, default=500.0, help="drop height (mm, default 500 as in the thesis)")
    s.add_argument("--target", choices=("plate", "ball"), default="plate")
    s.add_argument("--change", type=number, default=50.0, help="relative change of each parameter (%%, default 50)")
    s.set_defaults(fn=announced(cmd_sensitivity))

    o = csub.add_parser("oblique", help="thesis Fig 2.8: two spheres with offsets, simulated vs eqs 2.3/2.4")
    common(o, "final normal and tangential relative velocities against the offset")
    o.add_argument("--speed", type=number, default=3300.0, help="relative speed (mm/s, default 3300)")
    o.add_argument("--offsets", default="0:12:1", help="centre offsets Δ in mm, A:B:STEP or A,B,C (default 0:12:1)")
    o.add_argument("--friction", action="store_true", help="use the pair's friction (default frictionless, as Fig 2.8)")
    o.set_defaults(fn=announced(cmd_oblique))
