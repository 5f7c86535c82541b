"""`taimill export liggghts PRESET --out DIR` (a ready-to-run LIGGGHTS case) and
`taimill import liggghts DIR --out RUN.zarr` (its dumps as a taimill run store);
docs/liggghts.md. Approximations of the mapping are printed as warnings on stderr;
what LIGGGHTS cannot express stops with one line and exit code 2."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from taimill.cli.common import DEFAULT_PRESET, PRESET_HELP, add_overrides, overrides, plain, print_warnings, summary_table


def register(sub) -> None:
    e = sub.add_parser("export", help="write a preset as a case for another DEM code")
    es = e.add_subparsers(dest="target", required=True)
    x = es.add_parser("liggghts", help="a LIGGGHTS-PUBLIC 3.8 case: jar STL, input deck, start positions, run.sh")
    x.add_argument("preset", nargs="?", default=DEFAULT_PRESET, help=PRESET_HELP)
    x.add_argument("--out", required=True, help="case directory to write")
    x.add_argument("--overwrite", action="store_true", help="replace an existing case directory")
    x.add_argument("--strict", action="store_true",
                   help="refuse what LIGGGHTS can only approximate (a speed-dependent restitution, stiction)")
    x.add_argument("--dump-mesh", action="store_true", help="also dump the moving jar mesh (STL) with every frame")
    x.add_argument("--liggghts", default="liggghts", help="LIGGGHTS binary run.sh calls (default: liggghts)")
    add_overrides(x)
    x.set_defaults(fn=cmd_export)
    i = sub.add_parser("import", help="read another DEM code's output back as a taimill run store")
    is_ = i.add_subparsers(dest="source", required=True)
    y = is_.add_parser("liggghts", help="the dumps of a case written by `taimill export liggghts`")
    y.add_argument("case", metavar="DIR", help="the case directory, after LIGGGHTS ran in it")
    y.add_argument("--out", required=True, help="zarr run store to write (RUN.zarr)")
    y.add_argument("--overwrite", action="store_true", help="replace an existing store")
    y.add_argument("--dump", help="dump file (default: the case's dumps/balls.dump)")
    y.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    y.set_defaults(fn=cmd_import)


def _check_out(path: str, overwrite: bool, what: str, ours, inputs) -> None:
    """The output folder (case or store) checked like every command's outputs: not
    empty, not an existing path without --overwrite, with it only an output of its
    kind taimill wrote and none of the inputs; its nearest existing folder writable."""
    from taimill.model.files import check_output

    check_output(path, "--out", overwrite=overwrite, folder=True, what=what, ours=ours, inputs=inputs)


def cmd_export(a) -> int:
    from taimill.bridge.contact_map import contact_mapping
    from taimill.bridge.liggghts import export_case, is_case
    from taimill.model.files import reads
    from taimill.model.preset import load_preset
    from taimill.store.output import Output

    with reads() as inputs:
        preset = load_preset(a.preset, overrides(a))
    mapping = contact_mapping(preset, strict=a.strict)  # a refusal leaves an existing --out case untouched
    _check_out(a.out, a.overwrite, "LIGGGHTS case", is_case, inputs)
    print_warnings(preset)  # once every check passed: a refusal stays one line
    # built beside an existing case and swapped in when complete (store/output.py); a
    # half-written case is of no use, so none is kept
    with Output(a.out, overwrite=a.overwrite, what="case", kind="LIGGGHTS case",
                ours=is_case, inputs=inputs, keep=lambda _: False) as out:
        result = export_case(preset, out.build, strict=a.strict, dump_mesh=a.dump_mesh, liggghts=a.liggghts,
                             mapping=mapping)
        out.commit()
    result.out = Path(a.out)  # where it is now, not where it was built
    for w in result.mapping.warnings:
        print(f"taimill: warning: {w}", file=sys.stderr)
    print(result.describe())
    return 0


def cmd_import(a) -> int:
    from taimill.bridge.dumps import LOG, import_case, liggghts_run_time
    from taimill.bridge.liggghts import MANIFEST
    from taimill.errors import ConfigError
    from taimill.store.output import Output
    from taimill.store.layout import is_run_store

    inputs = [a.case] + ([a.dump] if a.dump else [])  # the case (dumps, deck, STL): --out must not replace it
    _check_out(a.out, a.overwrite, "run store", is_run_store, inputs)
    if not Path(a.case).is_dir():
        raise ConfigError("command line", "DIR", a.case, "an existing case directory (taimill export liggghts --out)")
    if not (Path(a.case) / MANIFEST).is_file():  # before the output is touched
        raise ConfigError("command line", "DIR", a.case, f"not a case exported by `taimill export liggghts` (no {MANIFEST})")
    # locked, built beside an existing store and swapped in when complete, as `run` writes;
    # one that failed (a full disk) is deleted: the case is still there to import again
    with Output(a.out, overwrite=a.overwrite, what="run", kind="run store", ours=is_run_store, inputs=inputs,
                keep=lambda _: False) as out:
        summary = import_case(a.case, out.build, dump=a.dump)
        out.commit()
    ran = liggghts_run_time(a.case)
    if ran is None:
        print(f"taimill: warning: {Path(a.case) / LOG}: no \"Loop time of\" line (no log, or LIGGGHTS was stopped): "
              "LIGGGHTS' run time is unknown, the summary's wall time and speed are empty", file=sys.stderr)
    if a.json:
        print(json.dumps(plain(summary)))
        return 0
    took = f"LIGGGHTS ran them in {ran[0]:.4g} s on {ran[1]} process{'es' if ran[1] != 1 else ''} ({LOG})" if ran else ""
    print(f"{a.case}: LIGGGHTS dumps, {summary['sim_seconds']:g} s{'; ' + took if took else ''}; collision events "
          "reconstructed from the frames (store attribute events_source); no energy ledger (energy_source)")
    print(summary_table(summary))
    print(f"stored in {a.out}")
    return 0
