"""The headline figures of two stored runs side by side, with relative differences
(`taimill compare A.zarr B.zarr`). Any two run stores: two presets, a run and its
replica, a taimill run and one imported from LIGGGHTS. Both are analysed afresh by the
same code (`taimill.analysis.run.analyse`) over their own windows, so stored summaries
of different versions do not matter."""

from __future__ import annotations

import math

from taimill.analysis.run import analyse
from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.schema import SUMMARY_ROWS

# (key, label, unit, scale): the run summary's rows (schema.SUMMARY_ROWS) where it has
# the key, and the few figures only an analysis gives
_ANALYSIS_ONLY = {
    "mean_se_ball_ball": ("mean_se_ball_ball", "  ball-ball", "mJ", 1e3),
    "mean_se_ball_wall": ("mean_se_ball_wall", "  ball-wall", "mJ", 1e3),
    "side_wall_fraction": ("side_wall_fraction", "share of ball-frames on the side wall", "", 1),
    "flight_fraction": ("flight_fraction", "share of ball-frames in flight", "", 1),
}
_KEYS = ("events", "collision_rate", "impact_power", "impact_power_normal", "impact_power_tangential", "mean_se",
         "mean_se_normal", "mean_se_tangential", "mean_se_ball_ball", "mean_se_ball_wall", "normal_fraction",
         "randomness_index", "side_wall_fraction", "flight_fraction", "dissipated_power", "energy_balance_error", "regime")
_SUMMARY = {row[0]: row for row in SUMMARY_ROWS}
HEADLINE = tuple(_SUMMARY.get(k) or _ANALYSIS_ONLY[k] for k in _KEYS)


def headline(q: dict) -> dict:
    """The HEADLINE values of one analysis (`RunAnalysis.quantities()`)."""
    e, crit = q["event_estimator"], q.get("regime_criteria", {})
    out = {}
    for key, *_ in HEADLINE:
        if key in e:
            out[key] = e[key]
        elif key == "side_wall_fraction":
            out[key] = crit.get("wall_fraction", math.nan)
        elif key == "flight_fraction":
            out[key] = crit.get("flight_fraction", math.nan)
        else:
            out[key] = q.get(key, math.nan)
    return out


def relative_difference(a, b) -> float:
    """(b − a)/|a|; nan when either is not a finite number or a is 0."""
    ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (a, b))
    return (b - a) / abs(a) if ok and a != 0 else math.nan


def compare(a, b, *, analysis_start: float | None = None, min_un: float = STRESS_MIN_UN) -> dict:
    """Both runs analysed (paths or RunStores): {"a": {...}, "b": {...}, "rows": [...]}
    with one row per HEADLINE entry: key, label, unit, a, b, relative difference."""
    qa = analyse(a, analysis_start=analysis_start, min_un=min_un).quantities()
    qb = analyse(b, analysis_start=analysis_start, min_un=min_un).quantities()
    ha, hb = headline(qa), headline(qb)
    rows = [{"key": k, "label": label, "unit": unit, "scale": scale, "a": ha[k], "b": hb[k],
             "relative_difference": relative_difference(ha[k], hb[k]) if scale is not None else
             (0.0 if ha[k] == hb[k] else math.nan)}
            for k, label, unit, scale in HEADLINE]
    info = {side: {"analysis_window": q["analysis_window"], "ratio": q["ratio"], "plate_rpm": q["plate_rpm"],
                   "status": q["status"]} for side, q in (("a", qa), ("b", qb))}
    return {"a": info["a"], "b": info["b"], "rows": rows}
