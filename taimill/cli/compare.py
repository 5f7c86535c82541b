"""`taimill compare A.zarr B.zarr`: the headline figures of two runs side by side."""

from __future__ import annotations

import json
import math

from taimill.cli.common import number, path_text
from taimill.model.mechanisms import STRESS_MIN_UN


def register(sub) -> None:
    p = sub.add_parser("compare", help="headline figures of two stored runs side by side, relative differences")
    p.add_argument("a", type=path_text, help="run store A (RUN.zarr)")
    p.add_argument("b", type=path_text, help="run store B; differences are (B - A)/|A|")
    p.add_argument("--analysis-start", type=number, help="start of both analysis windows (s; default: each run's)")
    p.add_argument("--min-un", type=number, default=STRESS_MIN_UN * 1e3,
                   help=f"stress events: onset normal speed at least this (mm/s, default {STRESS_MIN_UN * 1e3:g})")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(fn=cmd_compare)


def _cell(v, scale) -> str:
    if scale is None or isinstance(v, str):
        return str(v)
    if v is None or not math.isfinite(v):
        return "–"
    return f"{v * scale:.4g}"


def table(result: dict, name_a: str, name_b: str) -> str:
    rows = result["rows"]
    w = max(len(r["label"]) + (len(r["unit"]) + 3 if r["unit"] else 0) for r in rows)
    lines = [f"A = {name_a}: window {result['a']['analysis_window'][0]:g}–{result['a']['analysis_window'][1]:g} s, "
             f"K = {result['a']['ratio']:.4g}, Ω = {result['a']['plate_rpm']:.4g} rpm",
             f"B = {name_b}: window {result['b']['analysis_window'][0]:g}–{result['b']['analysis_window'][1]:g} s, "
             f"K = {result['b']['ratio']:.4g}, Ω = {result['b']['plate_rpm']:.4g} rpm",
             f"{'':{w}}  {'A':>12} {'B':>12} {'(B-A)/|A|':>10}"]
    for r in rows:
        label = r["label"] + (f" ({r['unit']})" if r["unit"] else "")
        rel = r["relative_difference"]
        rel_s = "–" if rel is None or not math.isfinite(rel) else f"{rel:+.1%}"
        if r["scale"] is None:
            rel_s = "same" if r["a"] == r["b"] else "differs"
        lines.append(f"{label:{w}}  {_cell(r['a'], r['scale']):>12} {_cell(r['b'], r['scale']):>12} {rel_s:>10}")
    return "\n".join(lines)


def cmd_compare(a) -> int:
    from taimill.analysis.compare import compare
    from taimill.cli.common import plain
    from taimill.errors import ConfigError

    from taimill.cli.common import open_run_store
    from taimill.cli.report import MAX_MIN_UN_MM_S

    if a.analysis_start is not None and not a.analysis_start >= 0:
        raise ConfigError("command line", "--analysis-start", a.analysis_start, "allowed range [0, the runs' end) s")
    if not 0 <= a.min_un <= MAX_MIN_UN_MM_S:
        raise ConfigError("command line", "--min-un", a.min_un, f"allowed range [0, {MAX_MIN_UN_MM_S:g}] mm/s")
    stores = [open_run_store(path, key) for key, path in (("A", a.a), ("B", a.b))]
    result = compare(*stores, analysis_start=a.analysis_start, min_un=a.min_un * 1e-3)
    if a.json:
        print(json.dumps(plain(result)))
    else:
        print(table(result, a.a, a.b))
    return 0
