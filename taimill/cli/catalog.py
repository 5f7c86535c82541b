"""`taimill presets`, `taimill jars [show NAME | new NAME]`, `taimill mills [NAME]`,
`taimill materials [NAME]`: what can be run (the bundled presets, jars, bowls and mills,
by name from any folder), the jars drawn, a cylinder jar built from a bowl's volume and
diameter, the planetary mills and the materials, with where each of their numbers comes
from."""

from __future__ import annotations

import json
import math
import re
import shutil
import textwrap
from pathlib import Path


FIGURE_SUFFIXES = (".png", ".svg")


def register(sub) -> None:
    from taimill.cli.common import name_text, number, path_text

    p = sub.add_parser("presets", help="list the bundled presets (run one by name: taimill run NAME)")
    p.add_argument("--describe", action="store_true", help="each preset's description (its first sentence) instead of the table")
    p.add_argument("--json", action="store_true", help="print the table as a JSON list (units in the key names)")
    p.set_defaults(fn=cmd_presets)
    j = sub.add_parser("jars", help="list the bundled jars and bowls (area, volume, pieces); "
                                    "'jars show NAME' draws one, 'jars new NAME' builds a cylinder")
    j.add_argument("--json", action="store_true", help="print the table as a JSON list")
    j.set_defaults(fn=cmd_jars)
    jsub = j.add_subparsers(dest="jar_command")
    js = jsub.add_parser("show", help="draw a jar's outline and signed-distance field")
    js.add_argument("name", type=name_text, help="a bundled jar or bowl by name, or a jar file NAME.toml")
    js.add_argument("--out", type=path_text, help="image to write, .png or .svg (default jar-NAME.png)")
    js.add_argument("--overwrite", action="store_true", help="replace an existing --out image")
    jn = jsub.add_parser("new", help="write a cylinder jar file from a bowl's inside volume and diameter")
    jn.add_argument("name", type=name_text, help="the jar's name (letters, digits, . _ -); the file is NAME.toml")
    jn.add_argument("--volume", type=number, required=True, help="inside volume (ml), e.g. the maker's nominal 250")
    jn.add_argument("--diameter", type=number, required=True, help="inside diameter (mm); height = V / (π r²)")
    jn.add_argument("--fillet", type=number, default=0.0,
                    help="fillet radius (mm), recorded in the file; a plain cylinder's cross-section has no corner it rounds")
    jn.add_argument("--material", default="aisi-304", help="wall material of taimill/data/materials.toml (default aisi-304)")
    jn.add_argument("--out", type=path_text, help="jar file to write, .toml (default NAME.toml in the current folder)")
    jn.add_argument("--overwrite", action="store_true", help="replace an existing --out jar file written by jars new")
    m = sub.add_parser("mills", help="list planetary mills (R_p, gear, speeds, bowls; * marks estimates); 'mills NAME' shows one with sources")
    m.add_argument("name", nargs="?", type=name_text, help="mill name or mill file NAME.toml")
    m.add_argument("--json", action="store_true", help="print the mills as a JSON list (units in the key names, "
                                                       "estimated numbers listed under 'estimates')")
    m.set_defaults(fn=cmd_mills)
    mt = sub.add_parser("materials", help="list ball and jar materials (density, E, nu, e, mu) and friction pairs "
                       "(* marks an estimate); 'materials NAME' gives each number's source")
    mt.add_argument("name", nargs="?", type=name_text, help="a material: its numbers and their sources")
    mt.add_argument("--json", action="store_true", help="print the materials as a JSON list, sources included")
    mt.set_defaults(fn=cmd_materials)


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


# (JSON key, table heading, alignment) of `taimill presets`
PRESET_COLUMNS = (("name", "preset", "<"), ("mill", "mill", "<"), ("jar", "jar", "<"), ("balls", "balls", ">"),
                  ("radius_mm", "r mm", ">"), ("pair", "pair", "<"), ("ratio_K", "K", ">"),
                  ("plate_rpm", "Ω rpm", ">"), ("duration_s", "duration s", ">"))


