"""Run summary (docs/outputs.md): the event-based stress-energy statistics over the
analysis window, dissipated power, the energy balance, g(r) and its randomness index,
the motion regime, the wear hot spot and the analytic landmarks (critical ratio,
single-ball hit energy).

`Summary` holds the accumulators and computes the keys; the summary sink of a run, the
analysis of a stored run (`taimill.analysis.run`) and the TUI's live window all use it,
so a key means the same wherever it is shown. NumPy only; running sums so a 24 s run
never holds its tables in memory.
"""

from __future__ import annotations

import math

import numpy as np

from taimill.analysis.events import EventStats
from taimill.analysis.regime import RegimeFeatures, class_note, map_regime, slip_ratio
from taimill.analysis.rungeometry import RunGeometry
from taimill.analysis.spatial import RadialDensity, WallMap
from taimill.analysis.spectra import summary as spectra_summary
from taimill.analysis.theory import single_ball_hit
from taimill.model.mechanisms import STRESS_MIN_UN
from taimill.schema import ENERGY_COLUMNS, MECHANISM_CLASSES, MECHANISM_COLUMNS, MECHANISM_KINDS, MECHANISM_PARTS


class EnergyLedger:
    """Energy balance from the cumulative ledger rows: E_kin + E_pot + E_el + dissipated
    must equal E_0 + drive work; errors relative to the largest |drive work| or
    dissipated energy so far, whichever is larger.

    Everything is counted from the first row seen: a stream that starts mid-run (a
    recording begun in the TUI at t = 20 s) balances from its own start, where the
    ledger's dissipated energy and drive work are already large."""

    def __init__(self, t0: float):
        self.t0 = t0
        self.first = self.window = self.last = None
        self.worst = 0.0
        self.scale = 0.0

    def add(self, block: dict) -> None:
        cols = [np.asarray(block[k]) for k in ENERGY_COLUMNS if k in block]
        if not len(cols[0]):
            return
        row = lambda i: np.array([c[i] for c in cols])  # noqa: E731  one ledger row, every column
        if self.first is None:
            self.first = row(0)
        if self.window is None and (cols[0] >= self.t0).any():
            self.window = row(int(np.argmax(cols[0] >= self.t0)))
        self.last = row(-1)
        # the imbalance and scale need five columns: not a copy of all of them per row
        rows = np.column_stack(cols[:6])
        self.worst = max(self.worst, float(np.abs(self.imbalance(rows)).max()))
        # the energy that went through the mill: its drive work, or what it dissipated
        # where that is more (a bed settling in a jar at rest does ≈ 0 work and would
        # otherwise give an error of 10³⁸)
        self.scale = max(self.scale, float(np.abs(rows[:, 4] - self.first[4]).max()),
                         float(np.abs(rows[:, 5] - self.first[5]).max()))

    def imbalance(self, rows):
        """(E_kin + E_pot + E_el + dissipated) - (E_0 + drive work), J, per row, with
        E_0, dissipated and drive work counted from the first row (for a stream that
        starts at t = 0 the ledger's first dissipated energy and work are exactly 0)."""
        e0 = self.first
        return ((rows[..., 1] + rows[..., 2] + rows[..., 3] + rows[..., 5])
                - (e0[1] + e0[2] + e0[3] + e0[5] + (rows[..., 4] - e0[4])))

    def result(self, tau: float) -> dict:
        if self.last is None:
            return {"dissipated_power": math.nan, "energy_balance_error": math.nan,
                    "energy_balance_worst": math.nan, "drive_work": math.nan}
        diss = (self.last[5] - self.window[5]) / tau if (tau > 0 and self.window is not None) else math.nan
        rel = (lambda x: x / self.scale if self.scale > 0 else math.nan)
        out = {"dissipated_power": float(diss), "energy_balance_error": float(rel(abs(self.imbalance(self.last)))),
               "energy_balance_worst": float(rel(self.worst)), "drive_work": float(self.last[4] - self.first[4])}
        if len(self.last) == len(ENERGY_COLUMNS) and self.window is not None and tau > 0:
            first = len(ENERGY_COLUMNS) - len(MECHANISM_COLUMNS)
            out.update(mechanism_powers((self.last[first:] - self.window[first:]) / tau))
        return out


