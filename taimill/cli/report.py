"""`taimill analyse RUN.zarr` (every quantity of docs/outputs.md, both estimators) and
`taimill report RUN.zarr` (publication figures)."""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
from pathlib import Path

from taimill.cli.common import number, path_text, stations_text
from taimill.model.mechanisms import STRESS_MIN_UN


MAX_MIN_UN_MM_S = 1e6  #: --min-un above 1 km/s would count nothing
# In a report folder: the names of the figures taimill wrote there, the only files
# `report --overwrite` replaces (a user's own file of a figure's name is kept).
REPORT_MARK = "taimill-report.json"
MAX_SAMPLING_RATE = 1e5  #: /s, the highest trajectory rate a preset may store


def _add_analysis_options(p):
    p.add_argument("run", metavar="RUN", type=path_text, help="run store written by `taimill run --out` (RUN.zarr)")
    p.add_argument("--analysis-start", type=number, help="start of the analysis window (s; default: the run's)")
    p.add_argument("--min-un", type=number, default=STRESS_MIN_UN * 1e3,
                   help=f"stress events: events with at least this onset normal speed (mm/s, default "
                        f"{STRESS_MIN_UN * 1e3:g}); 0 counts every contact (the all-contacts column always does)")
    p.add_argument("--sampling-rate", type=number, default=100.0,
                   help="sampled (thesis §3.3, MSC.Adams-like) estimator: output samples per second (default 100)")


def register(sub):
    a = sub.add_parser("analyse", help="every quantity of a stored run (event and sampled estimators)")
    _add_analysis_options(a)
    a.add_argument("--json", action="store_true", help="print one JSON object")
    a.set_defaults(fn=cmd_analyse)
    r = sub.add_parser("report", help="figures of a stored run (or of a sweep store)")
    _add_analysis_options(r)
    r.add_argument("--out", type=path_text, help="folder for the figures, created if needed (default: RUN-report next to the store)")
    r.add_argument("--overwrite", action="store_true", help="replace figures already in the --out folder")
    r.add_argument("--format", choices=("png", "svg", "pdf"), default="png")
    r.add_argument("--overlay", type=path_text, help="sweep stores only: measured series CSV drawn against K")
    r.set_defaults(fn=cmd_report)


def _check_options(a):
    """The analysis options, before the store is opened."""
    from taimill.errors import ConfigError

    if a.analysis_start is not None and a.analysis_start < 0:
        raise ConfigError("command line", "--analysis-start", a.analysis_start, "allowed range [0, the run's end) s")
    if not 0 <= a.min_un <= MAX_MIN_UN_MM_S:
        raise ConfigError("command line", "--min-un", a.min_un, f"allowed range [0, {MAX_MIN_UN_MM_S:g}] mm/s")
    if not 0 < a.sampling_rate <= MAX_SAMPLING_RATE:
        raise ConfigError("command line", "--sampling-rate", a.sampling_rate, f"allowed range (0, {MAX_SAMPLING_RATE:g}] /s")


def _open(a):
    from taimill.analysis.run import analyse
    from taimill.cli.common import open_run_store

    _check_options(a)
    store = open_run_store(a.run)
    return analyse(store, analysis_start=a.analysis_start, min_un=a.min_un * 1e-3, sampling_rate=a.sampling_rate)


def cmd_analyse(a) -> int:
    from taimill.cli.common import plain as _plain
    from taimill.outcome.dose import dose_keys
    from taimill.schema import with_units

    analysis = _open(a)
    q = analysis.quantities()
    q = with_units(q | dose_keys(q, analysis.store.config))  # per gram of powder, where the run names its powder
    if a.json:
        print(json.dumps(_plain(q)))
        return 0
    print(text_report(q))
    return 0


