"""`taimill heat predict RUN.zarr` and `taimill heat fit RUN.zarr --measured CSV`: the
temperatures of balls, powder and jar over a mill programme from a run's dissipated
power, and the jar's heat transfer coefficient fitted to measured temperatures
(docs/outcome.md, "Heat")."""

from __future__ import annotations

import json
import math
import sys

from taimill.cli.common import number, path_text

WHATS = {"jar": 2, "ball": 0, "balls": 0, "powder": 1}  #: measured column `what` -> node
TIME_UNITS = {"time_s": 1.0, "time_min": 60.0, "time_h": 3600.0}
DEFAULT_WALL_MM = 5.0
WALL_NOTE = ("estimate: the catalogue holds no bowl's wall; 5 mm of wall, floor and lid of the jar's material "
             "(weigh your bowl with its lid and give --jar-mass)")
H_RANGE = (0.01, 1e4)  #: W/(m² K), where a fitted coefficient is looked for


def _common(p, fit: bool) -> None:
    p.add_argument("run", type=path_text, help="a run store (taimill run --out RUN.zarr) with powder")
    p.add_argument("--programme", default="continuous", metavar="RUN_MIN:PAUSE_MIN",
                   help="the controller: run RUN_MIN, pause PAUSE_MIN, repeated (default: continuous)")
    p.add_argument("--ambient", type=number, default=25.0, help="the mill chamber's air, °C (default 25)")
    p.add_argument("--powder-cp", type=number, metavar="J/KGK", help="the powder's specific heat, J/(kg K)")
    p.add_argument("--h-conv", type=number, metavar="W/M2K",
                   help="jar to air (default: the rotating-jar correlation, docs/outcome.md)")
    p.add_argument("--h-contact", type=number, metavar="W/M2K",
                   help="balls to jar over the balls' surface (default: a ball in moving gas, Ranz-Marshall)")
    p.add_argument("--jar-mass", type=number, metavar="KG", help="the jar with its lid (default: estimated from a 5 mm wall)")
    p.add_argument("--powder-share", type=number, default=0.0, help="share of the contacts' heat made in the powder (default 0)")
    p.add_argument("--figure", type=path_text, help="temperatures against time (PNG or SVG)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --figure that taimill drew")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def register(sub) -> None:
    p = sub.add_parser("heat", help="temperatures of balls, powder and jar from a run's dissipated power")
    s = p.add_subparsers(dest="heat", required=True)
    q = s.add_parser("predict", help="temperatures over a mill programme, the steady state and a limit's warning")
    _common(q, False)
    q.add_argument("--hours", type=number, default=1.0, help="length of the programme, h (default 1)")
    q.add_argument("--limit", type=number, metavar="C", help="warn when the powder reaches this temperature, °C")
    q.set_defaults(fn=cmd_predict)
    f = s.add_parser("fit", help="fit the jar-to-air (or ball-to-jar) coefficient to measured temperatures")
    _common(f, True)
    f.add_argument("--measured", type=path_text, required=True,
                   help="CSV: time_s|time_min|time_h, temperature_C, what (jar, ball or powder)")
    f.add_argument("--fit", choices=("h-conv", "h-contact"), default="h-conv", help="the coefficient fitted (default h-conv)")
    f.add_argument("--sigma", type=number, default=1.0, help="the thermometer's standard uncertainty, K (default 1)")
    f.set_defaults(fn=cmd_fit)


def programme(text: str, total_s: float):
    from taimill.errors import ConfigError
    from taimill.outcome.thermal import Programme

    if text == "continuous":
        return Programme(total_s, 0.0, total_s)
    run, colon, pause = text.partition(":")
    try:
        r, p = float(run), float(pause)
    except ValueError:
        r = p = math.nan
    if not colon or not (math.isfinite(r) and math.isfinite(p)) or not 0 < r <= 10_000 or not 0 <= p <= 10_000:
        raise ConfigError("command line", "--programme", text, "RUN_MIN:PAUSE_MIN, run in (0, 10000] min, pause in "
                          "[0, 10000] min (e.g. 15:5), or continuous")
    return Programme(60.0 * r, 60.0 * p, total_s)


def _check(option, value, lo, hi, text):
    from taimill.errors import ConfigError

    if value is not None and not (lo <= value <= hi):
        raise ConfigError("command line", option, value, f"allowed range {text}")