ROUNDING = 1e-6  #: relative to the total dissipated power: a part below 0 by less is 0


def mechanism_powers(power: np.ndarray) -> dict:
    """Summary keys of the dissipated power by mechanism (W), from one value per
    schema MECHANISM_COLUMNS entry: the nested table, its sums by class, part and kind,
    and the largest single mechanism (`main_sink`) with its share."""
    p = np.asarray(power, dtype=float).reshape(len(MECHANISM_KINDS), len(MECHANISM_CLASSES), len(MECHANISM_PARTS))
    # each part is a difference of two running sums: one that dissipated nothing can come
    # out a rounding error below 0 (−2.8·10⁻⁹ W seen); dissipation is never negative
    p = np.where((p < 0) & (p >= -ROUNDING * np.abs(p).sum()), 0.0, p)
    out = {"dissipation_by_mechanism": {k: {c: {q: float(p[i, j, l]) for l, q in enumerate(MECHANISM_PARTS)}
                                            for j, c in enumerate(MECHANISM_CLASSES)}
                                        for i, k in enumerate(MECHANISM_KINDS)}}
    out.update({f"dissipated_power_{c}": float(p[:, j].sum()) for j, c in enumerate(MECHANISM_CLASSES)})
    out.update({f"dissipated_power_{q}": float(p[..., l].sum()) for l, q in enumerate(MECHANISM_PARTS)})
    out.update({f"dissipated_power_{k}": float(p[i].sum()) for i, k in enumerate(MECHANISM_KINDS)})
    total = float(p.sum())
    i, j, l = np.unravel_index(int(np.argmax(p)), p.shape)
    where = "ball-ball contacts" if MECHANISM_KINDS[i] == "ball_ball" else f"contacts with the {MECHANISM_KINDS[i]}"
    out["main_sink"] = {"mechanism": f"{MECHANISM_PARTS[l]} in {MECHANISM_CLASSES[j]} {where}",
                        "power": float(p[i, j, l]), "share": float(p[i, j, l] / total) if total > 0 else math.nan}
    return out


# Friction's share of the dissipated power at and above which a charge is friction-led:
# its impacts' normal damping takes a tenth or less. Measured (5 s runs, window 2–5 s):
# the thesis' P 4 with steel friction around its impact maximum, CY K = −1.4 … −2.6,
# 89, 86, 83, 79 % and HM K = −2.2 65 %; at its ends CY K = −1.0 90.1 % and the pinned
# ring at −3.6 91 % (low stress energies in the thesis too); standard-gear mills (K = −1)
# 94 % (P 7, 45 ml silicon nitride, powder set, 300 rpm: a rolling bed), 97.6 % (PM 100,
# zirconia: a hopping bed) and 100 % (powder-coated beds without impacts); the CY
# fluorite sliding bed 97.4 %.
FRICTION_LED = 0.9


def power_lead(energy: dict) -> dict:
    """What carries a run's dissipated power (the energy keys, W): `friction_share`, the
    friction (shear) part of the dissipated power, and `power_led`: "friction-led" when
    it is at least FRICTION_LED, else "impact-led"; None without dissipation."""
    total, friction = energy.get("dissipated_power", math.nan), energy.get("dissipated_power_friction", math.nan)
    if not (isinstance(total, float) and total > 0 and math.isfinite(friction)):
        return {"friction_share": math.nan, "power_led": None}
    share = min(max(friction / total, 0.0), 1.0)  # rounding of the ledger's parts
    return {"friction_share": share, "power_led": "friction-led" if share >= FRICTION_LED else "impact-led"}


