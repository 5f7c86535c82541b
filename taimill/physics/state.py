"""Taichi fields of a batch of B independent mills with up to N balls each, split by
kind: fixed parameters (`F.model`: written by the launcher; live-tunable values such as
the drive ramps and friction are field values, never Python globals, frozen at compile
time), evolving state (`F.state`), contact bookkeeping (`F.contacts`), spatial
structures (`F.spatial`) and output buffers (`F.out`). The sizes and the compiled
contact models stay on the Fields object itself. Shapes in brackets, SI units.
"""

import math

from taimill.model.contact.registry import contact_model, law_by_name
from taimill.model.geometry import MAX_PIECES, PIECE_COLUMNS
from taimill.model import spectra as SP
from taimill.physics.ti import ti
from taimill.schema import DERIVED_EVENT_COLUMNS, DRIVE_FIELDS, ENERGY_COLUMNS, EVENT_COLUMNS, MECHANISM_COLUMNS

# Contact slots per ball: 3 wall slots (side, floor, lid), then partner slots for the
# ball-ball contacts this ball owns (partner index > own index). 12 = kissing number of
# equal spheres, so a monodisperse packing can never overflow.
WALLS = 3
PARTNER_SLOTS = 12
SLOTS = WALLS + PARTNER_SLOTS

# Event accumulators of an open contact: one row of the mill's contact pool per open slot.
SLOT_T0, SLOT_UN, SLOT_UT, SLOT_PX, SLOT_PY, SLOT_PZ, SLOT_FPEAK, SLOT_UPEAK, SLOT_DN, SLOT_DT = range(10)
SLOT_DATA = 10
# History of a contact whose tangential or rolling model keeps one, after the
# accumulators in its pool row (present only in engines compiled for such a model): the
# energy its tangential and its rolling spring stored at the last step (J; only the
# owner's thread reads and writes them), then the springs, tangential ξ (m, 3) and
# rolling torque M_r (N m, 3), in blocks of HISTORY columns. Where both balls of a
# contact compute it (parallel mode) in two blocks: a step reads one and writes the
# other (pool.history_block), so a partner's thread reads what the owner read while the
# owner writes. 24 columns, 192 bytes: three cache lines, as many as a row of 18 columns
# spans at 16-byte offsets; with the energies in the blocks too (26 columns, four lines)
# the history cost twice as much (fused mode, the simple cubic bed of 2·10⁴ balls of
# scripts/bench.py: 94-95 ns of CPU per ball-step against 73-82 with one block, 53-60
# without history). The fused mode, where only the owner reads a contact's history,
# keeps one block (18 columns): two cost it 12 % on the face-centred cubic bed of 2·10⁴
# balls, 2.7 open contacts a ball (383-386 against 339-350 ns, interleaved runs).
SLOT_EXI, SLOT_EMR = SLOT_DATA, SLOT_DATA + 1
SLOT_SPRINGS = SLOT_DATA + 2  #: the first history block's first column
HIST_XI, HIST_MR = 0, 3
HISTORY = 6

# Event record columns as the kernel writes them: the schema's event columns without
# those the launcher derives after each launch (the stress energies).
EVENT_FIELDS = tuple(k for k in EVENT_COLUMNS if k not in DERIVED_EVENT_COLUMNS)
NCOL = len(EVENT_FIELDS)
EV = {name: c for c, name in enumerate(EVENT_FIELDS)}  #: column of the kernel's event record

# Energy ledger snapshot columns, taken with every frame (the schema's ENERGY_COLUMNS but time).
LEDGER_FIELDS = tuple(k for k in ENERGY_COLUMNS if k != "time")
LEDGER = {name: c for c, name in enumerate(LEDGER_FIELDS)}  #: column of the kernel's ledger record
NLEDGER = len(LEDGER_FIELDS)
# Dissipation by mechanism: index kind·4 + class·2 + part of the schema's MECHANISM_COLUMNS
# (kinds: 0 ball-ball, 1 + wall index; classes: 0 impact, 1 persistent; parts: 0
# normal, 1 friction).
NMECH = len(MECHANISM_COLUMNS)