def preset_row(name: str) -> dict:
    """One bundled preset's row, keyed by PRESET_COLUMNS; a preset that does not load
    has its name and `error` instead."""
    from taimill.errors import ConfigError
    from taimill.model.preset import load_preset

    try:
        p = load_preset(name)
    except (ConfigError, OSError) as err:
        return {"name": name, "error": str(err)}
    return {"name": name, "mill": p.mill.name, "jar": p.jar.name, "balls": p.balls.count,
            "radius_mm": round(p.balls.radius * 1e3, 9), "pair": p.pair, "ratio_K": p.drive.ratio,
            "plate_rpm": p.drive.plate_rpm, "duration_s": p.duration}


def _cell(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def cmd_presets(a) -> int:
    from taimill.model.files import BUNDLED, bundled_names

    if a.describe:
        describe([BUNDLED["preset"][0] / f"{n}.toml" for n in bundled_names("preset")])
        return 0
    rows = [preset_row(n) for n in bundled_names("preset")]
    if a.json:
        print(json.dumps(rows, indent=1, ensure_ascii=False))
        return 0
    cells = [[_cell(r[k]) for k, _, _ in PRESET_COLUMNS] if "error" not in r else None for r in rows]
    widths = [max([len(h)] + [len(c[i]) for c in cells if c]) for i, (_, h, _) in enumerate(PRESET_COLUMNS)]

    def line(values):
        return "  ".join(f"{c:{al}{w}}" for c, (_, _, al), w in zip(values, PRESET_COLUMNS, widths)).rstrip()

    print(line([h for _, h, _ in PRESET_COLUMNS]))
    for r, c in zip(rows, cells):
        print(line(c) if c else f"{r['name']:{widths[0]}}  (cannot load: {r['error']})")
    print("run one by name from any folder: taimill run NAME; its file: taimill/data/presets/NAME.toml")
    return 0


def describe(paths) -> None:
    """Each preset's name, then its first sentence, wrapped, never cut."""
    w = max((len(p.stem) for p in paths), default=0) + 2
    width = max(shutil.get_terminal_size().columns, w + 40)
    for p in paths:
        try:
            first = first_sentence(p)
        except (OSError, UnicodeDecodeError) as err:  # a folder or unreadable file named *.toml
            first = f"(cannot read: {getattr(err, 'strerror', None) or err})"
        print(textwrap.fill(first, width, initial_indent=p.stem.ljust(w), subsequent_indent=" " * w,
                            break_long_words=False, break_on_hyphens=False))


def cmd_jars(a) -> int:
    from taimill.figures.jars import draw_jar, jar_row
    from taimill.model.jars import jar_names, load_jar

    if getattr(a, "jar_command", None) == "new":
        return cmd_jars_new(a)
    if getattr(a, "jar_command", None) == "show":
        from taimill.figures import is_figure
        from taimill.model.files import check_output, reads

        with reads() as inputs:
            jar = load_jar(a.name, "command line")
        out = check_output(a.out or f"jar-{jar.name}.png", "--out", overwrite=a.overwrite, suffixes=FIGURE_SUFFIXES,
                           what="figure", ours=is_figure, inputs=inputs)
        print(draw_jar(jar, out))
        return 0
    from taimill.errors import ConfigError

    names = jar_names()
    cy = load_jar("CY").volume if "CY" in names else None
    rows = []
    for n in names:  # a bundled file that does not load is listed with why, not the end of the listing
        try:
            rows.append(jar_row(load_jar(n), cy))
        except ConfigError as err:
            rows.append({"name": n, "error": str(err)})
    if a.json:
        print(json.dumps(rows, indent=1, ensure_ascii=False))
        return 0
    w = max([6] + [len(r["name"]) for r in rows])
    print(f"{'jar':{w}} {'area mm²':>9} {'vol ml':>7} {'/CY':>6} {'pieces':>6} {'fillet mm':>9}  description")
    for r in rows:
        if "error" in r:
            print(f"{r['name']:{w}} (cannot load: {r['error']})")
            continue
        ratio = "-" if r["ratio_to_CY"] is None else f"{r['ratio_to_CY']:.3f}"
        print(f"{r['name']:{w}} {r['area_mm2']:9.1f} {r['volume_ml']:7.2f} {ratio:>6} {r['pieces']:6d} "
              f"{r['fillet_mm']:9g}  {r['description']}")
    return 0


def cmd_jars_new(a) -> int:
    """Write a cylinder jar file (taimill.model.jars.cylinder_jar_text), then load it back."""
    from taimill.errors import ConfigError
    from taimill.model.files import check_output
    from taimill.model.jars import BUILT_MARK, cylinder_jar_text, load_jar
    from taimill.store.output import whole_file

    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", a.name) or a.name.endswith(".toml"):
        raise ConfigError("command line", "NAME", a.name, "a jar name: letters, digits, '.', '_' and '-', without .toml")
    text = cylinder_jar_text(a.name, a.volume, a.diameter, a.fillet, a.material)

    def ours(p: Path) -> bool:
        try:
            return p.is_file() and p.read_text(encoding="utf-8", errors="replace").startswith(BUILT_MARK)
        except OSError:
            return False

    out = check_output(a.out or f"{a.name}.toml", "--out", overwrite=a.overwrite, suffixes=(".toml",),
                       what="jar file", ours=ours)
    with whole_file(out, "jar file") as part:  # a full disk leaves no empty file that blocks the retry: exit 5
        part.write_text(text, encoding="utf-8")
    jar = load_jar(str(out), "command line")
    print(f"{out}: {jar.description}, height {jar.height * 1e3:.4g} mm, volume {jar.volume * 1e6:.4g} ml; "
          f"use it with --jar {out} or jar = \"{out}\" in a preset")
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
        if a.json:
            print(json.dumps([mill.as_dict()], indent=1, ensure_ascii=False))
            return 0
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
    if a.json:
        print(json.dumps([m.as_dict() for m in mills], indent=1, ensure_ascii=False))
        return 0
    rows = [("mill", *(label for label, _ in mill_rows(mills[0])))] + [(m.name, *(v for _, v in mill_rows(m))) for m in mills]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip())
    if any(o.estimate for m in mills for o in m.origins):
        print("* estimate: not verified against a source (`taimill mills NAME` says where each number comes from)")
    return 0


