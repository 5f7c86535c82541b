"""How `taimill design` evaluates a jar: objectives read from the run summary, and the
protocol — R short runs (seeds seed … seed+R−1, the same seeds for every jar) of the
user's preset with the jar and K swapped in, run as one batch on the sweep machinery
(taimill.runs.sweep / executors: local spawned processes or a dask cluster). A jar's
figure is the mean over its replicas, its spread the replicas' sample standard
deviation (ddof = 1)."""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path

from taimill.errors import ConfigError, WorkerDied
from taimill.schema import SUMMARY_UNITS

ALIASES = {"wear_concentration": "wear_hot_spot.concentration", "wear_power_per_area": "wear_hot_spot.power_per_area"}
DIRECTIONS = {"max": "maximize", "min": "minimize"}


@dataclass(frozen=True)
class Objective:
    """A summary figure (key, or nested.key) and whether to maximise or minimise it."""

    key: str
    direction: str  #: "maximize" or "minimize"

    @property
    def label(self) -> str:
        return f"{self.key}:{'max' if self.direction == 'maximize' else 'min'}"

    @property
    def unit(self) -> str:
        return SUMMARY_UNITS.get(self.key.rpartition(".")[2], "")


def _summary_key(text: str, option: str, whole: str) -> str:
    key = ALIASES.get(text, text)
    if key.rpartition(".")[2] not in SUMMARY_UNITS or key in ("points", "stations"):
        known = "impact_power_normal, normal_fraction, impact_power, mean_se_normal, dissipated_power, wear_concentration, …"
        raise ConfigError("command line", option, whole, f"KEY must name a number of the run summary ({known}; "
                          "docs/outputs.md), nested keys as wear_hot_spot.concentration")
    return key


def parse_objective(text: str) -> Objective:
    """'impact_power_normal:max' → Objective (':max' is the default)."""
    key, _, how = text.partition(":")
    how = how or "max"
    if how not in DIRECTIONS:
        raise ConfigError("command line", "--objective", text, "KEY:max or KEY:min")
    return Objective(_summary_key(key.strip(), "--objective", text), DIRECTIONS[how])


def parse_floor(text: str) -> tuple[str, float]:
    """'impact_power=2.5' → ("impact_power", 2.5): candidates whose mean is below are infeasible."""
    key, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not sep or not math.isfinite(number):
        raise ConfigError("command line", "--floor", text, "KEY=VALUE with a finite number, e.g. impact_power=2.5 (W)")
    return _summary_key(key.strip(), "--floor", text), number


def value_of(summary: dict, key: str) -> float:
    """The summary's number at `key` (dots go into nested objects); NaN if absent."""
    v = summary
    for part in key.split("."):
        v = v.get(part) if isinstance(v, dict) else None
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan


def mean_spread(values: list[float]) -> tuple[float, float | None]:
    """(mean, sample standard deviation) of the replicas. One replica has no spread: it
    is None (unknown), never 0, which would let any difference count as significant."""
    values = [v for v in values if math.isfinite(v)]
    if not values:
        return math.nan, math.nan
    return statistics.fmean(values), statistics.stdev(values) if len(values) > 1 else None


@dataclass
class Protocol:
    """The runs that make one jar's figures: the preset with `overrides` (duration,
    analysis start, …), the jar and K swapped in, replicas seeds seed … seed+R−1. On a
    fixed-gear mill (`fixed_gear`) K is the gear's and is not passed (the loader refuses a
    K set on such a mill). The reference bowl of a jar_volume_ml override is the study's
    jar size only: the jar swapped in replaces it."""

    preset: str
    overrides: dict = field(default_factory=dict)
    replicas: int = 3
    seed: int = 1
    fixed_gear: bool = False

    def presets(self, jar: str, ratio: float) -> list:
        from taimill.model.preset import load_preset

        jar = str(Path(jar).resolve()) if jar.endswith(".toml") else jar
        base = {k: v for k, v in self.overrides.items() if k != "jar_volume_ml"} | {"jar": jar}
        if not self.fixed_gear:
            base["ratio"] = ratio
        return [load_preset(self.preset, base | {"seed": self.seed + r}) for r in range(self.replicas)]


def evaluate(protocol: Protocol, candidates: list[tuple[str, float]], *, workers=None, scheduler=None,
             progress=None) -> list[list[dict]]:
    """Run every (jar, K) candidate's replicas as one sweep; their summaries per candidate,
    in order. Every preset is loaded (validated) before any run starts."""
    import os

    from taimill.runs.executors import Job, PoolBroken, run_dask, run_local
    from taimill.runs.signals import sigterm_interrupts
    from taimill.runs.sweep import Progress, auto_batch, chunks

    jobs, owner = [], []
    for c, (jar, ratio) in enumerate(candidates):
        for p in protocol.presets(jar, ratio):
            owner.append(c)
            jobs.append(Job(len(jobs), p))
    out: list[list[dict]] = [[] for _ in candidates]
    if not jobs:
        return out
    workers = workers or os.cpu_count() or 1
    todo = chunks(jobs, 1 if scheduler else auto_batch(len(jobs), workers))
    prog = Progress(todo, progress)
    summaries = {}
    with sigterm_interrupts():
        stream = (run_dask(todo, scheduler, False, prog) if scheduler
                  else run_local(todo, min(workers, len(todo)), False, prog))
        try:
            for results in stream:
                for r in results:
                    summaries[r.index] = r.summary | {"status": r.status}
        except PoolBroken as broken:
            who = "; ".join(f"worker {pid} {how}" for pid, how in broken.dead) or "a worker process died"
            raise WorkerDied(f"design: {who}; the study's finished trials are stored, the same command resumes it") from None
        finally:
            stream.close()
    for i in sorted(summaries):
        out[owner[i]].append(summaries[i])
    return out


def figures(summaries: list[dict], objectives, floors: dict) -> dict:
    """{key: (mean, spread, [replica values])} for the objectives' and floors' keys."""
    keys = list(dict.fromkeys([o.key for o in objectives] + list(floors)))
    out = {}
    for key in keys:
        values = [value_of(s, key) for s in summaries]
        out[key] = (*mean_spread(values), values)
    return out