# Verlet list length per ball (equal spheres within a skin of 0.1 r: at most ~14).
NEIGHBOURS = 32

# Open-contact pool: rows per mill. A mill of n balls gets n·SLOTS rows (it can never
# run out) up to POOL_FLOOR rows, above that POOL_PER_BALL·n: each contact has one owner,
# and a close-packed bed of equal spheres (12 contacts a ball, the densest there is)
# owns at most 6 per ball, a wall contact replacing at least one missing partner at
# the boundary (the dense bed of scripts/bench.py holds 2-3). A pool that runs out
# stops the run (POOL_FULL). (A sparse pool of n·SLOTS rows, ti.root.pointer blocks,
# took memory only for rows in use; it was dropped after one unexplained segfault.)
POOL_FLOOR = 4096
POOL_PER_BALL = 6
# The first HOME_ROWS rows of the pool per ball are that ball's own (rows i·home to
# i·home + home - 1, moved with the ball by reorder.py), the rest a shared stack. A
# contact takes one of its owner's home rows while one is free: the force pass walks
# the balls in row order, so their event data is read in memory order. Rows taken from
# the shared stack scatter over the pool as contacts open and close; on a settled bed of
# 10⁵ balls the load of such a row missed the cache at every step of every contact
# (a fifth of the force pass). A bed's ball owns 2-3 open contacts, at most 6 + a wall.
HOME_ROWS = 4


def pool_rows(balls: int) -> int:
    """Rows of the open-contact pool of a mill with room for `balls` balls."""
    return min(balls * SLOTS, max(POOL_FLOOR, POOL_PER_BALL * balls))


# Balls per partial sum of a frame's energy ledger, and the sums (kinetic, potential,
# elastic, drive work, dissipated, then each mechanism: physics/snapshot.py).
LEDGER_BLOCK = 1024
LEDGER_SUMS = 5 + NMECH
# Cells per block, and blocks per group, of the parallel prefix sum of the spatial hash
# (grid.prefix_cells).
SCAN_BLOCK = 256

# Status codes.
OK, NONFINITE, ESCAPED, SLOTS_FULL, LIST_FULL, POOL_FULL = 0, 1, 2, 3, 4, 5

CONTACT_TYPES = 2  # 0 ball-ball, 1 ball-wall
LAWS_DEFAULT = "adams-impact"


class MillModel:
    """Fixed parameters: of each mill [B] (time step, drive ramps, gravity, jar profile,
    contact coefficients per contact type [B, 2]) and of each ball [B, N] (radius,
    mass, inverse inertia). Written by the launcher (mill.py); the live-tunable ones
    (drive ramps, dt, friction) through mill.py's setters."""


class MillState:
    """What evolves: ball positions, velocities, spins, this step's forces and energy
    books [B, N]; each mill's step, status and the drive's cached trigonometry [B]."""


class ContactBook:
    """Open contacts: per-ball slots [B, N, SLOTS] and the pool of rows holding their
    event accumulators and history [B, P] (pool.py, events.py)."""


class Spatial:
    """The spatial hash grid [B, cells] and the Verlet neighbour lists [B, N, NEIGHBOURS]."""


class Outputs:
    """Buffers of events and frames, drained by the launcher after every launch."""


GROUPS = ("model", "state", "contacts", "spatial", "out")


def default_models() -> tuple:
    """The thesis' contact model for both contact types (adams-impact, regularised
    Coulomb friction, constant rolling torque)."""
    one = (contact_model(law_by_name(LAWS_DEFAULT)),)
    return one, one


# Field types of the groups below.
f64, i32, i64 = ti.f64, ti.i32, ti.i64
vec3 = ti.types.vector(3, f64)


