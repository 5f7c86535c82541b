"""Acceptance comparison of taimill with LIGGGHTS-PUBLIC 3.8 on one case, both analysed
by taimill (docs/liggghts.md):

    CY jar, 12 steel balls of 6 mm, Ω = 200 rpm, K = -2.2, constant restitution
    e = 0.516 (law hertz-mindlin), μ = 0.8 (μ_s = μ_d), the same start positions,
    5 s simulated, the analysis window 2-5 s.

Steps: the preset is written to OUT/accept.toml; taimill runs it (OUT/taimill.zarr);
`taimill export liggghts` writes OUT/case and LIGGGHTS runs it there (`nice`, serial,
~10 min per 5 s on a free core; skipped when its dumps are complete); `taimill import
liggghts` reads them back (OUT/liggghts.zarr). LIGGGHTS writes no collision events, so
the imported run's events are reconstructed from its frames; the same reconstruction
is applied to taimill's frames (OUT/taimill-reconstructed.zarr) for a like-for-like
comparison beside the one with taimill's exact events. Both comparisons and the
verdict (mean SE within 15 %, 1/σ within 10 %) go to results/liggghts_comparison.md.

`--friction` selects the friction models (FRICTIONS): `coulomb` (the default, above:
taimill's regularised Coulomb friction against LIGGGHTS' tangential spring) or the same
sub-models in both codes, `history` (tangential = "history", LIGGGHTS `tangential
history` without tangential damping) and `history-epsd2` (also rolling = "epsd2",
μ_r = 0.05 on both contact kinds). These like-for-like cases are held to ±10 % on
mean SE, stress-event rate and 1/σ (like-for-like event reconstruction) and write their
own section of the results file, replacing an earlier one of the same case.

    python scripts/liggghts_compare.py [--out runs/liggghts-compare] [--np 1] [--friction history]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

PRESET = """\
# acceptance comparison with LIGGGHTS (scripts/liggghts_compare.py): CY jar, 12 steel
# balls, 200 rpm, K = {ratio}, constant restitution e = 0.516 (hertz-mindlin), mu = 0.8
jar = "CY"
pair = "steel-steel"
law = "hertz-mindlin"
plate_rpm = 200
ratio = {ratio}
duration = {duration}
analysis_start = {start}
seed = {seed}

[balls]
count = 12
material = "steel-c1020"
radius_mm = 6

