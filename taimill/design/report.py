"""A design study's results: the best designs (one objective) or the Pareto set
(several) as jar files ready to run, the reference jars at their best K, a JSON and a
markdown summary, and the report page (PNG): the profiles side by side, the objective
history and the Pareto front (or, for one objective, the objective against K).

Every figure is the mean over the replicas ± the replicas' sample standard deviation.
A design "beats" a reference when its band lies wholly beyond the reference's:
|mean_d − mean_r| > s_d + s_r in the objective's direction. One replica has no spread:
its figures read "± ?" and nothing is compared (`comparable`), since a spread taken as 0
would let any difference count."""

from __future__ import annotations

import json
import math
from pathlib import Path

from taimill.design import families

MM = 1e3
UNKNOWN = "unknown: one replica per design; 2 or more --replicas are needed to compare designs and references"


def spread(fig) -> float | None:
    """A figure's spread, None where fewer than two replicas give it (a study stored
    before one replica's spread was None has 0 there)."""
    _, s, values = fig
    return s if s is not None and sum(map(math.isfinite, values)) >= 2 else None


def known(figs: dict) -> dict:
    """{key: [mean, spread or None, values]}: `spread` for every figure."""
    return {k: [f[0], spread(f), f[2]] for k, f in figs.items()}


def comparable(study) -> bool:
    """Designs and references are compared only with a spread: two replicas or more."""
    return study.s.replicas >= 2


def trial_rows(study) -> list[dict]:
    """The evaluated trials: number, params, K, figures {key: [mean, s, values]}, feasible, state."""
    from taimill.design.study import feasible

    rows = []
    for t in study.evaluated():
        design, ratio = study.design_of(t.params)
        rows.append({"trial": t.number, "params": design, "ratio": ratio, "figures": known(t.user_attrs["figures"]),
                     "feasible": feasible(t) and t.state.name == "COMPLETE", "state": t.state.name,
                     "jar": str(study.jar_path(t.number))})
    return rows


def pareto(rows: list[dict], objectives) -> list[dict]:
    """The feasible rows no other feasible row dominates (on the objectives' means)."""
    ok = [r for r in rows if r["feasible"]]

    def key(r):
        return [r["figures"][o.key][0] * (1 if o.direction == "maximize" else -1) for o in objectives]

    front = []
    for r in ok:
        a = key(r)
        if not any(all(x >= y for x, y in zip(key(q), a)) and key(q) != a for q in ok):
            front.append(r)
    return sorted(front, key=lambda r: -key(r)[0])


def best_references(references: dict, objective) -> dict:
    """{name: {"ratio": K, "figures": …}} at each reference's best K for `objective`."""
    out = {}
    for name, by_k in references.items():
        k = max(by_k, key=lambda k: by_k[k][objective.key][0] * (1 if objective.direction == "maximize" else -1)
                if math.isfinite(by_k[k][objective.key][0]) else -math.inf)
        out[name] = {"ratio": float(k), "figures": known(by_k[k])}
    return out


def beats(design: dict, ref: dict, objective) -> tuple[bool, float]:
    """(whether the design's band lies beyond the reference's, the margin in units of s_d + s_r).
    Only for figures with a spread (`comparable`)."""
    d, r = design["figures"][objective.key], ref["figures"][objective.key]
    sd, sr = spread(d), spread(r)
    if sd is None or sr is None:
        raise ValueError("beats: a figure without a spread (one replica) is compared with nothing")
    diff = (d[0] - r[0]) * (1 if objective.direction == "maximize" else -1)
    band = sd + sr
    return bool(diff > band), diff / band if band > 0 else math.inf