@ti.data_oriented
class Fields:
    def __init__(self, batch: int, balls: int, event_capacity: int, frame_capacity: int, grid_cells: int,
                 pool: int | None = None, share_pairs: bool = False, reorder: bool = False, models=None):
        self._compile_for(models, batch, share_pairs, reorder)
        self._size(batch, balls, event_capacity, frame_capacity, grid_cells, pool)
        self.model, self.state, self.contacts, self.spatial, self.out = (
            MillModel(), MillState(), ContactBook(), Spatial(), Outputs())
        # the fields in the order they were always made (their places in Taichi's tree)
        self._mill_fields()
        self._grid_fields()
        self._ball_fields()
        self._contact_fields()
        self._spatial_fields()
        self._output_fields()
        self._history_fields()

    def _compile_for(self, models, B: int, share_pairs: bool, reorder: bool):
        """The contact models and modes the kernels are compiled for."""
        # the ContactModels the kernels are compiled for, per contact type (ball-ball,
        # ball-wall): compile-time constants of every kernel that takes these fields
        self.models = tuple(tuple(m) for m in (models or default_models()))
        # per contact type: a model keeps a per-contact history (in its pool row)
        self.history = tuple(any(m.tangential.history or m.rolling.history for m in ms) for ms in self.models)
        if reorder and (B != 1 or share_pairs):
            raise ValueError("balls are stored in grid order only in parallel mode (one mill)")
        # the balls' forces are computed one after another in index order (fused mode):
        # a pair's owner leaves the partner's force and torque (contacts.partner_share)
        self.share_pairs = share_pairs
        # otherwise both balls of a history contact compute it, the partner with the
        # owner's history, found through the owner's slots as they were at the step's
        # start (contacts.slot_prev: the owner's thread rewrites slot_mask meanwhile),
        # from the second of two history blocks (pool.history_block)
        self.prev_mask = self.history[0] and not share_pairs
        self.history_copies = 2 if self.prev_mask else 1
        self.pool_width = SLOT_SPRINGS + self.history_copies * HISTORY if any(self.history) else SLOT_DATA
        # parallel mode: ball rows are kept in the order of the grid cells, refreshed at
        # every neighbour-list build (reorder.py); user_of maps a row to the ball's own
        # index, which every output and the contact ownership use
        self.reorder = reorder

    def _size(self, B: int, N: int, event_capacity: int, frame_capacity: int, grid_cells: int, pool: int | None):
        """The sizes of the fields: mills, balls, buffers, pool rows and grid cells."""
        P = pool_rows(N) if pool is None else pool
        self.B, self.N, self.event_capacity, self.frame_capacity = B, N, event_capacity, frame_capacity
        self.pool_capacity = P
        # home rows per ball; at least a third of the pool stays shared, for the balls that
        # own more contacts than their home rows hold (a large mill: 4 a ball and 2 shared)
        self.home = min(HOME_ROWS, (P - P // 3) // N)
        self.spill_base = N * self.home  # rows [spill_base, P): the shared stack's
        self.grid_cells = grid_cells

    def _mill_fields(self):
        """The fixed parameters of each mill [B]: clock, drive, mechanism classes,
        spectra, contact models and coefficients per contact type [B, 2], jar profile."""
        B, model = self.B, self.model
        model.n_balls = ti.field(i32, B)
        model.dt = ti.field(f64, B)  #: s
        model.gravity = ti.field(f64, B)  #: m/s²
        model.plate_radius = ti.field(f64, B)  #: R_p, m
        model.height = ti.field(f64, B)  #: jar height, m
        model.plate_ramp = ti.Vector.field(5, f64, B)  #: Ω ramp (t0, start, end, T, phase0)
        model.jar_ramp = ti.Vector.field(5, f64, B)  #: w ramp, absolute jar spin
        model.frame_every = ti.field(i32, B)  #: steps between frames
        model.target = ti.field(i64, B)  #: step count to reach
        # class of a contact for the mechanism ledger (taimill.model.mechanisms) [B]
        model.stress_un = ti.field(f64, B)  #: m/s, least onset normal speed of an impact
        model.impact_age = ti.field(f64, B)  #: s, an impact older than this is persistent
        model.spectra_from = ti.field(f64, B)  #: s, events starting from this time enter the spectra
        model.spectrum_edges = ti.field(f64, len(SP.EDGES))  #: J, bin edges (taimill.model.spectra)
        model.spectrum_scale = ti.field(f64, SP.NBIN)  #: 1/J, fixed-point scale per bin
        # contact model per contact type [B, 2] (0 ball-ball, 1 ball-wall): one of the
        # engine's compiled models (self.models[ct], variant only if it has several)
        # and the normal law's coefficients
        model.variant = ti.field(i32, (B, CONTACT_TYPES))  #: index into self.models[ct]
        model.law_k = ti.field(f64, (B, CONTACT_TYPES))  #: stiffness, N/m^n
        model.law_c = ti.field(f64, (B, CONTACT_TYPES))  #: damping coefficient, unit of the damping model
        model.law_d = ti.field(f64, (B, CONTACT_TYPES))  #: m, full-damping overlap (adams-step)
        model.law_kt = ti.field(f64, (B, CONTACT_TYPES))  #: N/m^1.5, tangential stiffness per √u (history models)
        # friction (eq 3.7) and rolling resistance per contact type, live-tunable [B, 2]
        model.mu_s = ti.field(f64, (B, CONTACT_TYPES))
        model.mu_d = ti.field(f64, (B, CONTACT_TYPES))
        model.v_s = ti.field(f64, (B, CONTACT_TYPES))  #: m/s
        model.v_d = ti.field(f64, (B, CONTACT_TYPES))  #: m/s
        model.mu_r = ti.field(f64, (B, CONTACT_TYPES))  #: 0: no rolling resistance
        # jar profile: boundary pieces, rows of taimill.model.geometry [B, MAX_PIECES]
        model.n_pieces = ti.field(i32, B)
        model.piece = ti.Vector.field(PIECE_COLUMNS, f64, (B, MAX_PIECES))
        model.piece_bound = ti.Vector.field(3, f64, (B, MAX_PIECES))  #: m, geometry.piece_bounds rows

    def _grid_fields(self):
        """The uniform grid of the spatial hash of each mill [B]."""
        B, spatial = self.B, self.spatial
        spatial.grid_lo = ti.Vector.field(3, f64, B)  #: m, corner of the grid
        spatial.grid_h = ti.field(f64, B)  #: m, cell edge (≥ largest ball diameter)
        spatial.grid_dim = ti.Vector.field(3, i32, B)
        spatial.skin = ti.field(f64, B)  #: m, Verlet-list skin

    def _ball_fields(self):
        """Of each ball [B, N]: its fixed parameters and what evolves, placed as the
        mode reads them; of each mill [B] its step, status and drive trigonometry."""
        B, N, model, state, reorder = self.B, self.N, self.model, self.state, self.reorder
        model.r = ti.field(f64)  #: m
        model.m = ti.field(f64)  #: kg
        model.inv_i = ti.field(f64)  #: 1/(kg m²)
        model.inv_m = ti.field(f64)  #: 1/kg
        # state [B, N], and per mill [B]
        state.turn_trig = ti.Vector.field(3, f64, B)  #: (Δφ_jar, cos, sin) of the last step's turn (engine.drive)
        state.psi_rec = ti.Vector.field(3, f64, B)  #: (t, cos ψ, sin ψ) of the last step's drive (engine.psi_trig)
        state.psi_rot = ti.Vector.field(3, f64, B)  #: (δ, cos δ, sin δ), ψ's growth a step at constant speeds
        state.x = ti.field(vec3)  #: position, jar frame, m
        state.v = ti.field(vec3)  #: velocity, jar frame, m/s
        state.s = ti.field(vec3)  #: absolute spin in jar-frame components, rad/s
        state.user_of = ti.field(i32, None if reorder else (1, 1))  #: the ball's own index (its index in the MillSpec) of row i
        state.f = ti.field(vec3)  #: contact force of this step, N
        state.tau = ti.field(vec3)  #: contact torque of this step, N m
        state.drive_step = ti.field(f64)  #: J, walls' work on this ball in this step
        state.diss_step = ti.field(f64)  #: J, dissipated in its contacts this step
        state.drive_work = ti.field(f64)  #: J, walls' work on this ball
        state.dissipated = ti.field(f64)  #: J, in contacts this ball owns
        state.mech = ti.field(f64, (B, N, NMECH))  #: J, dissipation by mechanism, booked in the force pass
        state.elastic = ti.field(f64)  #: J, stored now in contacts this ball owns
        state.side_ref = ti.field(ti.types.vector(3, f64))  #: m, (x₀, y₀, lower bound of φ there), walls.side_wall_near
        self._place_balls((state.x, state.v, state.s, model.r, model.m, model.inv_m, model.inv_i),
                          (state.f, state.tau, state.drive_step, state.diss_step, state.drive_work, state.dissipated,
                           state.elastic, state.side_ref))
        ids = (B, N) if reorder else (1, 1)
        state.row_of = ti.field(i32, ids)  #: row of the ball with own index u (inverse of user_of)
        state.step = ti.field(i64, B)
        state.status = ti.field(i32, B)
        state.bad_ball = ti.field(i32, B)  #: own index (user_id) of the ball that raised the status

    def _place_balls(self, partner: tuple, own: tuple):
        """Place the fields [B, N] of what a contact reads of its partner and of what the
        ball's own passes write. Large-mill mode (reorder) keeps a ball's values side by
        side in memory, in these two records (partner: x, v, s, r, m, 1/m, 1/I and its own
        index, 108 bytes, two cache lines where eight arrays took eight). Settled bed of
        10⁵ balls, one thread: 242 → 194 ns per ball-step (interleaved in one process),
        250-270 → 189-203 (bench.py --ab). A dozen balls, which fit the first-level cache,
        ran 7 % slower so (CY steel 0.154-0.157 → 0.166-0.167 µs a step): one array per
        value there."""
        B, N = self.B, self.N
        if self.reorder:
            ti.root.dense(ti.ij, (B, N)).place(*partner, self.state.user_of)
            ti.root.dense(ti.ij, (B, N)).place(*own)
        else:
            for fld in partner + own:
                ti.root.dense(ti.ij, (B, N)).place(fld)

    def _contact_fields(self):
        """Open contacts [B, N, SLOTS], their event data in a pool of rows [B, P]."""
        B, N, P, contacts = self.B, self.N, self.pool_capacity, self.contacts
        contacts.slot_mask = ti.field(i32, (B, N))  #: bit k set: slot k holds an open event
        contacts.slot_closed = ti.field(i32, (B, N))  #: bit k set: slot k closed this step, its row not yet released
        contacts.slot_partner = ti.field(i32, (B, N, SLOTS))  #: partner ball of slot k ≥ WALLS
        contacts.slot_row = ti.field(i32, (B, N, SLOTS))  #: pool row of open slot k
        contacts.pool = ti.Vector.field(self.pool_width, f64, (B, P))  #: event accumulators (and history) of an open contact
        contacts.pool_free = ti.field(i32, (B, max(1, P - self.spill_base)))  #: stack of released shared rows, [0, pool_top)
        contacts.pool_top = ti.field(i32, B)
        contacts.pool_used = ti.field(i32, B)  #: shared rows ever handed out: spill_base + [0, pool_used)
        shared = (B, N, SLOTS) if self.share_pairs else (1, 1, 1)
        contacts.pair_f = ti.field(vec3, shared)  #: N, force of this step on the partner of slot k
        contacts.pair_tq = ti.field(vec3, shared)  #: N m, torque of this step on the partner of slot k

    def _history_fields(self):
        """What the history blocks of parallel mode need, made last: Taichi lays the
        fields out one after another in the order they are made, and these two, made
        among the contact fields, moved the fields after them off their alignment: the
        settled bed of 10⁵ balls (no history) ran 196 against 183 ns of CPU a ball-step
        (scripts/bench.py --ab, 2 rounds, best of each)."""
        B, N, contacts = self.B, self.N, self.contacts
        contacts.slot_prev = ti.field(i32, (B, N) if self.prev_mask else (1, 1))  #: slot_mask at the step's start
        contacts.history_shift = ti.field(i32, B)  #: added to the step, whose parity picks the history block read

    def _spatial_fields(self):
        """The spatial hash [B, cells] and [B, N], the Verlet neighbour lists [B, N, NEIGHBOURS]."""
        B, N, spatial = self.B, self.N, self.spatial
        spatial.cell_count = ti.field(i32, (B, self.grid_cells))
        spatial.cell_start = ti.field(i32, (B, self.grid_cells))
        blocks = -(-self.grid_cells // SCAN_BLOCK) if B == 1 else 1
        spatial.block_start = ti.field(i32, blocks)  #: parallel mode: first cell_start of each block of cells (grid.prefix_cells)
        spatial.group_start = ti.field(i32, -(-blocks // SCAN_BLOCK))  #: and of each group of blocks
        spatial.cell_of = ti.field(i32, (B, N))
        spatial.sorted_ids = ti.field(i32, (B, N))
        # Verlet neighbour lists
        spatial.rebuild = ti.field(i32, B)  #: 1: lists are stale
        spatial.x_ref = ti.field(vec3, (B, N))  #: positions at the last build, m (scratch of reorder.py before it)
        spatial.nbr_count = ti.field(i32, (B, N))
        spatial.nbr = ti.field(i32, (B, N, NEIGHBOURS))  #: neighbour rows (scratch of reorder.py before a build)

    def _output_fields(self):
        """The buffers of events and frames, drained by the launcher after every launch."""
        B, N, out, event_capacity, frame_capacity = self.B, self.N, self.out, self.event_capacity, self.frame_capacity
        out.events = ti.Vector.field(NCOL, f64, (B, event_capacity))
        out.n_events = ti.field(i32, B)
        out.frame_t = ti.field(f64, (B, frame_capacity))
        out.frame_x = ti.field(vec3, (B, frame_capacity, N))
        out.frame_v = ti.field(vec3, (B, frame_capacity, N))
        out.frame_s = ti.field(vec3, (B, frame_capacity, N))
        out.frame_ledger = ti.Vector.field(len(LEDGER_FIELDS), f64, (B, frame_capacity))
        out.frame_drive = ti.Vector.field(len(DRIVE_FIELDS), f64, (B, frame_capacity))  #: φ_p, Ω, φ_j, w
        out.n_frames = ti.field(i32, B)
        # parallel mode: a frame's energy sums per block of balls (engine.ledger_block)
        blocks = -(-N // LEDGER_BLOCK) if B == 1 else 1
        out.ledger_part = ti.Vector.field(LEDGER_SUMS, f64, blocks)
        # energy spectra of the events closed so far [B, kind, class, measure, bin]
        # (taimill.model.spectra): events, and their energy in fixed point
        out.spectrum_count = ti.field(i64, (B, *SP.SHAPE))
        out.spectrum_fixed = ti.field(i64, (B, *SP.SHAPE))

    def nbytes(self) -> int:
        """Bytes of every field (what the device holds for these mills: Taichi
        allocates them when a kernel first runs). 10⁶ balls in parallel mode with the
        thesis' contact model: 1.27 GB (tests/test_parallel_step.py)."""
        total = 0
        for group in GROUPS:
            for fld in vars(getattr(self, group)).values():
                wide = fld.dtype in (f64, i64)
                total += math.prod(fld.shape) * getattr(fld, "n", 1) * getattr(fld, "m", 1) * (8 if wide else 4)
        return total

    def field(self, name: str):
        """The field called `name`, in whichever group holds it."""
        for group in GROUPS:
            if hasattr(getattr(self, group), name):
                return getattr(getattr(self, group), name)
        raise AttributeError(name)


@ti.func
def user_id(F: ti.template(), b, i):
    """The ball's own index (its index in the MillSpec, in every output) of row i."""
    u = i
    if ti.static(F.reorder):
        u = F.state.user_of[b, i]
    return u


@ti.func
def owns(F: ti.template(), b, i, j):
    """Ball i owns its contact with ball j (books its event and energy): the lower own
    index, so a contact keeps its owner when the rows are reordered."""
    mine = i < j
    if ti.static(F.reorder):
        mine = F.state.user_of[b, i] < F.state.user_of[b, j]
    return mine