[friction]
mu_s = 0.8
mu_d = 0.8
{friction}
[outputs]
trajectory_rate = {rate}
"""
MEAN_SE_TOLERANCE, RANDOMNESS_TOLERANCE = 0.15, 0.10
# --friction: the [friction] keys each case adds, and its description. `history` and
# `history-epsd2` run the same friction sub-models in both codes, so the comparison
# tests the rest of the model (and the statistics) alone.
FRICTIONS = {
    "coulomb": ("", "μ = 0.8 (μ_s = μ_d), taimill's regularised Coulomb friction"),
    "history": ('tangential = "history"\n', "tangential = history (μ_d = 0.8) in both codes"),
    "history-epsd2": ('tangential = "history"\nrolling = "epsd2"\nmu_r = 0.05\n',
                      "tangential = history (μ_d = 0.8) and rolling = epsd2 (μ_r = 0.05, ball-ball and ball-wall) "
                      "in both codes"),
}
# the like-for-like cases: each headline figure within ±10 %
SAME_MODEL_TOLERANCE = 0.10
SAME_MODEL_KEYS = ("mean_se", "collision_rate", "randomness_index")


def run_taimill(preset, out: Path) -> float:
    from taimill.runs.simulation import run
    from taimill.store.writer import ZarrSink

    t0 = time.perf_counter()
    run(preset, ZarrSink(out))
    return time.perf_counter() - t0


def run_liggghts(case: Path, processes: int, liggghts: str) -> tuple[float, float]:
    """(wall time, CPU time) in s: on a shared machine the CPU time is the fair cost."""
    cmd = [liggghts, "-in", "in.taimill", "-log", "log.liggghts"]
    if processes > 1:
        cmd = ["mpirun", "--allow-run-as-root", "-np", str(processes), *cmd]
    t0, c0 = time.perf_counter(), _children_cpu()
    with open(case / "screen.txt", "w") as screen:
        subprocess.run(["nice", "-n", "5", *cmd], cwd=case, stdout=screen, stderr=subprocess.STDOUT, check=True)
    return time.perf_counter() - t0, _children_cpu() - c0


def _children_cpu() -> float:
    import resource

    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime


def dumps_complete(case: Path) -> bool:
    from taimill.bridge.dumps import read_manifest

    dump = case / "dumps" / "balls.dump"
    if not dump.exists():
        return False
    last = subprocess.run(["grep", "-A1", "ITEM: TIMESTEP", str(dump)], capture_output=True, text=True).stdout.split()
    return bool(last) and int(last[-1]) == read_manifest(case)["steps"]


def reconstructed_copy(src: Path, out: Path) -> None:
    """A copy of a taimill store whose events are reconstructed from its frames, as an
    imported LIGGGHTS run's are (like-for-like comparison)."""
    import zarr

    from taimill.bridge.dumps import EVENTS_SOURCE, events_from_store
    from taimill.store.run import open_run

    run = open_run(src)
    events = events_from_store(run)
    if out.exists():
        shutil.rmtree(out)
    shutil.copytree(src, out)
    g = zarr.open_group(out, mode="r+")
    ev = g["events"]
    for k, v in events.items():
        ev[k].resize((len(v),))
        ev[k][:] = v
    ev.attrs["n_valid"] = len(events["t_start"])
    g.attrs["events_source"] = EVENTS_SOURCE
    # the store's check holds the summary's event count to the committed rows
    g.attrs.update({"summary": {**run.summary, "events_total": len(events["t_start"]),
                                "note": "events replaced by the reconstruction from frames"}})


def table(result: dict, a: str, b: str) -> list[str]:
    lines = [f"| quantity | {a} | {b} | (B − A)/\\|A\\| |", "|---|---:|---:|---:|"]
    for r in result["rows"]:
        unit = f" ({r['unit']})" if r["unit"] else ""
        if r["scale"] is None:
            lines.append(f"| {r['label'].strip()}{unit} | {r['a']} | {r['b']} | {'same' if r['a'] == r['b'] else 'differs'} |")
            continue
        fa = "–" if not _finite(r["a"]) else f"{r['a'] * r['scale']:.4g}"
        fb = "–" if not _finite(r["b"]) else f"{r['b'] * r['scale']:.4g}"
        rel = "–" if not _finite(r["relative_difference"]) else f"{r['relative_difference']:+.1%}"
        lines.append(f"| {r['label'].strip()}{unit} | {fa} | {fb} | {rel} |")
    return lines


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def verdict(result: dict) -> tuple[bool, str]:
    rows = {r["key"]: r for r in result["rows"]}
    se, ri = rows["mean_se"]["relative_difference"], rows["randomness_index"]["relative_difference"]
    ok = _finite(se) and _finite(ri) and abs(se) <= MEAN_SE_TOLERANCE and abs(ri) <= RANDOMNESS_TOLERANCE
    return ok, (f"mean SE {se:+.1%} (limit ±{MEAN_SE_TOLERANCE:.0%}), 1/σ {ri:+.1%} "
                f"(limit ±{RANDOMNESS_TOLERANCE:.0%}): {'AGREE' if ok else 'DO NOT AGREE'}")


def same_model_verdict(result: dict) -> tuple[bool, str]:
    """±10 % on mean SE, stress-event rate and 1/σ (the like-for-like cases)."""
    rows = {r["key"]: r for r in result["rows"]}
    parts, ok = [], True
    for key in SAME_MODEL_KEYS:
        d = rows[key]["relative_difference"]
        ok = ok and _finite(d) and abs(d) <= SAME_MODEL_TOLERANCE
        parts.append(f"{rows[key]['label'].strip()} {d:+.1%}")
    return ok, ", ".join(parts) + f" (limit ±{SAME_MODEL_TOLERANCE:.0%}): {'AGREE' if ok else 'DO NOT AGREE'}"