MATERIAL_COLUMNS = (("density_kg_m3", "ρ kg/m³", 8, "g"), ("youngs_modulus_gpa", "E GPa", 6, "g"), ("poisson", "ν", 6, "g"),
                    ("restitution", "e", 6, "g"), ("restitution_speed_mm_s", "at mm/s", 8, "g"), ("friction", "μ", 5, "g"),
                    ("hardness_hv", "HV", 6, "g"))
THERMAL_COLUMNS = (("cp_J_per_kgK", "c_p J/kgK", 8, "g"), ("conductivity_W_per_mK", "k W/mK", 8, "g"))  #: `materials NAME`, the heat model
NO_SOURCE = "none found: `taimill wear` cannot wear this material"  #: an optional number the table lacks


def _number_cell(v, fmt: str) -> str:
    return "—" if v is None else format(v, fmt)


def material_row(data) -> dict:
    """A material's numbers in its file's units, with their sources and estimates."""
    from taimill.errors import ConfigError
    from taimill.model.materials import thermal_data
    from taimill.model.tables import is_estimate

    m = data.material
    try:
        heat = thermal_data(data.name)
        thermal = {"cp_J_per_kgK": heat.cp, "conductivity_W_per_mK": heat.conductivity}, heat.sources
    except ConfigError:  # a material without thermal numbers: listed all the same, `taimill heat` refuses it
        thermal = {"cp_J_per_kgK": None, "conductivity_W_per_mK": None}, {}
    return {"name": data.name, "density_kg_m3": m.density, "youngs_modulus_gpa": m.youngs_modulus / 1e9,
            "poisson": m.poisson, "restitution": data.restitution,
            "restitution_speed_mm_s": round(data.restitution_speed * 1e3, 9), "friction": data.friction,
            **thermal[0], "hardness_hv": data.hardness_hv if math.isfinite(data.hardness_hv) else None,
            "sources": {**data.sources, **thermal[1]},
            "estimates": data.estimates() + [k for k, v in thermal[1].items() if is_estimate(v)]}


