"""The design study: Optuna ask/tell over a jar family (and K), stored in SQLite in the
study folder, evaluated in batches on the sweep machinery (taimill.design.protocol).

Determinism and resume. Optuna's samplers keep their random state in memory only, so
a restarted study would draw other designs. Here the sampler is rebuilt before every
ask, seeded from (study seed, number of live trials stored), so the n-th design is a
function of the stored history and the seed. A batch is planned in the study's
`batch` attribute (its first trial and size) before its first ask; its trials are
asked one after another (a candidate breaking a constraint is told PRUNED at once, its
violations kept in the trial), then run as one sweep and told in trial order. After a
kill −9 the same command finds the unfinished batch: it asks the trials still missing
(only if none was told yet), re-evaluates the trials left RUNNING with their stored
parameters (the runs are seeded and bit-stable, so they give the values the lost
evaluation would have) and tells them in order. A trial the kill caught while it was
being asked (its parameters possibly incomplete, its constraints not yet checked) is
marked `abandoned`, failed, and asked again: the seed counts live trials only, so the
new ask draws the same design (trial numbers shift by one; the designs do not). An interrupted and resumed study
therefore ends with the same designs as an uninterrupted one with the same seed.

The database is checked before Optuna opens it (`check_database`): a damaged one would
otherwise end the study in a SQLAlchemy traceback, or be written on. Every file the
study writes beside it (jar files, references.json) appears whole or not at all.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sqlite3
from dataclasses import asdict, dataclass, field
from pathlib import Path

from taimill.design import constraints, families
from taimill.design.protocol import Protocol, evaluate, figures
from taimill.errors import ConfigError, StoreError, one_line
from taimill.store.output import whole_file

STUDY = "design"
DATABASE = "study.db"
SQLITE_HEADER = b"SQLite format 3\x00"
MAX_PRUNED = 50  #: candidates pruned per wanted candidate of a batch before the batch stops asking


@dataclass
class Settings:
    """What makes a study (stored with it; a resumed study must match)."""

    preset: str
    family: str
    objectives: list  #: [Objective]
    floors: dict  #: {key: lowest allowed mean}
    ratio: tuple  #: (lo, hi) searched, or (K, K)
    replicas: int
    seed: int
    batch: int
    overrides: dict  #: run overrides of every run (duration, analysis_start, …)
    tolerance: float
    min_wall_mm: float
    fixed: dict = field(default_factory=dict)  #: family parameters held fixed

    def identity(self) -> dict:
        d = asdict(self)
        d["objectives"] = [o.label for o in self.objectives]
        d["ratio"] = list(self.ratio)
        return d


class Study:
    def __init__(self, out: Path, settings: Settings, *, workers=None, scheduler=None, log=print):
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        self.out, self.s, self.workers, self.scheduler, self.log = Path(out), settings, workers, scheduler, log
        from taimill.model.preset import load_preset

        base = load_preset(settings.preset, settings.overrides)
        fixed_gear = base.mill is not None and base.mill.gear.kind == "fixed"  # K is the gear's, never set
        if not fixed_gear:
            base = load_preset(settings.preset, settings.overrides | {"ratio": settings.ratio[0]})
        self.base = base
        self.protocol = Protocol(settings.preset, settings.overrides, settings.replicas, settings.seed, fixed_gear)
        self.limits = constraints.Limits(self._circle(base.jar), base.jar.volume, settings.tolerance,
                                         base.balls.radius, settings.min_wall_mm * 1e-3)
        self.family = families.family(settings.family)
        self.params = {p.name: p for p in self.family.params(self.limits.radius * 1e3, base.balls.radius * 1e3)}
        for k, v in settings.fixed.items():
            if k not in self.params:
                raise ConfigError("command line", "--fix", k, f"a parameter of the {settings.family} family: {', '.join(self.params)}")
            p = self.params[k]
            if not p.lo <= v <= p.hi or (p.integer and v != int(v)):
                raise ConfigError("command line", "--fix", f"{k}={v:g}", f"allowed range [{p.lo:g}, {p.hi:g}]"
                                  + (", an integer" if p.integer else ""))
        self.study = None  # open(): the settings are checked before anything is written

    @property
    def database(self) -> Path:
        return self.out / DATABASE

    def open(self) -> "Study":
        """Create or resume the stored study (the caller holds the folder's lock)."""
        import optuna

        check_database(self.database)
        self.out.mkdir(parents=True, exist_ok=True)
        directions = [o.direction for o in self.s.objectives]
        storage = f"sqlite:///{self.database.resolve()}"
        self.study = optuna.create_study(study_name=STUDY, storage=storage, directions=directions, load_if_exists=True)
        (self.out / "jars").mkdir(exist_ok=True)  # after the database: a folder with jars/ alone is not a study
        stored = self.study.user_attrs.get("settings")
        identity = json.loads(json.dumps(self.s.identity()))
        if stored is None:
            self.study.set_user_attr("settings", self.s.identity())
        elif stored != identity:
            changed = sorted(k for k in stored if stored.get(k) != identity.get(k))
            raise ConfigError(self.out, "settings", ", ".join(changed),
                              "differ from the stored study's; give the same options to resume it, or another --out")
        return self

    @staticmethod
    def _circle(jar) -> float:
        """The reference jar's curved wall (the families keep its radius); a jar without one refused."""
        radius = next((v["radius"] for kind, v in jar.primitives if kind == "circle"), None)
        if radius is None:
            raise ConfigError("command line", "reference jar", jar.name, "has no circular wall [[profile]] type = "
                              "\"circle\" whose radius the designs could keep; give a jar or bowl with one")
        return radius

    # ------------------------------------------------------------ sampling
    def _sampler(self, n: int):
        import optuna

        seed = (self.s.seed * 1_000_003 + n) % 2**32
        if len(self.s.objectives) > 1:
            return optuna.samplers.NSGAIISampler(seed=seed, population_size=max(2, self.s.batch))
        return optuna.samplers.TPESampler(seed=seed)

    def distributions(self) -> dict:
        from optuna.distributions import FloatDistribution, IntDistribution

        out = {}
        for p in self.params.values():
            if p.name in self.s.fixed:
                continue
            out[p.name] = IntDistribution(int(p.lo), int(p.hi)) if p.integer else FloatDistribution(p.lo, p.hi)
        lo, hi = sorted(self.s.ratio)
        if lo != hi:
            out["ratio"] = FloatDistribution(lo, hi)
        return out

    def design_of(self, params: dict) -> tuple[dict, float]:
        """(family parameters, K) of a trial's parameters."""
        p = dict(self.s.fixed) | {k: v for k, v in params.items() if k != "ratio"}
        return p, params.get("ratio", self.s.ratio[0])

    def jar_path(self, number: int) -> Path:
        return self.out / "jars" / f"trial-{number:05d}.toml"

    def write_jar(self, number: int, params: dict, extra: list[str] = (), path: Path | None = None) -> Path:
        design, ratio = self.design_of(params)
        jar = self.base.jar
        comment = [f"Designed by `taimill design` (study {self.out.name}, trial {number}, family {self.s.family}).",
                   f"Parameters: {', '.join(f'{k} = {v:.6g}' for k, v in sorted(design.items()))}; K = {ratio:.6g}.",
                   *extra]
        text = families.jar_text(design, self.limits.radius * 1e3, jar.height * 1e3, jar.wall_material,
                                 f"{families.describe(design)} (design trial {number})", comment)
        path = path or self.jar_path(number)
        with whole_file(path, "jar file") as part:
            part.write_text(text)
        return path

    def check(self, number: int, params: dict) -> tuple[Path, list[str]]:
        """Write the trial's jar file and check it: (path, violations)."""
        from taimill.model.jars import load_jar

        path = self.write_jar(number, params)
        try:
            jar = load_jar(str(path.resolve()), "design")
        except ConfigError as err:
            return path, [f"not a valid jar: {err}"]
        return path, constraints.violations(jar, self.limits)

    # ------------------------------------------------------------ the loop
    def evaluated(self) -> list:
        return [t for t in self.study.get_trials(deepcopy=False) if "figures" in t.user_attrs and t.state.is_finished()]

    def run(self, trials: int, progress=None) -> None:
        """Continue the stored study until `trials` candidates are evaluated."""
        while True:
            plan = self.study.user_attrs.get("batch")
            if plan and not plan.get("done"):
                self._finish_batch(plan, progress)
            done = len(self.evaluated())
            if done >= trials:
                return
            plan = {"first": len(self.study.trials), "size": min(self.s.batch, trials - done), "done": False}
            self.study.set_user_attr("batch", plan)
            self._finish_batch(plan, progress)
            if len(self.evaluated()) == done:  # every design of the batch broke a constraint
                last = self.study.get_trials(deepcopy=False)[-1].user_attrs.get("violations") or ["?"]
                raise ConfigError(self.out, "constraints", f"{MAX_PRUNED * plan['size']} designs in a row",
                                  f"every one broke a constraint (the last: {last[0]}); loosen --tolerance, "
                                  "--min-wall or --fix")
    def _finish_batch(self, plan: dict, progress) -> None:
        from optuna.trial import TrialState

        def mine():
            return [t for t in self.study.get_trials(deepcopy=False) if t.number >= plan["first"]]

        for t in mine():
            if t.state != TrialState.RUNNING:
                continue
            if "violations" not in t.user_attrs or t.user_attrs.get("abandoned"):
                # killed while it was asked: its parameters may be incomplete; fail it and ask
                # again, with the seed of the same count of live trials (the same design)
                self.study._storage.set_trial_user_attr(t._trial_id, "abandoned", True)
                self.study.tell(t.number, state=_state("FAIL"))
            elif t.user_attrs["violations"]:
                self.study.tell(t.number, state=_state("PRUNED"))
            else:
                self.write_jar(t.number, t.params)
        if not any(t.state == TrialState.COMPLETE or "figures" in t.user_attrs for t in mine()):
            while True:
                ts = _live(mine())
                wanted = sum(not t.user_attrs.get("violations") for t in ts)
                pruned = len(ts) - wanted
                if wanted >= plan["size"] or pruned >= MAX_PRUNED * plan["size"]:
                    break
                self.study.sampler = self._sampler(len(_live(self.study.get_trials(deepcopy=False))))
                trial = self.study.ask(self.distributions())
                self._checked(trial.number, trial.params)
        running = [t for t in mine() if t.state == TrialState.RUNNING]
        if running:
            self.log(f"design: evaluating trials {running[0].number}-{running[-1].number} "
                     f"({len(running)} jars × {self.s.replicas} replicas)")
            cands = [(str(self.jar_path(t.number)), self.design_of(t.params)[1]) for t in running]
            results = evaluate(self.protocol, cands, workers=self.workers, scheduler=self.scheduler, progress=progress)
            for t, summaries in zip(running, results):
                self._tell(t.number, summaries)
        self.study.set_user_attr("batch", plan | {"done": True})

    def _checked(self, number: int, params: dict) -> None:
        """Write and check trial `number`'s jar; a violating one is told PRUNED, not run (TPE
        counts pruned trials among the worse ones, so it learns to avoid them)."""
        _, bad = self.check(number, params)
        self.study._storage.set_trial_user_attr(self._id(number), "violations", bad)
        if bad:
            self.study.tell(number, state=_state("PRUNED"))

    def _id(self, number: int) -> int:
        return self.study._storage.get_trial_id_from_study_id_trial_number(self.study._study_id, number)

    def _tell(self, number: int, summaries: list[dict]) -> None:
        import optuna

        figs = figures(summaries, self.s.objectives, self.s.floors)
        storage, tid = self.study._storage, self._id(number)
        storage.set_trial_user_attr(tid, "figures", {k: [m, s, v] for k, (m, s, v) in figs.items()})
        storage.set_trial_user_attr(tid, "status", sorted({s["status"] for s in summaries}))
        excess = [lo - figs[k][0] for k, lo in self.s.floors.items()]
        storage.set_trial_user_attr(tid, "floor_excess", excess)
        trial = optuna.trial.Trial(self.study, tid)
        for key, x in zip(self.s.floors, excess):  # ≤ 0 feasible; the samplers read it from the trial
            if f"constraints:floor {key}" not in storage.get_trial_system_attrs(tid):
                trial.set_constraint(f"floor {key}", x if math.isfinite(x) else 1.0)
        values = [figs[o.key][0] for o in self.s.objectives]
        if all(math.isfinite(v) for v in values) and all(s["status"] == "complete" for s in summaries):
            self.study.tell(number, values)
        else:
            self.study.tell(number, state=_state("FAIL"))


def _live(trials) -> list:
    """The trials not abandoned (asked when a kill −9 came, then failed and asked again)."""
    return [t for t in trials if not t.user_attrs.get("abandoned")]


def _state(name: str):
    from optuna.trial import TrialState

    return getattr(TrialState, name)


def feasible(trial) -> bool:
    return all(x <= 0 for x in trial.user_attrs.get("floor_excess", []))


def evaluate_references(study: Study, names: list[str], ratios: list[float], progress=None) -> dict:
    """The reference jars by the study's protocol at each of `ratios`: {name: {K: figures}}.
    Kept in references.json beside the study (computed once per settings)."""
    path = study.out / "references.json"
    identity = {"settings": study.s.identity(), "names": names, "ratios": ratios}
    if path.exists():
        stored = json.loads(path.read_text())
        if stored.get("identity") == json.loads(json.dumps(identity)):
            return stored["references"]
    if not names:
        return {}
    study.log(f"design: evaluating the references {', '.join(names)} at K = {', '.join(f'{k:g}' for k in ratios)}")
    cands = [(n, k) for n in names for k in ratios]
    results = evaluate(study.protocol, cands, workers=study.workers, scheduler=study.scheduler, progress=progress)
    out: dict = {}
    for (name, k), summaries in zip(cands, results):
        figs = figures(summaries, study.s.objectives, study.s.floors)
        out.setdefault(name, {})[f"{k:.10g}"] = {key: [m, s, v] for key, (m, s, v) in figs.items()}
    with whole_file(path, "references") as part:
        part.write_text(json.dumps({"identity": identity, "references": out}, indent=1))
    return out


def check_database(path: Path) -> None:
    """Refuse a study database that is not a sound SQLite file of an Optuna study, in
    one line that says how to recover. An empty file is SQLite's empty database (a
    study killed while creating it): a new study. A hot journal beside it (a kill -9
    mid-write) is rolled back by the check's own connection, as SQLite does."""
    if not os.path.lexists(path):
        return

    def bad(why):
        return damaged(path, why)

    if path.is_dir():
        raise bad("is a folder, not an SQLite file")
    try:
        with open(path, "rb") as f:
            head = f.read(len(SQLITE_HEADER))
    except OSError as err:
        raise bad(f"unreadable ({err.strerror or err})") from None
    if not head:
        return
    if head != SQLITE_HEADER:
        raise bad("not an SQLite database (its first bytes are not SQLite's header)")
    try:
        with contextlib.closing(sqlite3.connect(f"file:{path.resolve()}?mode=rw", uri=True, timeout=30)) as db:
            problems = [row[0] for row in db.execute("PRAGMA quick_check")]
            tables = {name for (name,) in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    except sqlite3.Error as err:
        raise bad(f"damaged ({err})") from None
    if problems != ["ok"]:
        raise bad(f"damaged ({one_line(problems[0])[:200]}{', …' if len(problems) > 1 else ''})")
    if tables and "studies" not in tables:
        raise bad("an SQLite database but not an Optuna study (no studies table)")


def damaged(path: Path, why: str) -> StoreError:
    """The one-line refusal of a damaged study database, saying how to recover."""
    out = path.parent
    return StoreError(path, "study database", f"{why}; move it away to start a new study, or restore it from a copy "
                      f"(the designs already written are in {out / 'jars'} and {out / 'best'})")