def replace_section(path: Path, name: str, lines: list[str]) -> None:
    """Put `lines` between this case's markers in the results file (replacing an
    earlier section of the case, else appended), leaving the rest as it is."""
    begin, end = f"<!-- liggghts_compare --friction {name} -->", f"<!-- end --friction {name} -->"
    text = path.read_text() if path.exists() else ""
    block = "\n".join([begin, *lines, end])
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        text = head + block + rest.split(end, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(text)


def same_model_section(a, exact: dict, alike: dict, manifest: dict, times: dict) -> int:
    """The results file's section of a like-for-like friction case; 0 when it agrees."""
    ok_exact, text_exact = same_model_verdict(exact)
    ok_alike, text_alike = same_model_verdict(alike)
    lines = [
        f"## Identical friction models: {FRICTIONS[a.friction][1]}",
        "",
        f"The case above (CY, 12 steel balls of 6 mm, Ω = 200 rpm, K = {a.ratio:g}, hertz-mindlin e = 0.516, seed "
        f"{a.seed}, {a.duration:g} s, window {a.start:g}–{a.duration:g} s, {a.rate:g} frames/dumps per s, "
        f"dt = {manifest['dt'] * 1e6:.4g} µs) with `[friction] "
        + FRICTIONS[a.friction][0].strip().replace("\n", "; ") + "`, so that both codes run the same friction "
        f"sub-models. Command: `python scripts/liggghts_compare.py --friction {a.friction}"
        + (f" --seed {a.seed}" if a.seed != 1 else "") + "`. Acceptance: mean SE, "
        f"stress-event rate and 1/σ within ±{SAME_MODEL_TOLERANCE:.0%}, judged like for like (table b).",
        "",
        "### a. taimill (exact events) vs LIGGGHTS (reconstructed events)",
        "",
        *table(exact, "taimill", "LIGGGHTS"),
        "",
        f"**{text_exact}** (for information, not the acceptance: the reconstruction from dumps counts fewer, "
        "more energetic events than an engine's exact table, see table b and the discussion of the first case)",
        "",
        "### b. both with events reconstructed from frames (like for like)",
        "",
        *table(alike, "taimill", "LIGGGHTS"),
        "",
        f"**{text_alike}**",
        "",
        "### The mapping used",
        "",
        *(f"- {n}" for n in manifest["mapping"]["notes"]),
        *(f"- approximated: {w}" for w in manifest["mapping"]["warnings"]),
        "",
    ]
    if times:
        lines += ["Run times: " + ", ".join(f"{k} {v:.0f} s" for k, v in times.items()) + ".", ""]
    replace_section(Path(a.results), a.friction, lines)
    print("\n".join(lines))
    return 0 if ok_alike else 1


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=None, help="default runs/liggghts-compare[-FRICTION]")
    p.add_argument("--ratio", type=float, default=-2.2)
    p.add_argument("--duration", type=float, default=5.0)
    p.add_argument("--start", type=float, default=2.0)
    p.add_argument("--rate", type=float, default=5000.0, help="frames and dumps per s (events are reconstructed from them)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--np", type=int, default=1, help="MPI processes for LIGGGHTS")
    p.add_argument("--liggghts", default="liggghts")
    p.add_argument("--results", default=str(ROOT / "results" / "liggghts_comparison.md"))
    p.add_argument("--friction", choices=tuple(FRICTIONS), default="coulomb",
                   help="friction models: coulomb (taimill's own), or history / history-epsd2 in both codes")
    a = p.parse_args(argv)
    if a.out is None:
        a.out = str(ROOT / "runs" / ("liggghts-compare" + ("" if a.friction == "coulomb" else f"-{a.friction}")))

    from taimill.analysis.compare import compare
    from taimill.bridge.dumps import import_case
    from taimill.bridge.liggghts import export_case
    from taimill.model.preset import load_preset

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "accept.toml").write_text(PRESET.format(ratio=a.ratio, duration=a.duration, start=a.start, seed=a.seed,
                                                   rate=a.rate, friction=FRICTIONS[a.friction][0]))
    preset = load_preset(out / "accept.toml")
    # wall times of the runs made, kept beside them (a re-analysis runs nothing)
    times_file = out / "times.json"
    times = json.loads(times_file.read_text()) if times_file.exists() else {}
    if not (out / "taimill.zarr").exists():
        times["taimill"] = run_taimill(preset, out / "taimill.zarr")
        times_file.write_text(json.dumps(times))
    case = out / "case"
    if not dumps_complete(case):
        if case.exists():
            shutil.rmtree(case)
        export = export_case(preset, case, liggghts=a.liggghts)
        print(export.describe())
        times["liggghts"], times["liggghts CPU"] = run_liggghts(case, a.np, a.liggghts)
        times_file.write_text(json.dumps(times))
    import_case(case, out / "liggghts.zarr")
    reconstructed_copy(out / "taimill.zarr", out / "taimill-reconstructed.zarr")
    exact = compare(out / "taimill.zarr", out / "liggghts.zarr")
    alike = compare(out / "taimill-reconstructed.zarr", out / "liggghts.zarr")
    ok_exact, text_exact = verdict(exact)
    ok_alike, text_alike = verdict(alike)
    manifest = json.loads((case / "taimill-case.json").read_text())
    if a.friction != "coulomb":
        return same_model_section(a, exact, alike, manifest, times)
    lines = [
        "# taimill against LIGGGHTS-PUBLIC 3.8.0",
        "",
        f"CY jar, 12 steel balls (6 mm), Ω = 200 rpm, K = {a.ratio:g}, law hertz-mindlin (constant restitution "
        f"e = 0.516), μ = 0.8 (μ_s = μ_d), seed {a.seed}: the same start positions in both codes; "
        f"{a.duration:g} s simulated, analysis window {a.start:g}–{a.duration:g} s; frames (taimill) and dumps "
        f"(LIGGGHTS) at {a.rate:g} /s; dt = {manifest['dt'] * 1e6:.4g} µs in both. Both analysed by taimill "
        "(`taimill compare`).",
        "",
        "Command: `python scripts/liggghts_compare.py" + (f" --np {a.np}" if a.np > 1 else "") + "` "
        "(writes runs/liggghts-compare/ and this file).",
        "",
        "LIGGGHTS writes no collision events: the imported run's events are reconstructed from its dumps "
        "(docs/liggghts.md). Table 1 sets them against taimill's exact events; table 2 against the same "
        "reconstruction applied to taimill's own frames, like for like.",
        "",
        "## 1. taimill (exact events) vs LIGGGHTS (reconstructed events)",
        "",
        *table(exact, "taimill", "LIGGGHTS"),
        "",
        f"**{text_exact}**",
        "",
        "## 2. taimill vs LIGGGHTS, both with events reconstructed from frames",
        "",
        *table(alike, "taimill", "LIGGGHTS"),
        "",
        f"**{text_alike}**",
        "",
        "## The mapping used",
        "",
        *(f"- {n}" for n in manifest["mapping"]["notes"]),
        *(f"- approximated: {w}" for w in manifest["mapping"]["warnings"]),
        f"- jar mesh: {manifest['jar_mesh']['side_facets']} side facets, wall within "
        f"{manifest['jar_mesh']['deviation'] * 1e6:.2f} µm of the profile",
        "",
    ]
    if times:
        lines += ["Wall time of this run: " + ", ".join(f"{k} {v:.0f} s" for k, v in times.items()) + ".", ""]
    results = Path(a.results)
    kept = results.read_text().partition("\n## Discussion")[2] if results.exists() else ""
    if kept:  # a discussion written by hand below the generated part stays
        lines += ["## Discussion" + kept.rstrip("\n"), ""]
    results.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0 if ok_alike else 1


if __name__ == "__main__":
    sys.exit(main())