def setup_of_run(a) -> tuple:
    """(Setup, notes, estimates) of the run store `a.run` with the options' values."""
    import numpy as np

    from taimill.errors import ConfigError, StoreError
    from taimill.model.jars import Jar
    from taimill.model.materials import thermal_data
    from taimill.outcome import thermal
    from taimill.store.run import open_run

    if a.run.lower().endswith(".json"):
        raise ConfigError("command line", "run", a.run, "a run store (RUN.zarr): a summary JSON does not hold the "
                          "balls, the jar and the powder")
    try:
        run = open_run(a.run)
    except StoreError as err:
        raise ConfigError("command line", "run", a.run, f"cannot be read ({err})") from None
    cfg, summ = run.config or {}, run.summary or {}
    by = summ.get("dissipation_by_mechanism")
    if not cfg or not isinstance(by, dict):
        raise ConfigError("command line", "run", a.run, "not a finished taimill run store (no config or dissipation by mechanism)")
    balls, jc = cfg["balls"], cfg["jar"]
    powder_kg = float(((cfg.get("powder") or {}).get("mass")) or 0.0)
    if powder_kg > 0 and a.powder_cp is None:
        raise ConfigError("command line", "--powder-cp", None, "missing: the powder's specific heat in J/(kg K) "
                          "(taimill does not know the powder)")
    _check("--powder-cp", a.powder_cp, 50, 1e4, "[50, 10000] J/(kg K)")
    _check("--ambient", a.ambient, -80, 200, "[-80, 200] °C")
    _check("--h-conv", a.h_conv, 0.01, 1e4, "[0.01, 10000] W/(m² K)")
    _check("--h-contact", a.h_contact, 0.01, 1e5, "[0.01, 100000] W/(m² K)")
    _check("--jar-mass", a.jar_mass, 0.001, 100, "[0.001, 100] kg")
    _check("--powder-share", a.powder_share, 0, 1, "[0, 1]")
    if a.powder_share > 0 and powder_kg <= 0:
        raise ConfigError("command line", "--powder-share", a.powder_share, "0 for a run without powder")
    ball_t = thermal_data(balls["material"]["name"], "command line", "run")
    jar_t = thermal_data(jc["wall_material"], "command line", "run")
    from taimill.model.materials import load_material

    jar_rho = load_material(jc["wall_material"]).density
    jar = Jar(jc.get("name", "jar"), jc.get("source", ""), float(jc["height"]), jc["wall_material"],
              tuple((k, dict(v)) for k, v in jc["primitives"]), float(jc.get("fillet", 0.0)))
    outline = jar.profile.outline
    r_in = jar.radius
    estimates = [*ball_t.estimate_notes("ball material"), *jar_t.estimate_notes("jar material")]
    wall = DEFAULT_WALL_MM * 1e-3
    r_out, h_out_len = r_in + wall, jar.height + 2 * wall
    if a.jar_mass is None:
        jar_mass = jar_rho * (math.pi * r_out**2 * h_out_len - jar.volume)
        estimates.append(f"jar mass {jar_mass:.3g} kg: {WALL_NOTE}")
    else:
        jar_mass = a.jar_mass
    area_out = 2 * math.pi * r_out * h_out_len + math.pi * r_out**2  # side and lid; the floor sits in the clamp
    n, r = int(balls["count"]), float(balls["radius"])
    rho_b = float(balls["material"]["density"])
    plate, spin = float(cfg.get("plate_omega", 0.0)), float(cfg.get("jar_spin", 0.0))  # rad/s; the jar's is absolute
    hj = thermal.h_jar(2 * r_out, spin, abs(plate) * float(cfg.get("plate_radius", 0.0)))
    v_ball = abs(spin - plate) * r_in  # the wall's speed past the charge, which the plate holds outward
    h_ball = thermal.nu_sphere(v_ball * 2 * r / thermal.AIR_NU) * thermal.AIR_K / (2 * r)
    p_bb = sum(v for c in by["ball_ball"].values() for v in c.values())
    p_bw = sum(v for k in ("side", "floor", "lid") for c in by[k].values() for v in c.values())
    e_b = thermal.effusivity(ball_t.conductivity, rho_b, ball_t.cp)
    e_w = thermal.effusivity(jar_t.conductivity, jar_rho, jar_t.cp)
    s = thermal.Setup(
        ball_mass=n * rho_b * 4 / 3 * math.pi * r**3, ball_cp=ball_t.cp, ball_diameter=2 * r, ball_count=n,
        powder_mass=powder_kg, powder_cp=a.powder_cp or 0.0, jar_mass=jar_mass, jar_cp=jar_t.cp, jar_area=area_out,
        ball_area=n * 4 * math.pi * r**2, h_out=a.h_conv if a.h_conv is not None else hj["h"],
        h_in=a.h_contact if a.h_contact is not None else h_ball, p_ball_ball=max(p_bb, 0.0),
        p_ball_wall=max(p_bw, 0.0), share_wall=thermal.wall_share(e_b, e_w), powder_share=a.powder_share)
    notes = {"h_conv_correlation": hj["h"], "h_contact_correlation": h_ball, "nu_spin": hj["nu_spin"],
             "nu_orbit": hj["nu_orbit"], "jar_outer_area_m2": area_out, "jar_mass_kg": jar_mass,
             "inner_perimeter_m": float(np.sum(np.hypot(*np.diff(outline, axis=0).T))),
             "h_conv_from": "--h-conv" if a.h_conv is not None else "correlation",
             "h_contact_from": "--h-contact" if a.h_contact is not None else "correlation",
             "sources": {"ball_" + k: v for k, v in ball_t.sources.items()} | {"jar_" + k: v for k, v in jar_t.sources.items()}}
    return s, notes, estimates