def cmd_report(a) -> int:
    from taimill.errors import ConfigError
    from taimill.model.files import check_output

    _check_options(a)
    out = a.out or str(Path(a.run)).rstrip("/").removesuffix(".zarr") + "-report"
    out = check_output(out, "--out", overwrite=None, folder=True)
    if _is_sweep(a.run):
        from taimill.figures.sweep import figure_stems, read_overlay, report_sweep
        from taimill.store.sweep import open_sweep

        if a.overlay:
            read_overlay(a.overlay)  # its errors before the store is read or any figure drawn
        try:  # maps too where two numeric axes vary
            table = open_sweep(a.run).table()
        except ConfigError:  # also StoreError: said by report_sweep, after the --out checks
            table = {}
        _refuse_existing(out, figure_stems(table, bool(a.overlay)), a)
        with ReportFolder(out) as folder:
            paths = folder.commit(report_sweep(a.run, folder.build, a.format, overlay=a.overlay))
    else:
        from taimill.figures.report import FIGURES, left_out, left_out_text, write_report

        if a.overlay:
            raise ConfigError("command line", "--overlay", a.overlay, "only for sweep stores (taimill sweep --out)")
        _refuse_existing(out, list(FIGURES), a)
        analysis = _open(a)
        left = left_out(analysis)  # figures with nothing to draw (no stress event, say): named in one line
        with ReportFolder(out) as folder:
            built = write_report(analysis, folder.build, a.format, leave_out=left)
            paths = folder.commit(built, stale=[f"{s}.{a.format}" for s in left])
        if left:
            print(f"taimill: note: {left_out_text(left)}", file=sys.stderr)
    for p in paths:
        print(p)
    return 0


class ReportFolder:
    """The figures of one report, drawn where they cannot mix with a report already in
    `out`: in a hidden folder inside it (OUT/.taimill-report.partial-PID), moved in by
    `commit` once every one is drawn. An interrupt, a full disk or a figure that fails
    leaves `out` as it was (no figure of the new report in it, none of the old one
    replaced; a folder the report created is deleted) and deletes the partial folder,
    so the same command simply runs again. Inside, not beside: `out` may be the current
    folder, or one in a folder the user cannot write. `out` is locked while it is
    written (OUT/.taimill-report.lock, store.output.OutputLock): a second report into
    the same folder is refused naming the first. Only the figures are moved in: the
    user's files in `out`, and figures of other formats, stay."""

    def __init__(self, out: Path):
        from taimill.store.output import OutputLock, partial_path

        self.out = Path(out)
        self.base = self.out / ".taimill-report"  # the name the partial folder and the lock are made from
        self.build = partial_path(self.base)
        self.lock = OutputLock(self.base)
        self.existed = os.path.lexists(out)

    def __enter__(self) -> "ReportFolder":
        from taimill.errors import StoreError, StoreWriteError
        from taimill.store.output import refused, remove

        try:
            self.out.mkdir(parents=True, exist_ok=True)
            self.lock.acquire()
        except StoreError as err:  # in use, or no lock file: named by the folder
            self._remove_new_folder()
            raise type(err)(self.out, err.key, err.allowed) from None
        except OSError as err:
            raise StoreWriteError(self.out, "figures", f"cannot create the folder ({refused(err)})") from None
        try:
            remove(self.build)
            self.build.mkdir()
        except BaseException as err:
            self.__exit__(type(err), err, None)
            raise
        return self

    def commit(self, built, stale=()) -> list[Path]:
        """Move the figures `built` (paths in the partial folder) into `out` with the
        updated REPORT_MARK, delete this report's earlier figures of the names `stale`
        (_stale), and return where the figures are now. SIGTERM and Ctrl-C wait for
        the few renames (runs.signals.hold): a report is in `out` whole or not at all."""
        from taimill.runs.signals import drop_hold, hold

        names = [Path(p).name for p in built]
        drop = _stale(self.out, stale)
        _mark(self.build, names, _marked(self.out) - set(drop))  # a full disk stops here, before any move
        hold()
        try:
            for name in drop:
                os.unlink(self.out / name)
            for name in [*names, REPORT_MARK]:
                os.replace(self.build / name, self.out / name)
        finally:
            drop_hold()  # the report is complete: an interrupt during the renames ends nothing
        self._clear_leftovers()
        return [self.out / n for n in names]

    def _clear_leftovers(self) -> None:
        """Partial folders of reports into `out` that were killed (kill -9): deleted."""
        from taimill.store.output import leftovers, remove

        for q in leftovers(self.base):
            if q.is_dir() and all(_report_file(e.name) for e in q.iterdir()):
                try:
                    remove(q)
                except OSError:
                    continue
                print(f"taimill: removed {q}, left by an earlier report into {self.out} that did not finish",
                      file=sys.stderr)

    def kept(self) -> str:
        return f"{self.out} is unchanged" if self.existed else f"nothing was written to {self.out}"

    def _remove_new_folder(self) -> None:
        if not self.existed:
            with contextlib.suppress(OSError):
                os.rmdir(self.out)  # created here and empty again

    def __exit__(self, exc_type, err, tb):
        from taimill.errors import Interrupted, StoreWriteError
        from taimill.store.output import refused, remove

        with contextlib.suppress(OSError):
            remove(self.build)
        self.lock.release()
        if err is None:
            return
        self._remove_new_folder()
        if isinstance(err, KeyboardInterrupt):
            raise Interrupted(f"{str(err) or 'interrupted'}; {self.kept()}", getattr(err, "exit_code", 130)) from err
        if isinstance(err, OSError):
            raise StoreWriteError(self.out, "figures", f"write failed ({refused(err)}); {self.kept()}") from err
        if isinstance(err, StoreWriteError):  # a figure's whole_file, named by its place in the partial folder
            raise StoreWriteError(self.out, err.key, f"{err.allowed.split('; ')[0]}; {self.kept()}") from err