def results(study, references: dict, keep: int = 3) -> dict:
    """The study's outcome as a JSON-ready dict (also what summary.json holds)."""
    objs = study.s.objectives
    rows = trial_rows(study)
    if len(objs) == 1:
        o = objs[0]
        ok = sorted((r for r in rows if r["feasible"]), key=lambda r: r["figures"][o.key][0],
                    reverse=o.direction == "maximize")
        best = ok[:keep]
    else:
        best = pareto(rows, objs)
    refs = best_references(references, objs[0]) if references else {}
    comparison = {}
    if best and refs and comparable(study):
        comparison = {n: dict(zip(("beats", "margin"), beats(best[0], r, objs[0]))) for n, r in refs.items()}
    pruned = [t for t in study.study.get_trials(deepcopy=False) if t.user_attrs.get("violations")]
    return {"objectives": [o.label for o in objs], "floors": study.s.floors, "family": study.s.family,
            "spread": "sample standard deviation of the replicas (ddof 1)" if comparable(study) else UNKNOWN,
            "settings": study.s.identity(), "evaluated": len(rows), "pruned": len(pruned),
            "runs": len(rows) * study.s.replicas + sum(len(v) for v in references.values()) * study.s.replicas,
            "searched": sorted(study.distributions()), "best": best, "references": refs,
            "reference_grid": {n: {k: known(f) for k, f in by_k.items()} for n, by_k in references.items()},
            "comparison": comparison,
            "history": [{"trial": r["trial"], "ratio": r["ratio"], "feasible": r["feasible"],
                         **{o.key: r["figures"][o.key][0] for o in objs}} for r in rows]}


def write_best(study, res: dict) -> list[Path]:
    """The best designs (or the Pareto set) as jar files in best/, with a comment block:
    study, parameters, K, objective values ± spread."""
    folder = study.out / "best"
    folder.mkdir(exist_ok=True)
    for old in folder.glob("*.toml"):
        old.unlink()
    paths = []
    for i, r in enumerate(res["best"], 1):
        figs = [f"{k} = {m:.5g} ± {s:.2g} {study_unit(k)} (mean ± sample s.d. of {len(v)} replicas)" if s is not None
                else f"{k} = {m:.5g} ± ? {study_unit(k)} (spread unknown: {len(v)} replica)"
                for k, (m, s, v) in r["figures"].items()]
        path = folder / f"design-{i}.toml"
        extra = [f"Run it (from the study folder {study.out.name}): {run_line(study, path, r['ratio'])}", *figs]
        path = study.write_jar(r["trial"], {**r["params"], "ratio": r["ratio"]}, extra, path)
        r["file"] = str(path)
        paths.append(path)
    return paths


# the study's run overrides as `taimill run` options; the duration and analysis window are
# the design's short runs' (a run of the design keeps the preset's), the bowl of
# jar_volume_ml is replaced by the designed jar, whose file has the wall material
RUN_OPTIONS = {"mill": "--mill", "plate_rpm": "--plate-rpm", "pair": "--pair", "balls.count": "--balls",
               "balls.material": "--ball-material", "balls.diameter_mm": "--ball-diameter",
               "powder.mass_g": "--powder-mass", "dt": "--dt", "law": "--law"}


def run_line(study, jar: Path, ratio: float) -> str:
    """`taimill run …` of a designed jar file, every path relative to the study folder (the
    line is pasted there: `cd STUDY` first), K only where the mill's gear is not fixed."""
    import os
    import shlex

    def rel(path) -> str:
        try:
            return os.path.relpath(Path(path).resolve(), study.out.resolve())
        except ValueError:  # another drive (Windows): no relative path
            return str(Path(path).resolve())

    preset = preset_text(study.s.preset)
    words = ["taimill", "run", rel(preset) if preset.endswith(".toml") else preset, "--jar", rel(jar)]
    for key, option in RUN_OPTIONS.items():
        v = study.s.overrides.get(key)
        if v is None:
            continue
        if key == "mill" and str(v).endswith(".toml"):
            v = rel(v)
        words += [option, f"{v:.6g}" if isinstance(v, float) else str(v)]
    if not study.protocol.fixed_gear:
        words.append(f"--ratio={ratio:.6g}")  # the = form: a negative K is the option's value
    return shlex.join(words)


def preset_text(preset: str) -> str:
    """A bundled preset by its name (p4-cy-steel), any other as given."""
    from taimill.model import files

    p = Path(preset)
    bundled = files.BUNDLED["preset"][0] / p.name
    return p.stem if p.suffix == ".toml" and bundled.exists() and bundled.resolve() == p.resolve() else preset


def study_unit(key: str) -> str:
    from taimill.schema import SUMMARY_UNITS

    return SUMMARY_UNITS.get(key.rpartition(".")[2], "")


def _fmt(fig) -> str:
    m, s, _ = fig
    return f"{m:.4g} ± {s:.2g}" if s is not None else f"{m:.4g} ± ?"