def _outputs(a, inputs):
    from taimill.cli.calibrate import FIGURE_SUFFIXES
    from taimill.cli.kinetics import _check_outputs
    from taimill.figures import is_figure

    return _check_outputs([("--figure", a.figure, "figure", is_figure, FIGURE_SUFFIXES)], a.overwrite, inputs)


def _draw(a, given, inputs, draw) -> None:
    from taimill.cli.kinetics import _commit, _writing
    from taimill.store.output import Outputs

    if not given:
        return
    with Outputs() as outs:
        build = _writing(outs, given, a.overwrite, inputs)
        draw(build["--figure"])
        _commit(outs)


def _celsius(x, ambient):
    return [float(v) + ambient for v in x]


def cmd_predict(a) -> int:
    import numpy as np

    from taimill.cli.common import plain
    from taimill.model.files import reads
    from taimill.outcome import thermal

    _check("--hours", a.hours, 1e-3, 1000, "[0.001, 1000] h")
    prog = programme(a.programme, a.hours * 3600.0)
    with reads() as inputs:
        s, notes, estimates = setup_of_run(a)
    if a.limit is not None and not a.ambient < a.limit <= 2000:
        from taimill.errors import ConfigError

        raise ConfigError("command line", "--limit", a.limit, f"allowed range ({a.ambient:g}, 2000] °C (above --ambient)")
    given = _outputs(a, [*inputs, a.run])
    net, q = thermal.network(s)
    hist = thermal.simulate(net, q, prog, samples=max(1, min(20, 40_000 // len(prog.phases()))))
    per = thermal.periodic(net, q, prog)
    cont = thermal.steady(net, q)
    crossing = None
    if a.limit is not None:
        crossing = thermal.first_crossing(net, q, prog, 1, a.limit - a.ambient)
    out = {"run": a.run, "ambient_C": a.ambient, "programme": {"run_s": prog.run_s, "pause_s": prog.pause_s,
                                                                 "total_s": prog.total_s},
           "power_W": {n: float(v) for n, v in zip(thermal.NODES, q)},
           "heat_capacity_J_per_K": dict(zip(thermal.NODES, net.C.tolist())),
           "h_conv_W_per_m2K": s.h_out, "h_contact_W_per_m2K": s.h_in, "wall_share": s.share_wall,
           "time_s": hist.times.tolist(),
           "temperature_C": {n: _celsius(hist.x[:, i], a.ambient) for i, n in enumerate(thermal.NODES)},
           "hottest_powder_C": float(hist.x[:, 1].max()) + a.ambient,
           "end_C": dict(zip(thermal.NODES, _celsius(hist.x[-1], a.ambient))),
           "steady_continuous_C": dict(zip(thermal.NODES, _celsius(cont, a.ambient))),
           "periodic_peak_C": dict(zip(thermal.NODES, _celsius(per["end_of_run"], a.ambient))),
           "ledger_J": {"heat_in": hist.heat_in, "stored": hist.stored, "lost": hist.lost, "residual": hist.residual},
           "limit_C": a.limit, "limit_reached_s": crossing, "estimates": estimates, "notes": notes}
    if given:
        def draw(path):
            from taimill.figures.heat import heat_figure

            heat_figure(path, hist.times, out["temperature_C"], a.limit,
                        title=f"{a.run}: programme {a.programme}, ambient {a.ambient:g} °C")
        _draw(a, given, [*inputs, a.run], draw)
    for e in estimates:
        print(f"taimill: warning: {e}", file=sys.stderr)
    if crossing is not None:
        print(f"taimill: warning: the powder reaches the limit {a.limit:g} °C after {crossing / 60:.1f} min "
              f"of the programme", file=sys.stderr)
    if a.json:
        print(json.dumps(plain(out)))
        return 0
    print(f"{a.run}: heat over {a.hours:g} h, programme {a.programme}, ambient {a.ambient:g} °C")
    print(f"power: balls {q[0]:.3g} W, powder {q[1]:.3g} W, jar {q[2]:.3g} W while running; "
          f"h jar-air {s.h_out:.3g} W/(m² K) ({notes['h_conv_from']}), h balls-jar {s.h_in:.3g} W/(m² K) "
          f"({notes['h_contact_from']})")
    print(f"{'time (min)':>10}  {'balls °C':>9}  {'powder °C':>9}  {'jar °C':>8}")
    at = np.linspace(0.0, prog.total_s, 13)
    for when, x in zip(at, thermal.temperatures_at(net, q, prog, at)):
        t = x + a.ambient
        print(f"{when / 60:>10.1f}  {t[0]:>9.1f}  {t[1]:>9.1f}  {t[2]:>8.1f}")
    i = int(hist.x[:, 1].argmax())
    print(f"hottest powder: {hist.x[i, 1] + a.ambient:.1f} °C at {hist.times[i] / 60:.1f} min")
    print("steady state, running without pause: " + ", ".join(f"{k} {v:.1f} °C" for k, v in out["steady_continuous_C"].items()))
    if prog.pause_s > 0:
        print("periodic state, end of a run phase: " + ", ".join(f"{k} {v:.1f} °C" for k, v in out["periodic_peak_C"].items()))
    if a.limit is not None:
        print(f"powder limit {a.limit:g} °C: " + ("not reached" if crossing is None else f"reached after {crossing / 60:.1f} min"))
    print(f"energy: in {hist.heat_in:.4g} J = stored {hist.stored:.4g} J + lost {hist.lost:.4g} J "
          f"(gap {hist.residual:.1e})")
    if a.figure:
        print(f"wrote {a.figure}")
    return 0


def read_measured(path) -> list:
    """(time_s, °C, what) rows of a measured-temperature CSV; any slip is one line
    naming the file, line and column."""
    import csv
    import io

    from taimill.errors import ConfigError
    from taimill.model.files import read_text

    text = read_text(path, "command line", "--measured", "measured temperatures (CSV)")
    lines = list(csv.reader(io.StringIO(text)))
    numbered = [(i + 1, row) for i, row in enumerate(lines) if row and any(c.strip() for c in row)
                and not row[0].lstrip().startswith("#")]
    if not numbered:
        raise ConfigError(path, "header", "", "missing: the first line names the columns time_s|time_min|time_h, "
                          "temperature_C, what")
    n0, head = numbered[0]
    names = [h.strip() for h in head]
    times = [c for c in names if c in TIME_UNITS]
    for need, ok in (("time_s|time_min|time_h", len(times) == 1), ("temperature_C", "temperature_C" in names),
                     ("what", "what" in names)):
        if not ok:
            raise ConfigError(f"{path}: line {n0}", "header", ",".join(names),
                              f"needs one column {need} (the columns: time_s|time_min|time_h, temperature_C, what)")
    it, iT, iw = names.index(times[0]), names.index("temperature_C"), names.index("what")
    rows = []
    for n, row in numbered[1:]:
        where = f"{path}: line {n}"
        if len(row) != len(names):
            raise ConfigError(where, "line", ",".join(row), f"has {len(row)} fields; the header names {len(names)}")
        vals = []
        for i, lo, hi, text in ((it, 0, 1e7, "[0, 1e7]"), (iT, -100, 2000, "[-100, 2000] °C")):
            try:
                v = float(row[i])
            except ValueError:
                raise ConfigError(where, f"column {i + 1} ({names[i]})", row[i].strip(), "not a number") from None
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ConfigError(where, f"column {i + 1} ({names[i]})", row[i].strip(), f"allowed range {text}")
            vals.append(v)
        what = row[iw].strip()
        if what not in WHATS:
            raise ConfigError(where, f"column {iw + 1} (what)", what, "one of jar, ball, powder")
        rows.append((vals[0] * TIME_UNITS[times[0]], vals[1], what))
    if not rows:
        raise ConfigError(path, "rows", 0, "no measured temperatures below the header")
    return rows


def fit_coefficient(s, which: str, prog, rows, ambient: float, sigma: float) -> dict:
    """The coefficient `which` ("h-conv" or "h-contact") that brings the model nearest
    the measured rows (least squares in log h), with its 95 % interval: where χ² rises
    by 3.84 above its least (σ scaled up by the scatter when there are ≥ 3 rows)."""
    import dataclasses

    import numpy as np

    from taimill.outcome import thermal

    t = np.array([r[0] for r in rows])
    y = np.array([r[1] for r in rows]) - ambient
    node = np.array([WHATS[r[2]] for r in rows])
    field = "h_out" if which == "h-conv" else "h_in"

    def chi2(log_h):
        net, q = thermal.network(dataclasses.replace(s, **{field: math.exp(log_h)}))
        x = thermal.temperatures_at(net, q, prog, t)[np.arange(len(t)), node]
        return float(np.sum(((x - y) / sigma) ** 2))

    lo, hi = math.log(H_RANGE[0]), math.log(H_RANGE[1])
    grid = np.linspace(lo, hi, 81)
    vals = np.array([chi2(g) for g in grid])
    k = int(vals.argmin())
    a_, b_ = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    g = (math.sqrt(5) - 1) / 2
    for _ in range(80):  # golden section
        c, d = b_ - g * (b_ - a_), a_ + g * (b_ - a_)
        if chi2(c) < chi2(d):
            b_ = d
        else:
            a_ = c
    best = 0.5 * (a_ + b_)
    c2 = chi2(best)
    scale = max(1.0, c2 / (len(t) - 1)) if len(t) >= 3 else 1.0
    target = c2 + 3.84 * scale

    def edge(far):
        if chi2(far) <= target:
            return far, True
        inner, outer = best, far
        for _ in range(60):
            mid = 0.5 * (inner + outer)
            inner, outer = (mid, outer) if chi2(mid) <= target else (inner, mid)
        return 0.5 * (inner + outer), False

    (l, l_open), (u, u_open) = edge(lo), edge(hi)
    return {"parameter": which, "value": math.exp(best), "interval": [math.exp(l), math.exp(u)],
            "open_ends": [e for e, f in (("lower", l_open), ("upper", u_open)) if f],
            "chi2": c2, "points": len(t), "sigma_K": sigma * math.sqrt(scale)}


def cmd_fit(a) -> int:
    import dataclasses

    import numpy as np

    from taimill.cli.common import plain
    from taimill.model.files import reads
    from taimill.outcome import thermal

    _check("--sigma", a.sigma, 1e-3, 100, "[0.001, 100] K")
    with reads() as inputs:
        rows = read_measured(a.measured)
        total = max(r[0] for r in rows)
        prog = programme(a.programme, max(total, 1.0))
        s, notes, estimates = setup_of_run(a)
    given = _outputs(a, [*inputs, a.run, a.measured])
    res = fit_coefficient(s, a.fit, prog, rows, a.ambient, a.sigma)
    fitted = dataclasses.replace(s, **{("h_out" if a.fit == "h-conv" else "h_in"): res["value"]})
    net, q = thermal.network(fitted)
    t = np.array([r[0] for r in rows])
    model = thermal.temperatures_at(net, q, prog, t)
    res["residuals_K"] = [float(r[1] - a.ambient - model[i, WHATS[r[2]]]) for i, r in enumerate(rows)]
    if given:
        def draw(path):
            from taimill.figures.heat import heat_figure

            hist = thermal.simulate(net, q, prog)
            heat_figure(path, hist.times, {n: _celsius(hist.x[:, i], a.ambient) for i, n in enumerate(thermal.NODES)},
                        measured=rows, title=f"{a.run}: {a.fit} fitted to {a.measured}")
        _draw(a, given, [*inputs, a.run, a.measured], draw)
    for e in estimates:
        print(f"taimill: warning: {e}", file=sys.stderr)
    if a.json:
        print(json.dumps(plain({"run": a.run, "measured": a.measured, **res, "estimates": estimates, "notes": notes})))
        return 0
    lo, hi = res["interval"]
    opened = res["open_ends"]
    print(f"{a.fit} fitted to {res['points']} measured temperatures of {a.measured} (σ {res['sigma_K']:.3g} K)")
    print(f"{a.fit} = {res['value']:.4g} W/(m² K), 95 % interval [{'…' if 'lower' in opened else ''}{lo:.4g}, "
          f"{hi:.4g}{'…' if 'upper' in opened else ''}]")
    print(f"χ² = {res['chi2']:.4g}; residuals (K): " + ", ".join(f"{r:+.2f}" for r in res["residuals_K"]))
    if a.figure:
        print(f"wrote {a.figure}")
    return 0