def _report_file(name: str) -> bool:
    """A name a report writes in its partial folder: a figure (or its temporary file), REPORT_MARK."""
    return name.endswith((".png", ".svg", ".pdf")) or name == REPORT_MARK


def _stale(out: Path, names) -> list[str]:
    """Of `names`, this report's figures an earlier report left in `out`: the figures
    this one leaves out, which beside the new ones would pass for this run's. Only those
    REPORT_MARK lists (_refuse_existing let --overwrite replace only ours); the commit
    deletes them."""
    from taimill.figures import is_figure

    ours = _marked(out)
    return [n for n in names if n in ours and os.path.lexists(out / n) and is_figure(out / n)]


def _refuse_existing(out: Path, stems, a) -> None:
    """No figure already in `out` is replaced without --overwrite."""
    from taimill.errors import ConfigError

    there = [out / f"{s}.{a.format}" for s in stems if os.path.lexists(out / f"{s}.{a.format}")]
    if there and not a.overwrite:
        raise ConfigError("command line", "--out", str(out), f"already holds {there[0].name} (and {len(there) - 1} more "
                          "figure(s) of this report); pass --overwrite to replace them")
    for p in there:
        if p.is_dir():
            raise ConfigError("command line", "--out", str(out), f"{p.name} is a folder; a figure would go there")
    from taimill.figures import is_figure
    from taimill.model.files import check_replaceable

    ours = _marked(out)
    for p in there:
        check_replaceable(p, "--out", f"report figure (listed in {REPORT_MARK})",
                          lambda q: q.name in ours and is_figure(q))


def _marked(out: Path) -> set[str]:
    """The figures a report wrote in `out` (REPORT_MARK); none if it is not there or not ours."""
    try:
        names = json.loads((out / REPORT_MARK).read_text()).get("figures", [])
        return {n for n in names if isinstance(n, str)}
    except (OSError, ValueError, AttributeError):
        return set()


def _mark(folder: Path, names, earlier=frozenset()) -> None:
    """Write REPORT_MARK in `folder`: the figures `names` and the `earlier` ones of the
    folder it will be moved into; flushed to disk like the figures."""
    from taimill.store.output import whole_file

    figures = sorted(set(earlier) | set(names))
    with whole_file(folder / REPORT_MARK, "report list") as part:
        part.write_text(json.dumps({"written_by": "taimill report", "figures": figures}, indent=1))


def _is_sweep(path) -> bool:
    try:
        from taimill.store.sweep import is_sweep
    except ImportError:
        return False
    return os.path.isdir(path) and is_sweep(path)


