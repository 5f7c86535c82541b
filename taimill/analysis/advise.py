"""The answer of `taimill advise` from its sweep's rows (plain dicts, one per point ×
replica, as `taimill.runs.sweep.run_sweep` returns them): one row per plate speed with
its dissipated power (per gram of powder where the run has a powder mass), regime
classes and power-led verdict across the friction levels μ, impact power, and whether
the answer there hinges on μ (`hinges`); then the speed with the highest value of the
user's measure at each μ (`recommendation`). NumPy-free, no I/O.

Rows are grouped by `plate_rpm` and by the ball-ball `mu_d` (the level a sweep's
`friction.mu` set; a measured pair's own μ_d where μ is not varied)."""

from __future__ import annotations

import math

# The measures a recommendation may follow: key -> (what it is, unit, scale to the unit).
# Each is better when higher. Impact power is a choice, never the default: a
# friction-led charge takes its power by friction, not impacts
# (taimill.analysis.summary.power_lead).
MEASURES = {
    "dissipated_power": ("dissipated power", "W", 1.0),
    "specific_power_W_per_g": ("dissipated power per gram of powder", "W/g", 1.0),
    "impact_power": ("impact power (kinematic stress energy)", "W", 1.0),
    "mean_se": ("mean stress energy", "mJ", 1e3),
    "mean_se_normal": ("mean normal stress energy", "mJ", 1e3),
    "collision_rate": ("stress-event rate", "1/s", 1.0),
}
# The dissipated power across μ (mean of the replicas at each μ) spreading by more than
# this factor (largest over smallest) makes the answer hinge on μ.
SPREAD_FACTOR = 1.5


def default_measure(per_gram: bool) -> str:
    """The measure when none is chosen: the dissipated power, per gram of powder when
    the run has a powder mass (what the charge takes, however it takes it)."""
    return "specific_power_W_per_g" if per_gram else "dissipated_power"


def number(v) -> float:
    """A row's value as a float; NaN for a missing, non-numeric or non-finite one."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return math.nan
    return float(v) if math.isfinite(v) else math.nan


def text(v) -> str | None:
    """A row's label, or None for a missing one (a store keeps "" or NaN)."""
    return v if isinstance(v, str) and v else None


def _stats(values) -> dict:
    """{mean, min, max} of the finite values (NaN when there are none)."""
    v = [x for x in values if math.isfinite(x)]
    if not v:
        return {"mean": math.nan, "min": math.nan, "max": math.nan}
    return {"mean": sum(v) / len(v), "min": min(v), "max": max(v)}


def _counted(labels) -> list[str]:
    """The distinct labels, the most frequent first (ties in order of appearance)."""
    labels = [x for x in labels if x]
    return sorted(dict.fromkeys(labels), key=lambda x: -labels.count(x))


def speed_rows(rows: list[dict], measure: str, power: str = "dissipated_power") -> list[dict]:
    """One row per plate speed (ascending |Ω|): `plate_rpm`; `power` (the key shown:
    dissipated_power, or specific_power_W_per_g with a powder mass) with `power_mean`,
    `power_min`, `power_max` over every replica and μ; `impact_power_mean/min/max`;
    `by_mu`, per μ (ascending): `mu`, `replicas`, `regime_classes` and `power_led`
    (distinct labels, the most frequent first), power_*, impact_power_*, measure_*;
    `classes_across_mu` and `power_led_across_mu` (the labels as text, across_mu); `hinges_why` (hinges)
    and `hinges_on_mu`; `measure`; `best_at_mu` (filled by with_best)."""
    speeds: dict = {}
    for r in rows:
        rpm = round(number(r.get("plate_rpm")), 9)
        mu = round(number(r.get("mu_d", r.get("mu"))), 10)
        speeds.setdefault(rpm, {}).setdefault(mu, []).append(r)
    out = []
    for rpm in sorted(speeds, key=lambda s: (abs(s), s)):
        by_mu = []
        for mu in sorted(speeds[rpm]):
            rs = speeds[rpm][mu]
            one = {"mu": mu, "replicas": len(rs),
                   "regime_classes": _counted(text(r.get("regime_class")) or "unknown" for r in rs),
                   "power_led": _counted(text(r.get("power_led")) for r in rs)}
            for key, name in ((power, "power"), ("impact_power", "impact_power"), (measure, "measure")):
                one |= {f"{name}_{k}": v for k, v in _stats(number(r.get(key)) for r in rs).items()}
            by_mu.append(one)
        every = [r for rs in speeds[rpm].values() for r in rs]
        row = {"plate_rpm": rpm, "power": power, "measure": measure}
        for key, name in ((power, "power"), ("impact_power", "impact_power")):
            row |= {f"{name}_{k}": v for k, v in _stats(number(r.get(key)) for r in every).items()}
        row |= {"classes_across_mu": across_mu(by_mu, "regime_classes"), "power_led_across_mu": across_mu(by_mu, "power_led"),
                "by_mu": by_mu}
        why = hinges(by_mu)
        out.append(row | {"hinges_on_mu": bool(why), "hinges_why": why, "best_at_mu": []})
    return out