def regime_class(regime: dict, energy: dict, g: RunGeometry, n_balls: int) -> dict:
    """The run's regime split as the regime map splits it (taimill.analysis.regime):
    `wall_lag` (from the criteria), `slip_ratio` of the persistent side-wall friction
    power, `regime_class`, one of MAP_REGIMES (cascading, cataracting, hopping bed,
    pinned ring, sliding bed, rolling bed) or "unknown", and `regime_class_note`, a
    line when that class rests on a criterion near its threshold (else None)."""
    side = (energy.get("dissipation_by_mechanism") or {}).get("side", {}).get("persistent", {})
    row = {"plate_rpm": g.drive.plate_rpm, "mu_d_wall": g.wall_mu_d, "balls": n_balls, "ball_mass": g.ball_mass,
           "plate_radius": g.plate_radius, "jar_radius": g.jar_radius, "ratio": g.ratio,
           "dissipated_power_side_persistent_friction": side.get("friction", math.nan)}
    slip = slip_ratio(row)
    crit = regime.get("regime_criteria", {})
    lag = crit.get("wall_lag", math.nan)
    label = map_regime(regime.get("regime", "unknown"), slip, lag, crit.get("flight_fraction", math.nan),
                       crit.get("impact_chord", math.nan))
    return {"regime_class": label, "regime_class_note": class_note(label, crit, slip), "wall_lag": lag, "slip_ratio": slip}


def mill_power(event_stats: dict, energy: dict, stations: int | None) -> dict:
    """The whole mill's impact and dissipated power (W): a run simulates one jar, the
    mill turns `stations` alike; {} when the station count is not known."""
    if not stations:
        return {}
    return {"stations": stations, "impact_power_mill": stations * event_stats.get("impact_power", math.nan),
            "dissipated_power_mill": stations * energy.get("dissipated_power", math.nan)}