def write_markdown(res: dict, path: Path) -> None:
    objs = res["objectives"]
    keys = [o.rpartition(":")[0] for o in objs]
    lines = [f"# Jar design study: {', '.join(objs)}", "",
             f"Family `{res['family']}`; {res['evaluated']} designs evaluated, {res['pruned']} pruned by the "
             f"constraints before any run; {res['runs']} short runs. "
             + (f"Figures: mean ± {res['spread']}." if res["spread"] != UNKNOWN else
                "Figures: the one replica's value ± ? (spread unknown: 1 replica)."), ""]
    if res["floors"]:
        lines += ["Floors: " + ", ".join(f"{k} ≥ {v:g}" for k, v in res["floors"].items()), ""]
    lines += ["| design | K | " + " | ".join(keys) + " | jar file |", "|---|---|" + "---|" * len(keys) + "---|"]
    for i, r in enumerate(res["best"], 1):
        lines.append(f"| design {i} (trial {r['trial']}): {families.describe(r['params'])} | {r['ratio']:.3g} | "
                     + " | ".join(_fmt(r["figures"][k]) for k in keys) + f" | {Path(r.get('file', r['jar'])).name} |")
    for name, ref in res["references"].items():
        lines.append(f"| reference {name} | {ref['ratio']:.3g} | " + " | ".join(_fmt(ref["figures"][k]) for k in keys)
                     + " | (bundled) |")
    if res["spread"] == UNKNOWN:
        lines += ["", ("Spread unknown (1 replica): no design is compared with a reference or said to beat one; "
                       "run 2 or more --replicas to compare.")]
    if res["comparison"]:
        lines += ["", f"Design 1 against each reference on {objs[0]} (beats: the bands mean ± s do not overlap):", ""]
        ks = sorted({float(k) for by_k in res["reference_grid"].values() for k in by_k})
        if len(ks) > 1 and "ratio" in res.get("searched", ()):
            lines += [f"(The references run at K = {', '.join(f'{k:g}' for k in ks)}, each taken at its best; the designs' K "
                      "is searched continuously, and a reference may do better between those values.)", ""]
        lines += [f"- {n}: {'beats' if c['beats'] else 'does not beat'} it, margin {c['margin']:.2f} × (s_d + s_r)"
                  for n, c in res["comparison"].items()]
    if res.get("confirmation"):
        c = res["confirmation"]
        lines += ["", f"Confirmation ({c['duration']:g} s runs, analysis from {c['analysis_start']:g} s, "
                  f"{c['replicas']} replicas):", ""]
        lines += [f"- {n} at K {v['ratio']:.3g}: " + ", ".join(f"{k} {_fmt(f)}" for k, f in v["figures"].items())
                  + ("" if n not in c["comparison"] else
                     f"; design 1 {'beats' if c['comparison'][n]['beats'] else 'does not beat'} it, "
                     f"margin {c['comparison'][n]['margin']:.2f} × (s_d + s_r)")
                  for n, v in c["jars"].items()]
    path.write_text("\n".join(lines) + "\n")


def draw(study, res: dict, path: Path) -> Path:
    """The report page (taimill.figures.design) of the best designs and the references."""
    from taimill.figures.design import draw_report
    from taimill.model.jars import load_jar

    outlines = {}
    for r in res["best"][:5]:
        outlines[f"design {res['best'].index(r) + 1}"] = load_jar(r.get("file", r["jar"]), "design").profile.outline * MM
    for name in res["references"]:
        outlines[name] = load_jar(name, "design").profile.outline * MM
    return draw_report(res, outlines, study.limits.radius * MM, path)


def write_all(study, res: dict) -> dict:
    """best/*.toml, summary.json, summary.md and report.png in the study folder, each
    whole or not at all (an interrupt or a full disk leaves the file as it was)."""
    from taimill.store.output import whole_file

    write_best(study, res)
    with whole_file(study.out / "summary.json", "summary") as part:
        part.write_text(json.dumps(res, indent=1, default=float))
    with whole_file(study.out / "summary.md", "summary") as part:
        write_markdown(res, part)
    with whole_file(study.out / "report.png", "report page") as part:
        draw(study, res, part)
    return res