def across_mu(by_mu: list[dict], key: str) -> str:
    """The labels of `key` across μ as text: "hopping bed" where every μ gives it,
    "sliding bed (μ 0.1, 0.2) → hopping bed (μ 0.8)" where it changes; replicas of one μ
    in different states are joined by " / "; "-" for no label at all."""
    runs: list[list] = []
    for m in by_mu:
        label = " / ".join(m[key]) or "-"
        if runs and runs[-1][0] == label:
            runs[-1][1].append(m["mu"])
        else:
            runs.append([label, [m["mu"]]])
    if len(runs) == 1:
        return runs[0][0]
    return " → ".join(f"{label} (μ {', '.join(f'{mu:g}' for mu in mus)})" for label, mus in runs)


def hinges(by_mu: list[dict]) -> list[str]:
    """Why the answer at one plate speed hinges on μ (empty: it does not): "class" where
    the regime classes differ between two μ (the set its replicas ended in: a μ whose
    replicas disagree differs from one whose replicas agree), "power-led verdict" where
    the power-led labels do (a μ without dissipation has none and is left out),
    "power ×F" where the μ levels' mean dissipated power spreads by more than
    SPREAD_FACTOR (largest over smallest; "power 0 to X" where one level dissipates
    nothing). One μ: never."""
    if len(by_mu) < 2:
        return []
    why = []
    if len({frozenset(m["regime_classes"]) for m in by_mu}) > 1:
        why.append("class")
    leads = {frozenset(m["power_led"]) for m in by_mu if m["power_led"]}
    if len(leads) > 1:
        why.append("power-led verdict")
    means = [m["power_mean"] for m in by_mu if math.isfinite(m["power_mean"])]
    if len(means) > 1 and max(means) > 0:
        lo, hi = min(means), max(means)
        if lo <= 0:
            why.append(f"power 0 to {hi:.3g}")
        elif hi / lo > SPREAD_FACTOR:
            why.append(f"power ×{hi / lo:.3g}")
    return why


def best_speeds(rows: list[dict]) -> dict[float, dict | None]:
    """Per μ (every μ of the speed rows): the plate speed with the highest replica mean of
    the measure, as {plate_rpm, mean, min, max, runner_up} (runner_up: the next speed's
    {plate_rpm, mean, min, max}, or None), or None where no speed has a positive value
    (nothing to maximise: no stress events, or none with energy)."""
    levels = sorted({m["mu"] for r in rows for m in r["by_mu"]})
    out: dict = {}
    for mu in levels:
        cands = [{"plate_rpm": r["plate_rpm"], **{k: m[f"measure_{k}"] for k in ("mean", "min", "max")}}
                 for r in rows for m in r["by_mu"] if m["mu"] == mu and math.isfinite(m["measure_mean"])]
        cands.sort(key=lambda c: -c["mean"])
        out[mu] = None if not cands or cands[0]["mean"] <= 0 else cands[0] | {"runner_up": (cands[1:] or [None])[0]}
    return out


