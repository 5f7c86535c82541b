"""`taimill presets`, `taimill jars [show NAME]`, `taimill materials [NAME]`: what can be
run, the jars drawn, and the materials with their sources."""

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
    m = sub.add_parser("materials", help="list ball and jar materials (density, E, nu, e, mu) and friction pairs "
                       "(* marks an estimate); 'materials NAME' gives each number's source")
    m.add_argument("name", nargs="?", type=name_text, help="a material: its numbers and their sources")
    m.add_argument("--json", action="store_true", help="print the materials as a JSON list, sources included")
    m.set_defaults(fn=cmd_materials)


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


MATERIAL_COLUMNS = (("density_kg_m3", "ρ kg/m³", 8, "g"), ("youngs_modulus_gpa", "E GPa", 6, "g"), ("poisson", "ν", 6, "g"),
                    ("restitution", "e", 6, "g"), ("restitution_speed_mm_s", "at mm/s", 8, "g"), ("friction", "μ", 5, "g"))


def material_row(data) -> dict:
    """A material's numbers in its file's units, with their sources and estimates."""
    m = data.material
    return {"name": data.name, "density_kg_m3": m.density, "youngs_modulus_gpa": m.youngs_modulus / 1e9,
            "poisson": m.poisson, "restitution": data.restitution,
            "restitution_speed_mm_s": round(data.restitution_speed * 1e3, 9), "friction": data.friction,
            "sources": dict(data.sources), "estimates": data.estimates()}


def cmd_materials(a) -> int:
    from taimill.model.materials import load_friction, material_data, material_names, pair_estimate_keys, pair_names

    names = [a.name] if a.name else material_names()
    rows = [material_row(material_data(n, "command line", "material")) for n in names]
    if a.json:
        print(json.dumps(rows, indent=1, ensure_ascii=False))
        return 0
    if a.name:
        r = rows[0]
        print(f"{r['name']}:")
        for key, label, _, fmt in MATERIAL_COLUMNS:
            mark = "  (estimate)" if key in r["estimates"] else ""
            print(f"  {label:9} {format(r[key], fmt):>8}{mark}\n            {r['sources'][key]}")
        return 0
    print(f"{'material':18}" + "".join(f"{label:>{w}} " for _, label, w, _ in MATERIAL_COLUMNS))
    for r in rows:
        print(f"{r['name']:18}" + "".join(f"{format(r[k], f) + ('*' if k in r['estimates'] else ' '):>{w + 1}}"
                                       for k, _, w, f in MATERIAL_COLUMNS))
    print("* an estimate, not a measured value: 'taimill materials NAME' says where it comes from")
    print(f"\n{'friction pair':20} {'μ_s':>6} {'μ_d':>6}  measured contact set")
    for name in pair_names():
        friction, contact = load_friction(name, "command line")
        marks = {k: "*" if k in pair_estimate_keys(name) else " " for k in ("mu_s", "mu_d")}
        print(f"{name:20} {friction.mu_s:>5g}{marks['mu_s']} {friction.mu_d:>5g}{marks['mu_d']}  "
              f"{contact or '(none: always derived from the materials)'}")
    return 0