def pair_row(name: str) -> dict:
    """A built-in friction pair as `taimill materials PAIR` shows it: μ_s, μ_d, the
    transition speeds (mm/s), its measured contact set (None: derived from the
    materials), and the source of each number (estimates marked)."""
    from taimill.model.materials import load_friction, pair_estimate_keys, pair_source_texts

    friction, contact = load_friction(name, "command line")
    return {"name": name, "mu_s": friction.mu_s, "mu_d": friction.mu_d, "v_s_mm_s": friction.v_s * 1e3,
            "v_d_mm_s": friction.v_d * 1e3, "contact": contact or None, "estimates": pair_estimate_keys(name),
            "sources": pair_source_texts(name)}


def show_pair(name: str, as_json: bool) -> int:
    r = pair_row(name)
    if as_json:
        print(json.dumps(r, indent=1, ensure_ascii=False))
        return 0
    print(f"{name} (friction pair): measured contact set {r['contact'] or '(none: derived from the materials)'}")
    for key, label in (("mu_s", "μ_s"), ("mu_d", "μ_d"), ("v_s_mm_s", "v_s mm/s"), ("v_d_mm_s", "v_d mm/s")):
        mark = "  (estimate)" if key in r["estimates"] else ""
        print(f"  {label:9} {r[key]:>8g}{mark}\n            {r['sources'].get(key, 'no source given')}")
    return 0


def cmd_materials(a) -> int:
    from taimill.model.materials import load_friction, material_data, material_names, pair_estimate_keys, pair_names

    if a.name in pair_names():  # the listing shows the pairs beside the materials: each can be looked up
        return show_pair(a.name, a.json)
    names = [a.name] if a.name else material_names()
    rows = [material_row(material_data(n, "command line", "material")) for n in names]
    if a.json:
        print(json.dumps(rows, indent=1, ensure_ascii=False))
        return 0
    if a.name:
        r = rows[0]
        print(f"{r['name']}:")
        for key, label, _, fmt in MATERIAL_COLUMNS + tuple(c for c in THERMAL_COLUMNS if r[c[0]] is not None):
            mark = "  (estimate)" if key in r["estimates"] else ""
            print(f"  {label:9} {_number_cell(r[key], fmt):>8}{mark}\n            {r['sources'].get(key, NO_SOURCE)}")
        return 0
    print(f"{'material':18}" + "".join(f"{label:>{w}} " for _, label, w, _ in MATERIAL_COLUMNS))
    for r in rows:
        print(f"{r['name']:18}" + "".join(f"{_number_cell(r[k], f) + ('*' if k in r['estimates'] else ' '):>{w + 1}}"
                                       for k, _, w, f in MATERIAL_COLUMNS))
    print("* an estimate, not a measured value: 'taimill materials NAME' says where it comes from")
    print(f"\n{'friction pair':20} {'μ_s':>6} {'μ_d':>6}  measured contact set")
    for name in pair_names():
        friction, contact = load_friction(name, "command line")
        marks = {k: "*" if k in pair_estimate_keys(name) else " " for k in ("mu_s", "mu_d")}
        print(f"{name:20} {friction.mu_s:>5g}{marks['mu_s']} {friction.mu_d:>5g}{marks['mu_d']}  "
              f"{contact or '(none: always derived from the materials)'}")
    return 0
