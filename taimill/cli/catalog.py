"""`taimill presets`, `taimill jars [show NAME]`, `taimill mills [NAME]`: what can be run,
the jars drawn, and the planetary mills with where each of their numbers comes from."""

from __future__ import annotations

import json
import re
import shutil
import textwrap
from pathlib import Path


FIGURE_SUFFIXES = (".png", ".svg")


def register(sub) -> None:
    from taimill.cli.common import name_text, path_text

    sub.add_parser("presets", help="list presets").set_defaults(fn=cmd_presets)
    j = sub.add_parser("jars", help="list jars (area, volume, pieces); 'jars show NAME' draws one")
    j.add_argument("--json", action="store_true", help="print the table as a JSON list")
    j.set_defaults(fn=cmd_jars)
    jsub = j.add_subparsers(dest="jar_command")
    js = jsub.add_parser("show", help="draw a jar's outline and signed-distance field")
    js.add_argument("name", type=name_text, help="jar name (jars/NAME.toml) or path to a jar TOML")
    js.add_argument("--out", type=path_text, help="image to write, .png or .svg (default jar-NAME.png)")
    js.add_argument("--overwrite", action="store_true", help="replace an existing --out image")
    m = sub.add_parser("mills", help="list planetary mills (R_p, gear, speeds, bowls; * marks estimates); 'mills NAME' shows one with sources")
    m.add_argument("name", nargs="?", type=name_text, help="mill name or mill file NAME.toml")
    m.set_defaults(fn=cmd_mills)


def first_sentence(path) -> str:
    """The first sentence of a preset's leading comment (its description), whole."""
    lines = []
    for line in Path(path).read_text().splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    text = " ".join(x for x in lines if x)
    end = re.search(r"\.(\s|$)", text)  # a full stop before a space: "§3.2" and "-2.6" go on
    return text[: end.start() + 1] if end else text


def cmd_presets(a) -> int:
    from taimill.model.files import ROOT

    paths = sorted((ROOT / "presets").glob("*.toml"))
    names = [str(p.relative_to(ROOT)) for p in paths]
    w = max(map(len, names), default=0) + 2
    width = max(shutil.get_terminal_size().columns, w + 40)
    for name, p in zip(names, paths):  # wrapped, never cut: the name, then the first sentence
        try:
            first = first_sentence(p)
        except (OSError, UnicodeDecodeError) as err:  # a folder or unreadable file named *.toml
            first = f"(cannot read: {getattr(err, 'strerror', None) or err})"
        print(textwrap.fill(first, width, initial_indent=name.ljust(w), subsequent_indent=" " * w,
                            break_long_words=False, break_on_hyphens=False))
    return 0


def cmd_jars(a) -> int:
    from taimill.figures.jars import draw_jar, jar_row
    from taimill.model.jars import jar_names, load_jar

    if getattr(a, "jar_command", None) == "show":
        from taimill.figures import is_figure
        from taimill.model.files import check_output, reads

        with reads() as inputs:
            jar = load_jar(a.name, "command line")
        out = check_output(a.out or f"jar-{jar.name}.png", "--out", overwrite=a.overwrite, suffixes=FIGURE_SUFFIXES,
                           what="figure", ours=is_figure, inputs=inputs)
        print(draw_jar(jar, out))
        return 0
    names = jar_names()
    cy = load_jar("CY").volume if "CY" in names else None
    rows = [jar_row(load_jar(n), cy) for n in names]
    if a.json:
        print(json.dumps(rows, indent=1, ensure_ascii=False))
        return 0
    print(f"{'jar':6} {'area mm²':>9} {'vol ml':>7} {'/CY':>6} {'pieces':>6} {'fillet mm':>9}  description")
    for r in rows:
        ratio = "-" if r["ratio_to_CY"] is None else f"{r['ratio_to_CY']:.3f}"
        print(f"{r['name']:6} {r['area_mm2']:9.1f} {r['volume_ml']:7.2f} {ratio:>6} {r['pieces']:6d} "
              f"{r['fillet_mm']:9g}  {r['description']}")
    return 0


def _marked(mill, key: str, text: str) -> str:
    """A mill's number as shown: "≈70.5*" if it is an estimate."""
    return f"≈{text}*" if mill.is_estimate(key) else text


def _speeds(mill) -> str:
    lo, hi = mill.plate_rpm_min, mill.plate_rpm_max
    if hi is None:  # the global sanity cap applies
        r = mill.plate_range
        return f"unknown (cap {r.lo:g} to {r.hi:g})"
    return _marked(mill, "plate_rpm_min", f"{lo or 0:g}") + "-" + _marked(mill, "plate_rpm_max", f"{hi:g}")


def _gear(mill) -> str:
    key = "gear_ratios" if mill.gear.kind == "set" else "gear_ratio"
    text = f"{mill.gear.text} ({mill.gear.k_text})" if mill.gear.kind != "free" else mill.gear.k_text
    return _marked(mill, key, text) if mill.gear.kind != "free" else text


def mill_rows(mill) -> list[tuple[str, str]]:
    """(label, value as shown) of each of a mill's figures, estimates marked."""
    return [("maker, model", f"{mill.maker} {mill.model}"),
            ("R_p mm", _marked(mill, "plate_radius_mm", f"{mill.plate_radius * 1e3:g}")),
            ("gear (maker, K)", _gear(mill)),
            ("plate rpm", _speeds(mill)),
            ("stations", _marked(mill, "stations", f"{mill.stations:d}")),
            ("bowls ml", _marked(mill, "bowls_ml", ",".join(map(str, mill.bowls_ml)) or "-"))]


def cmd_mills(a) -> int:
    from taimill.model.mills import load_mill, mill_names

    if a.name:
        mill = load_mill(a.name, "command line", Path.cwd())
        print(f"{mill.name}: {mill.maker} {mill.model} ({mill.source})")
        if mill.description:
            print(f"  {mill.description}")
        for label, value in mill_rows(mill)[1:]:
            print(f"  {label:16} {value}")
        print("where each number comes from:")
        for o in mill.origins:
            print(textwrap.fill(f"{'estimate' if o.estimate else 'source'}: {o.text}", 100, initial_indent=f"  {o.key:16} ",
                                subsequent_indent=" " * 19, break_long_words=False, break_on_hyphens=False))
        if any(o.estimate for o in mill.origins):
            print("* estimate: not verified against a source")
        return 0
    mills = [load_mill(n, "command line") for n in mill_names()]
    rows = [("mill", *(label for label, _ in mill_rows(mills[0])))] + [(m.name, *(v for _, v in mill_rows(m))) for m in mills]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip())
    if any(o.estimate for m in mills for o in m.origins):
        print("* estimate: not verified against a source (`taimill mills NAME` says where each number comes from)")
    return 0