class Summary:
    """The accumulators of the run summary over the window t0 ≤ t < t1 (s; t1 = inf for a
    stream, whose end is not known yet) and the summary keys they give.

    geom: the run's RunGeometry; n_balls and radii (m) as a sink's start() gets them.
    min_un: m/s, the headline statistics count stress events, events with at least this
    onset normal speed (model/mechanisms.py). whole_run=False leaves out what only a
    run's summary reports (the all-contacts twin, g(r), the wall map, the single-ball
    hit): set up for every readout of a live window they would cost more than the window
    itself. regime=False leaves out the regime, three quarters of a live window's cost
    (contacts of every feature frame).

    Feed the stream's blocks in the order they come: the regime sums its pieces in the
    order they were first reached."""

    def __init__(self, geom: RunGeometry, n_balls: int, radii, t0: float, t1: float = math.inf, *,
                 min_un: float = STRESS_MIN_UN, whole_run: bool = True, regime: bool = True):
        self.geom, self.n_balls, self.t0, self.whole_run = geom, n_balls, t0, whole_run
        self.events_total = 0
        self.stats = EventStats(t0, t1, min_un)
        self.ledger = EnergyLedger(t0)
        self.regime = RegimeFeatures(geom, radii, t0) if regime else None
        self.all_contacts = EventStats(t0, t1) if whole_run else None
        self.density = RadialDensity(geom, t0) if whole_run else None
        self.wall = WallMap(geom, t0, t1=t1) if whole_run else None
        self.last_spectra = None  #: the kernel's energy spectra (taimill.model.spectra) at the last drain

    def events(self, block: dict) -> None:
        self.events_total += len(block["t_start"])
        self.stats.add(block)
        if self.regime:
            self.regime.events(block)
        if self.whole_run:
            self.all_contacts.add(block)
            self.wall.add(block)

    def frames(self, block: dict) -> None:
        if self.regime:
            self.regime.frames(block)
        if self.whole_run:
            self.density.add(block)

    def energy(self, block: dict) -> None:
        self.ledger.add(block)

    def spectra(self, spectra) -> None:
        self.last_spectra = spectra

    def parts(self, t1: float) -> dict:
        """The summary over [t0, t1] (t1: s, the window's end) by accumulator, named as
        `taimill analyse` reports them: `event_estimator`, `all_contacts_estimator`,
        `energy` (the ledger's keys), `randomness_index`, `regime` (the regime keys),
        `wear_hot_spot`, `critical_ratio`, `single_ball_hit`, `mill_power` (the whole
        mill's, when the config names its stations); those not accumulated are left
        out. The regime keys include the regime_class split."""
        tau = max(t1 - self.t0, 0.0)
        g = self.geom
        out = {"event_estimator": self.stats.result(tau, g.volume, self.n_balls), "energy": self.ledger.result(tau)}
        if self.regime:
            out["regime"] = self.regime.result()
            out["regime"].update(regime_class(out["regime"], out["energy"], g, self.n_balls))
        out["mill_power"] = mill_power(out["event_estimator"], out["energy"], g.stations)
        if self.whole_run:
            out["all_contacts_estimator"] = self.all_contacts.result(tau, g.volume, self.n_balls)
            out["randomness_index"] = self.density.randomness_index
            out["wear_hot_spot"] = self.wall.hot_spot(tau) if tau > 0 else {}
            out["single_ball_hit"] = single_ball_hit(g.plate_radius, g.jar_radius, g.ball_radius, g.plate.end, g.ratio,
                                                     g.ball_mass)
        out["critical_ratio"] = g.critical_ratio
        if self.whole_run and self.last_spectra is not None:
            out["spectra"] = spectra_summary(self.last_spectra)
        return out

    def result(self, t1: float) -> dict:
        """The summary keys (docs/outputs.md) over [t0, t1] (t1: s): the stress-event
        statistics, `all_contacts`, `events_total`, the energy keys, the whole mill's
        power (`stations`, `impact_power_mill`, `dissipated_power_mill`, when the config
        names its stations), `randomness_index`,
        the regime keys with `side_wall_fraction`, `wear_hot_spot`, `critical_ratio`,
        `single_ball_se`, `analysis_window` and `sim_seconds`, in that order; those not
        accumulated are left out."""
        p = self.parts(t1)
        out = p["event_estimator"]
        if self.whole_run:
            out["all_contacts"] = p["all_contacts_estimator"]
            out["events_total"] = self.events_total
        out.update(p["energy"])
        out.update(power_lead(p["energy"]))
        out.update(p["mill_power"])
        if self.whole_run:
            out["randomness_index"] = p["randomness_index"]
        if self.regime:
            out.update(p["regime"])
            if self.whole_run:
                out["side_wall_fraction"] = p["regime"]["regime_criteria"].get("wall_fraction", math.nan)
        if self.whole_run:
            out["wear_hot_spot"] = p["wear_hot_spot"]
        out["critical_ratio"] = p["critical_ratio"]
        if self.whole_run:
            out["single_ball_se"] = p["single_ball_hit"]["se"]
        if "spectra" in p:
            out["spectra"] = p["spectra"]
        out.update(analysis_window=[self.t0, t1], sim_seconds=t1)
        return out


class SummarySink:
    """Sink computing the summary keys (docs/outputs.md) over the analysis window [t0, end).

    analysis_start, duration: s. The geometry comes from the config given to start();
    the jar and ball radii arguments are accepted for older callers and not needed.
    min_un: m/s, the headline statistics count stress events, events with at least
    this onset normal speed (model/mechanisms.py); `all_contacts` counts every event."""

    def __init__(self, analysis_start: float, duration: float, jar_radius=None, ball_radius=None, *,
                 min_un: float = STRESS_MIN_UN):
        self.t0, self.duration, self.min_un = analysis_start, duration, min_un

    def start(self, config, n_balls, radii):
        self.summary = Summary(RunGeometry.from_config(config, radii), n_balls, radii, self.t0, min_un=self.min_un)

    def events(self, block):
        self.summary.events(block)

    def frames(self, block):
        self.summary.frames(block)

    def energy(self, block):
        self.summary.energy(block)

    def spectra(self, spectra):
        self.summary.spectra(spectra)

    def finish(self, summary, status):
        pass

    def result(self, sim_seconds: float, wall_seconds: float) -> dict:
        out = self.summary.result(sim_seconds)
        out.update(wall_seconds=wall_seconds, realtime_factor=sim_seconds / wall_seconds if wall_seconds > 0 else math.nan)
        return out
