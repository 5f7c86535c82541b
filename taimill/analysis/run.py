"""Analyse a stored run (docs/outputs.md): every quantity from the committed rows of its
tables, so a store left by a killed run is analysed up to its commit markers."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from taimill.analysis.events import EventStats
from taimill.analysis.rungeometry import RunGeometry
from taimill.analysis.sampled import SampledStats
from taimill.analysis.spatial import RadialDensity, WallMap, contact_map
from taimill.analysis.spectra import event_keys as spectra_event_keys
from taimill.analysis.summary import Summary, power_lead
from taimill.errors import ConfigError, StoreError
from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.model.spectra import from_rows
from taimill.store.chunks import why
from taimill.store.run import RunStore, open_run
from taimill.schema import with_units


@dataclass
class RunAnalysis:
    store: RunStore
    geom: RunGeometry
    t0: float  #: s, start of the analysis window
    t1: float  #: s, last committed frame
    summary: Summary  #: the run summary's accumulators over the window (not the store's own summary)
    sampled: dict | None
    sampled_error: str | None = None
    contacts: dict = field(default_factory=dict)

    @property
    def tau(self) -> float:
        return max(self.t1 - self.t0, 0.0)

    @functools.cached_property
    def parts(self) -> dict:
        """The summary's parts over the window (Summary.parts), computed once: the
        accumulators are complete when `analyse` returns."""
        parts = self.summary.parts(self.t1)
        if not self.events_stored:  # the event statistics from the spectra: the same numbers, exact to 2⁻²⁴
            sp = self.summary.last_spectra
            parts["event_estimator"] = spectra_event_keys(sp, self.tau, self.geom.volume, self.geom.n_balls)
            parts["all_contacts_estimator"] = spectra_event_keys(sp, self.tau, self.geom.volume, self.geom.n_balls,
                                                                 stress_only=False)
        return parts

    @property
    def events_stored(self) -> bool:
        """The run kept one row per event (else only their spectra: outputs.events)."""
        return (self.store.config or {}).get("events_output", "rows") == "rows"

    @property
    def event(self) -> EventStats:
        """The event estimator over stress events."""
        return self.summary.stats

    @property
    def all_contacts(self) -> EventStats:
        """The event estimator over every event."""
        return self.summary.all_contacts

    @property
    def density(self) -> RadialDensity:
        return self.summary.density

    @property
    def wall(self) -> WallMap:
        return self.summary.wall

    @property
    def energy(self) -> dict:
        """The energy keys (dissipated power, its mechanisms, the balance, drive work)."""
        return self.parts["energy"]

    def quantities(self) -> dict:
        """Everything as one JSON-able dict; each estimator labelled; the units of its
        numbers in `units` (taimill.schema.SUMMARY_UNITS)."""
        g, p, energy = self.geom, self.parts, self.energy
        edges = self.density.edges
        return with_units({
            "status": self.store.status if self.store.summary is not None else
            f"incomplete (status '{self.store.status}', no final summary: killed or still running)",
            "analysis_window": [self.t0, self.t1],
            "ratio": g.ratio, "plate_rpm": g.drive.plate_rpm,
            "event_estimator": p["event_estimator"],
            "all_contacts_estimator": p["all_contacts_estimator"],
            **{k: v for k, v in energy.items() if k.startswith(("dissipat", "main_sink"))},
            "sampled_estimator": self.sampled if self.sampled is not None else {"error": self.sampled_error},
            "dissipated_power": energy["dissipated_power"],
            "energy_balance_error": energy["energy_balance_error"],
            "drive_work": energy["drive_work"],
            **power_lead(energy),
            **p["mill_power"],
            "g_r": {"r_edges": edges.tolist(), "g": self.density.g.tolist()},
            "randomness_index": p["randomness_index"],
            **p["regime"],
            "wear_hot_spot": p["wear_hot_spot"],
            "wall_energy": {"impact": self.wall.total("impact"), "friction": self.wall.total("friction")},
            "critical_ratio": p["critical_ratio"],
            "single_ball_hit": p["single_ball_hit"],
            "spectra": p.get("spectra"),
            "events_stored": "rows" if self.events_stored else
            "spectra only (outputs.events = \"spectra\"): no wall map, contact map or speed distributions",
        })


def analyse(run, *, analysis_start: float | None = None, min_un: float = STRESS_MIN_UN,
            sampling_rate: float = 100.0, source: str = "command line") -> RunAnalysis:
    """run: a path or RunStore. analysis_start (s) defaults to the start of the store's
    own window (`window_start`); min_un (m/s): the event estimator counts stress events,
    events with at least this onset normal speed (model/mechanisms.py), and an
    all-contacts twin every event; sampling_rate (1/s) for the sampled estimator."""
    store = run if isinstance(run, RunStore) else open_run(run)
    config = store.config
    if not config:
        raise ConfigError(source, "RUN", getattr(store.group.store, "root", store.group), "a taimill run store (no config attribute)")
    geom = geometry(store)
    frames, events, energy = store.frames, store.events, store.energy
    if not len(frames["time"]):
        raise StoreError(store.where, "trajectory", f"no committed frame (status {store.status!r}): nothing to analyse")
    t_end = float(frames["time"][-1])
    t0 = window_start(store, geom) if analysis_start is None else analysis_start
    if analysis_start is None and store.analysis_window is None and t0 >= t_end:
        t0 = 0.0  # a writer stopped before its window began: what there is, from the start
    if not 0 <= t0 < max(t_end, 1e-300):
        raise ConfigError(source, "--analysis-start", t0, f"[0, {t_end:g}) s, the stored run ends at {t_end:g} s")
    if min_un < 0:
        raise ConfigError(source, "--min-un", min_un, ">= 0 (m/s)")
    # the window ends at the last committed frame: its estimators and wall map leave out later events
    summary = Summary(geom, geom.n_balls, store.radii, t0, t_end, min_un=min_un)
    summary.frames(frames)
    summary.events(events)
    rows_kept = config.get("events_output", "rows") == "rows"
    if rows_kept:  # the spectra of this window, binned from the rows as the kernel bins them
        summary.spectra(from_rows(events, t0, t_end, min_un))
    else:
        sp = store.spectra  # StoreError if missing or damaged, never zeros
        if t0 != sp.start or min_un != sp.stress_un:
            raise ConfigError(source, "--analysis-start" if t0 != sp.start else "--min-un", t0 if t0 != sp.start else min_un,
                              f"this run kept only its events' spectra (outputs.events = \"spectra\"), from {sp.start:g} s "
                              f"with u̇n ≥ {sp.stress_un:g} m/s for stress events: analyse it over that window")
        summary.spectra(sp)
    if len(energy["time"]):
        summary.energy(energy)
    sampled, error = None, None
    stored_rate = _stored_rate(frames["time"], config)
    try:
        s = SampledStats(geom, store.radii, stored_rate, sampling_rate, t0, t_end, source)
        s.add(frames)
        sampled = s.result(t_end - t0, geom.volume)
    except ConfigError as err:
        if sampling_rate != 100.0:
            raise
        error = str(err)
    return RunAnalysis(store=store, geom=geom, t0=t0, t1=t_end, summary=summary, sampled=sampled, sampled_error=error,
                       contacts=contact_map(geom, events, t0))


def geometry(store: RunStore) -> RunGeometry:
    """The run's geometry from its config; StoreError if the config is not a run's."""
    try:
        return RunGeometry.from_config(store.config or {}, store.radii)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        raise StoreError(store.where, "attrs.config", f"not the config of a taimill run ({why(err)})") from None


def window_start(store: RunStore, geom: RunGeometry) -> float:
    """Start (s) of the window the store's own summary covers: its `analysis_window`;
    for a store whose writer never finished, the start its config implies."""
    window = store.analysis_window
    return float(window[0]) if window is not None else geom.analysis_start


def _stored_rate(times: np.ndarray, config: dict) -> float:
    if len(times) > 2:
        return 1.0 / float(np.median(np.diff(times)))
    return float(config.get("trajectory_rate", 100.0))
