"""Heat: what the dissipated power does to the temperatures of the balls, the powder
and the jar (docs/outcome.md, "Heat").

A lumped model: each body is one temperature (a node with a heat capacity C, J/K);
nodes exchange heat through conductances (W/K) and lose it to the mill chamber's air
through their own conductance to ambient. With x = T − T_ambient the model is the
linear system C dx/dt = q − K x, K = the conductance (Laplacian) matrix plus the losses
on its diagonal. For a power q that is constant over an interval, the system is solved
exactly (no time step): in the coordinates y = C^½ x, K becomes the symmetric
M = C^-½ K C^-½ = V Λ Vᵀ and every mode relaxes on its own, z_i(t) = z_i e^{-λ_i t} +
r_i (1 − e^{-λ_i t}) / λ_i. A mill programme (run, pause, run, …) is a chain of such
intervals. The heat lost to the air is integrated in closed form too, so the ledger
heat in = stored + lost is a check of the solution, not a definition.

Everything here is pure: numbers in, numbers out; the CLI (taimill/cli/heat.py) builds
the network from a run (`network_of_run`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

NODES = ("balls", "powder", "jar")

# Dry air at 300 K and 1 atm: Incropera & DeWitt, Fundamentals of Heat and Mass
# Transfer, Table A.4. The chamber air is warmer than that under a long programme;
# the properties change by a few % over tens of kelvin.
AIR_K = 26.3e-3  #: W/(m K)
AIR_NU = 15.89e-6  #: m²/s, kinematic viscosity
AIR_PR = 0.707


@dataclass(frozen=True)
class Network:
    """Lumped nodes: heat capacities `C` (J/K), conductances `G` between nodes (W/K,
    symmetric, zero diagonal) and `loss` to ambient per node (W/K)."""

    names: tuple
    C: np.ndarray
    G: np.ndarray
    loss: np.ndarray
    notes: dict = field(default_factory=dict, compare=False)

    @property
    def K(self) -> np.ndarray:
        return np.diag(self.G.sum(axis=1) + self.loss) - self.G


@dataclass(frozen=True)
class Modes:
    """The decoupled system: rates λ (1/s), eigenvectors V of M and C^-½ as a vector."""

    lam: np.ndarray
    V: np.ndarray
    s: np.ndarray

    def to_z(self, x, q):
        """Modal state z and forcing r for node state x (K) and power q (W)."""
        return self.V.T @ (np.asarray(x, float) / self.s), self.V.T @ (self.s * np.asarray(q, float))

    def to_x(self, z):
        return self.s * (self.V @ z)


def modes(net: Network) -> Modes:
    """The modes of `net`: all λ > 0 when every node reaches ambient through some
    path (else the heat has nowhere to go and no steady state exists)."""
    s = 1.0 / np.sqrt(net.C)
    M = s[:, None] * net.K * s[None, :]
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    if not lam.min() > 0:
        raise ValueError("no path to ambient: the network has no steady state")
    return Modes(lam, V, s)


def _phi(lam, t):
    """(1 − e^{-λt})/λ, exact for small λt."""
    return -np.expm1(-lam * t) / lam


def advance(m: Modes, x0, q, t) -> np.ndarray:
    """Node temperatures above ambient after time t (s) at constant power q (W), from x0."""
    z, r = m.to_z(x0, q)
    return m.to_x(z * np.exp(-m.lam * t) + r * _phi(m.lam, t))


def lost_over(m: Modes, net: Network, x0, q, t) -> float:
    """J lost to ambient over [0, t]: Σ loss_i ∫ x_i dt, integrated in closed form."""
    z, r = m.to_z(x0, q)
    ph = _phi(m.lam, t)
    integral = z * ph + r * (t - ph) / m.lam
    return float(net.loss @ m.to_x(integral))


def steady(net: Network, q) -> np.ndarray:
    """Temperatures above ambient at constant power q, after every transient."""
    return np.linalg.solve(net.K, np.asarray(q, float))


@dataclass(frozen=True)
class Programme:
    """The mill's controller: run `run_s`, pause `pause_s`, repeated for `total_s`
    (pause 0: it runs without stopping)."""

    run_s: float
    pause_s: float
    total_s: float

    def phases(self):
        """(start, length, on) over the whole programme, the last phase cut at total_s."""
        t, out = 0.0, []
        while t < self.total_s - 1e-12:
            for length, on in ((self.run_s, True), (self.pause_s, False)):
                if length <= 0 or t >= self.total_s - 1e-12:
                    continue
                n = min(length, self.total_s - t)
                out.append((t, n, on))
                t += n
        return out


def periodic(net: Network, q_on, prog: Programme) -> dict:
    """The programme's periodic state, reached after many cycles: the temperatures at
    the end of a run phase (the cycle's peak for a warming jar) and of a pause."""
    m = modes(net)
    if prog.pause_s <= 0:
        x = steady(net, q_on)
        return {"end_of_run": x, "end_of_pause": x}
    zero = np.zeros(len(net.C))
    # x_pause_end = A_off (A_on x + b_on), each A and b from `advance` at zero power / start
    n = len(net.C)
    A_on = np.column_stack([advance(m, e, zero, prog.run_s) for e in np.eye(n)])
    A_off = np.column_stack([advance(m, e, zero, prog.pause_s) for e in np.eye(n)])
    b_on = advance(m, zero, q_on, prog.run_s)
    x_pause = np.linalg.solve(np.eye(n) - A_off @ A_on, A_off @ b_on)
    return {"end_of_run": A_on @ x_pause + b_on, "end_of_pause": x_pause}


def cycle_max(net: Network, q_on, prog: Programme, points: int = 400) -> np.ndarray:
    """Each node's highest temperature above ambient over a cycle of the periodic
    state (on a fine grid). Started from ambient, no node ever exceeds it: e^{-C⁻¹K t}
    has no negative entries (heat only flows from warm to cold), so the cycles' states
    rise monotonically towards the periodic one and stay below it."""
    m = modes(net)
    per = periodic(net, q_on, prog)
    x, q = per["end_of_pause"], np.asarray(q_on, float)
    if prog.pause_s <= 0:
        return per["end_of_run"]
    top = np.maximum(per["end_of_run"], x)
    for length, power, start in ((prog.run_s, q, x), (prog.pause_s, np.zeros(len(q)), per["end_of_run"])):
        for t in np.linspace(0.0, length, points):
            top = np.maximum(top, advance(m, start, power, t))
    return top


@dataclass
class History:
    """Temperatures above ambient at `times` (s), one column per node, and the energy
    ledger over the programme: heat_in (J) = stored + lost, `residual` their gap
    relative to heat_in."""

    times: np.ndarray
    x: np.ndarray
    heat_in: float
    stored: float
    lost: float

    @property
    def residual(self) -> float:
        return abs(self.heat_in - self.stored - self.lost) / max(abs(self.heat_in), 1e-300)


def simulate(net: Network, q_on, prog: Programme, x0=None, samples: int = 20) -> History:
    """The temperatures over the programme, exact at every sample (`samples` points
    per phase besides its ends), with the energy ledger."""
    m = modes(net)
    n = len(net.C)
    q_on = np.asarray(q_on, float)
    x = np.zeros(n) if x0 is None else np.asarray(x0, float)
    start = x.copy()
    times, rows = [0.0], [x.copy()]
    heat_in = lost = 0.0
    for t0, length, on in prog.phases():
        q = q_on if on else np.zeros(n)
        for f in np.linspace(0.0, 1.0, samples + 2)[1:]:
            times.append(t0 + f * length)
            rows.append(advance(m, x, q, f * length))
        heat_in += float(q.sum()) * length
        lost += lost_over(m, net, x, q, length)
        x = rows[-1]
    stored = float(net.C @ (x - start))
    return History(np.asarray(times), np.asarray(rows), heat_in, stored, lost)


def first_crossing(net: Network, q_on, prog: Programme, node: int, limit: float, x0=None) -> float | None:
    """s until node `node` first rises to `limit` K above ambient (None: never within
    the programme). Found on a fine grid of each phase, then by bisection."""
    m = modes(net)
    n = len(net.C)
    if x0 is None and cycle_max(net, q_on, prog)[node] < limit:
        return None  # from ambient, no node ever exceeds the periodic cycle (below)
    x = np.zeros(n) if x0 is None else np.asarray(x0, float)
    if x[node] >= limit:
        return 0.0
    for t0, length, on in prog.phases():
        q = np.asarray(q_on, float) if on else np.zeros(n)
        grid = np.linspace(0.0, length, 201)
        vals = np.array([advance(m, x, q, s)[node] for s in grid])
        above = np.flatnonzero(vals >= limit)
        if above.size:
            lo, hi = grid[above[0] - 1], grid[above[0]]
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if advance(m, x, q, mid)[node] < limit else (lo, mid)
            return t0 + hi
        x = advance(m, x, q, length)
    return None


# ------------------------------------------------------------------ heat transfer


def nu_rotating_cylinder(re: float) -> float:
    """Nusselt number of a cylinder spinning about its axis in still air, Re = ω D²/ν:
    Nu_D = 0.133 Re^⅔ Pr^⅓ (Kays & Bjorklund, Trans. ASME 80, 1958, as textbooks
    quote it), stated for Re < 4.3·10⁵ and 0.7 < Pr < 670."""
    return 0.133 * re ** (2.0 / 3.0) * AIR_PR ** (1.0 / 3.0)


def nu_cross_flow(re: float) -> float:
    """Nusselt number of a cylinder in cross flow (Churchill & Bernstein 1977;
    as in Incropera & DeWitt), Re·Pr > 0.2."""
    pr = AIR_PR
    return 0.3 + 0.62 * re**0.5 * pr ** (1 / 3) / (1 + (0.4 / pr) ** (2 / 3)) ** 0.25 * (1 + (re / 282000) ** 0.625) ** 0.8


def nu_sphere(re: float) -> float:
    """Nusselt number of a sphere in a gas (Ranz & Marshall 1952): 2 + 0.6 Re½ Pr⅓;
    2 is pure conduction into still gas."""
    return 2.0 + 0.6 * re**0.5 * AIR_PR ** (1 / 3)


def h_jar(diameter: float, spin: float, orbit_speed: float) -> dict:
    """W/(m² K) from the jar's outside to the chamber air taken at rest: the spin about
    its own axis (`spin` rad/s, absolute) and its path round the sun wheel (`orbit_speed`
    m/s) combined as Nu³ = Nu_spin³ + Nu_orbit³ (Churchill's blending of two forced
    flows). The air is really dragged round by the plate: the true h is likely lower."""
    nu_spin = nu_rotating_cylinder(abs(spin) * diameter**2 / AIR_NU)
    nu_orbit = nu_cross_flow(max(orbit_speed, 0.0) * diameter / AIR_NU)
    nu = (nu_spin**3 + nu_orbit**3) ** (1 / 3)
    return {"h": nu * AIR_K / diameter, "nu_spin": nu_spin, "nu_orbit": nu_orbit}


def effusivity(k: float, rho: float, cp: float) -> float:
    """√(k ρ c_p), J/(m² K s½): how much heat a surface takes up in a brief contact."""
    return math.sqrt(k * rho * cp)


def wall_share(e_ball: float, e_wall: float) -> float:
    """Share of the heat made at a ball–wall contact that goes into the wall: two
    bodies touching for a short time share it by their effusivities (Blok's partition)."""
    return e_wall / (e_ball + e_wall)


# ------------------------------------------------------------------ the mill's network


@dataclass(frozen=True)
class Setup:
    """What the network of one jar needs (SI units). Powers in W from the run's
    summary: `p_ball_ball` at ball–ball contacts, `p_ball_wall` at the side, floor and lid."""

    ball_mass: float
    ball_cp: float
    ball_diameter: float
    ball_count: int
    powder_mass: float
    powder_cp: float
    jar_mass: float
    jar_cp: float
    jar_area: float  #: m², outside surface that meets the air
    ball_area: float  #: m², the balls' surface
    h_out: float  #: W/(m² K), jar to air
    h_in: float  #: W/(m² K) over the balls' surface, balls to the jar (through the gas and contacts)
    p_ball_ball: float
    p_ball_wall: float
    share_wall: float  #: of p_ball_wall, into the jar
    powder_share: float = 0.0  #: of every contact's heat, straight into the powder
    powder_tau: float = 1.0  #: s: how fast the powder follows the balls


def network(s: Setup) -> tuple[Network, np.ndarray]:
    """The three-node network (balls, powder, jar) and its power while the mill runs."""
    C = np.array([s.ball_mass * s.ball_cp, max(s.powder_mass * s.powder_cp, 1e-9), s.jar_mass * s.jar_cp])
    g_bw = s.h_in * s.ball_area
    g_bp = C[1] / s.powder_tau
    G = np.array([[0.0, g_bp, g_bw], [g_bp, 0.0, 0.0], [g_bw, 0.0, 0.0]])
    loss = np.array([0.0, 0.0, s.h_out * s.jar_area])
    to_jar = s.p_ball_wall * s.share_wall
    to_balls = s.p_ball_ball + s.p_ball_wall - to_jar
    total = to_balls + to_jar
    # the powder's share comes from balls and jar in proportion to what each gets
    q = np.array([to_balls * (1 - s.powder_share), total * s.powder_share, to_jar * (1 - s.powder_share)])
    return Network(NODES, C, G, loss), q


def temperatures_at(net: Network, q_on, prog: Programme, times) -> np.ndarray:
    """Node temperatures above ambient at `times` (s, any order), exact."""
    m = modes(net)
    n = len(net.C)
    times = np.asarray(times, float)
    out = np.zeros((len(times), n))
    x = np.zeros(n)
    done = np.zeros(len(times), bool)
    for t0, length, on in prog.phases():
        q = np.asarray(q_on, float) if on else np.zeros(n)
        inside = ~done & (times <= t0 + length)
        for i in np.flatnonzero(inside):
            out[i] = advance(m, x, q, max(times[i] - t0, 0.0))
        done |= inside
        x = advance(m, x, q, length)
    for i in np.flatnonzero(~done):  # after the programme: it has stopped, the jar cools
        out[i] = advance(m, x, np.zeros(n), times[i] - prog.total_s)
    return out