def _f(v, scale=1.0, unit=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"{v * scale:.4g}{unit}"


def text_report(q: dict) -> str:
    e, s, a = q["event_estimator"], q["sampled_estimator"], q.get("all_contacts_estimator", {})
    from taimill.cli.common import lead_line

    lead = lead_line({**q, "impact_power": e.get("impact_power")}).rstrip("\n")
    lines = [f"status: {q['status']}; window {q['analysis_window'][0]:g}–{q['analysis_window'][1]:g} s; "
             f"K = {q['ratio']:.4g}, Ω = {q['plate_rpm']:.4g} rpm", *([lead] if lead else []),
             f"{'':34} {'stress events':>14} {'all contacts':>14} {s.get('estimator', 'sampled'):>16}"]
    rows = (("events (sampled: points)", "events", "points", 1, ""),
            ("impact power E_I/τ", "impact_power", "impact_power", 1, " W"),
            ("  normal", "impact_power_normal", "impact_power_normal", 1, " W"),
            ("  tangential", "impact_power_tangential", "impact_power_tangential", 1, " W"),
            ("  ball–ball", "impact_power_ball_ball", "impact_power_ball_ball", 1, " W"),
            ("  ball–wall", "impact_power_ball_wall", "impact_power_ball_wall", 1, " W"),
            ("impact power density (eq 4.1)", "impact_power_density", "impact_power_density", 1e-6, " W/cm³"),
            ("mean SE", "mean_se", "mean_se", 1e3, " mJ"),
            ("  normal", "mean_se_normal", "mean_se_normal", 1e3, " mJ"),
            ("  tangential", "mean_se_tangential", "mean_se_tangential", 1e3, " mJ"),
            ("  ball–ball", "mean_se_ball_ball", "mean_se_ball_ball", 1e3, " mJ"),
            ("  ball–wall", "mean_se_ball_wall", "mean_se_ball_wall", 1e3, " mJ"),
            ("normal fraction", "normal_fraction", "normal_fraction", 1, ""))
    for label, ke, ks, scale, unit in rows:
        lines.append(f"{label:34} {_f(e.get(ke), scale, unit):>14} {_f(a.get(ke), scale, unit):>14} "
                     f"{_f(s.get(ks), scale, unit):>16}")
    if e.get("min_un"):
        lines.append(f"stress events: onset u̇n ≥ {e['min_un'] * 1e3:g} mm/s ({e['events_below_threshold']} events below)")
    if isinstance(q.get("specific_power_W_per_g"), float):
        lines.append(f"per g of powder ({q['powder_mass_g']:g} g): dissipated {_f(q['specific_power_W_per_g'], 1, ' W/g')}, "
                     f"in impacts {_f(q.get('specific_power_impact_W_per_g'), 1, ' W/g')}")
    if q.get("main_sink"):
        m = q["main_sink"]
        lines.append(f"dissipated in impacts {_f(q.get('dissipated_power_impact'), 1, ' W')}, in persistent contacts "
                     f"{_f(q.get('dissipated_power_persistent'), 1, ' W')}; main sink: {m['mechanism']} "
                     f"({_f(m['share'], 100, ' %')})")
    if "error" in s:
        lines.append(f"sampled estimator unavailable: {s['error']}")
    crit = ", ".join(f"{k} {v:.3f}" for k, v in q["regime_criteria"].items())
    h = q["wear_hot_spot"]
    lines += [f"stress-event rate {_f(e.get('collision_rate'), 1, ' /s')}; dissipated power {_f(q['dissipated_power'], 1, ' W')} "
              f"(one jar); energy balance error {_f(q['energy_balance_error'], 100, ' %')}"]
    if q.get("stations"):
        lines.append(f"whole mill ({stations_text(q['stations'])}): impact power {_f(q.get('impact_power_mill'), 1, ' W')}, "
                     f"dissipated power {_f(q.get('dissipated_power_mill'), 1, ' W')}")
    lines += [f"randomness index 1/σ {_f(q['randomness_index'])}",
              f"regime {q['regime']}, class {q.get('regime_class', '–')} (confidence {_f(q['regime_confidence'])}; "
              f"slip ratio {_f(q.get('slip_ratio'))}; {crit})",
              f"critical ratio K_c {q['critical_ratio']:.3f}; one-ball hit energy {_f(q['single_ball_hit']['se'], 1e3, ' mJ')}"]
    if h.get("surface"):
        from taimill.analysis.spatial import hot_spot_text

        lines.append(hot_spot_text(h))
    return "\n".join(lines)