def with_best(rows: list[dict]) -> list[dict]:
    """The speed rows with `best_at_mu`: the μ levels at which each speed is best_speeds'."""
    best = best_speeds(rows)
    return [r | {"best_at_mu": [mu for mu, b in best.items() if b and b["plate_rpm"] == r["plate_rpm"]]} for r in rows]


def _mus(mus) -> str:
    return ", ".join(f"{m:g}" for m in mus)


def recommendation(rows: list[dict], measure: str) -> str:
    """The closing line: the speed with the highest replica mean of `measure` at every μ
    ("highest dissipated power at 650 rpm in every μ tried (0.1, 0.2, 0.8)"), or, where
    μ moves it, the best speed at each μ and the speed that stays closest to every μ's
    best ("the best speed depends on μ: 300 rpm at μ 0.1; 650 rpm at μ 0.2, 0.8; …").
    Added where they apply: μ levels with nothing to maximise, a runner-up within the
    replicas' spread of the best, and that the chosen speed's row hinges on μ."""
    what = MEASURES.get(measure, (measure, "", 1.0))[0]
    best = best_speeds(rows)
    found = {mu: b for mu, b in best.items() if b}
    empty = [mu for mu, b in best.items() if not b]
    if not found:
        return f"no speed gives any {what} at any μ tried ({_mus(best)}): nothing to recommend by this measure"
    by_speed: dict = {}
    for mu, b in found.items():
        by_speed.setdefault(b["plate_rpm"], []).append(mu)
    if len(by_speed) == 1:
        (speed, mus), = by_speed.items()
        where = (f"at μ {_mus(mus)}" if len(best) == 1 else
                 f"in every μ tried ({_mus(mus)})" if not empty else f"at every μ that gives any ({_mus(mus)})")
        line = f"highest {what} at {speed:g} rpm {where}"
        chosen = speed
    else:
        line = "the best speed depends on μ: " + "; ".join(f"{s:g} rpm at μ {_mus(m)}" for s, m in by_speed.items())
        closest = _closest(rows, found)
        chosen = closest[0] if closest else None
        if closest:
            line += f"; closest to every μ's best: {chosen:g} rpm (at least {closest[1]:.0%} of the best at each μ)"
    if empty:
        line += f"; no {what} at μ {_mus(empty)} at any speed"
    close = [f"{b['runner_up']['plate_rpm']:g} rpm at μ {mu:g}" for mu, b in found.items()
             if b["runner_up"] and b["runner_up"]["max"] >= b["min"] and b["runner_up"]["plate_rpm"] != b["plate_rpm"]]
    if close:
        line += f"; within the replicas' spread of the best: {', '.join(close)}"
    row = next((r for r in rows if r["plate_rpm"] == chosen), None)
    if row and row["hinges_on_mu"]:
        line += f"; at {chosen:g} rpm the answer hinges on μ ({', '.join(row['hinges_why'])})"
    return line


def _share(rows, found, speed) -> list[float]:
    """The measure at `speed` over each μ's best, for every μ in `found`."""
    out = []
    for mu, b in found.items():
        m = next((m for r in rows if r["plate_rpm"] == speed for m in r["by_mu"] if m["mu"] == mu), None)
        v = m["measure_mean"] if m else math.nan
        out.append(v / b["mean"] if math.isfinite(v) else math.nan)
    return out


def _closest(rows, found) -> tuple[float, float] | None:
    """(the speed whose lowest share of a μ's best, over the μ in `found`, is highest;
    that share), or None when no speed has a value at every one of them."""
    scores = {}
    for r in rows:
        shares = _share(rows, found, r["plate_rpm"])
        if all(math.isfinite(x) for x in shares):
            scores[r["plate_rpm"]] = min(shares)
    if not scores:
        return None
    speed = max(scores, key=lambda s: scores[s])
    return speed, scores[speed]
