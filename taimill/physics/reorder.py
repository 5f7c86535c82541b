"""Parallel mode: ball rows in the order of the grid cells, so that balls near in space
are near in memory. The contact loop reads every neighbour's state; with rows in the
order the balls were placed (random placement, or a bed once it has mixed), nearly
every such read misses the cache: a dense bed of 10⁵ balls in random row order ran
3-4× slower than the same bed in grid order (scripts/bench.py's case, one thread).

At every neighbour-list build, after the counting sort (grid.py) and before the lists,
each per-ball row moves to its place in the cell order (`permute`): row q takes the
ball at old row sorted_ids[q]. F.state.user_of follows the balls, so outputs, events, the
faulting ball and the contact ownership (state.owns: the lower own index) keep using
the ball's own index; the lists are sorted by own index (neighbours.sort_list), so
forces are summed in the same order as without the reorder, and results are
bit-identical to it (tests/test_reorder.py).

What moves: state (x, v, s), ball properties (r, m, inv_i; inv_m is recomputed from m,
the same division as at the start), the side-wall bound (side_ref), the energy ledger
(drive_work, dissipated, elastic, mech) and the open contacts (slot_mask, slot_row,
slot_partner, whose partner rows are renumbered, and slot_prev, equal to slot_mask
between steps). A ball's home rows of the pool move with it, every column, history
included (state.HOME_ROWS: its slots' home row numbers follow); the shared rows stay
where they are. Per-step scratch (f, tau, drive_step, diss_step) is rewritten by the
next force pass before it is read, x_ref, nbr and nbr_count by the list build that
follows, and slot_closed is empty between steps (release_rows): none of them moves.
x_ref and nbr are the scratch of the move.
"""

from taimill.physics import state as S
from taimill.physics.ti import ti

_INTS = 2 + 2 * S.SLOTS  # a row's slot_mask, user_of, slot_row and slot_partner in nbr's row
assert _INTS <= S.NEIGHBOURS


@ti.kernel
def _inverse(F: ti.template()):
    """cell_of (free after the counting sort) ← new row of each old row."""
    for q in range(F.model.n_balls[0]):
        F.spatial.cell_of[0, F.spatial.sorted_ids[0, q]] = q


@ti.kernel
def _gather_vec(F: ti.template(), a: ti.template()):
    for q in range(F.model.n_balls[0]):
        F.spatial.x_ref[0, q] = a[0, F.spatial.sorted_ids[0, q]]


@ti.kernel
def _put_vec(F: ti.template(), a: ti.template()):
    for q in range(F.model.n_balls[0]):
        a[0, q] = F.spatial.x_ref[0, q]


@ti.kernel
def _gather_scalars(F: ti.template(), a: ti.template(), b: ti.template(), c: ti.template()):
    for q in range(F.model.n_balls[0]):
        p = F.spatial.sorted_ids[0, q]
        F.spatial.x_ref[0, q] = ti.Vector([a[0, p], b[0, p], c[0, p]])


@ti.kernel
def _put_scalars(F: ti.template(), a: ti.template(), b: ti.template(), c: ti.template()):
    for q in range(F.model.n_balls[0]):
        row = F.spatial.x_ref[0, q]
        a[0, q] = row[0]
        b[0, q] = row[1]
        c[0, q] = row[2]


@ti.kernel
def _inverse_masses(F: ti.template()):
    for q in range(F.model.n_balls[0]):
        F.model.inv_m[0, q] = 1.0 / F.model.m[0, q]  # as mill.load_mill computed it: the same bits


@ti.kernel
def _gather_mech(F: ti.template(), c0: ti.template()):
    for q in range(F.model.n_balls[0]):
        p = F.spatial.sorted_ids[0, q]
        row = ti.Vector.zero(ti.f64, 3)
        for k in ti.static(range(3)):
            if ti.static(c0 + k < S.NMECH):
                row[k] = F.state.mech[0, p, c0 + k]
        F.spatial.x_ref[0, q] = row


@ti.kernel
def _put_mech(F: ti.template(), c0: ti.template()):
    for q in range(F.model.n_balls[0]):
        row = F.spatial.x_ref[0, q]
        for k in ti.static(range(3)):
            if ti.static(c0 + k < S.NMECH):
                F.state.mech[0, q, c0 + k] = row[k]


@ti.kernel
def _gather_home(F: ti.template(), h: ti.i32, c0: ti.i32):
    """Columns c0..c0+2 of home row h of every ball. (h and c0 are arguments, not
    templates: two kernels to compile, not one per row and column, ≈ 0.15 s each.)"""
    for q in range(F.model.n_balls[0]):
        data = F.contacts.pool[0, F.spatial.sorted_ids[0, q] * F.home + h]
        row = ti.Vector.zero(ti.f64, 3)
        for c in ti.static(range(F.pool_width)):  # (unrolled: nested, not ndrange, < 32 a loop)
            for k in ti.static(range(3)):
                if c == c0 + k:
                    row[k] = data[c]
        F.spatial.x_ref[0, q] = row


@ti.kernel
def _put_home(F: ti.template(), h: ti.i32, c0: ti.i32):
    for q in range(F.model.n_balls[0]):
        row = F.spatial.x_ref[0, q]
        for c in ti.static(range(F.pool_width)):  # only these columns: a row of history is 24
            for k in ti.static(range(3)):
                if c == c0 + k:
                    F.contacts.pool[0, q * F.home + h][c] = row[k]


@ti.kernel
def _gather_ints(F: ti.template()):
    for q in range(F.model.n_balls[0]):
        p = F.spatial.sorted_ids[0, q]
        mask = F.contacts.slot_mask[0, p]
        F.spatial.nbr[0, q, 0] = mask
        F.spatial.nbr[0, q, 1] = F.state.user_of[0, p]
        for k in ti.static(range(S.SLOTS)):
            row = F.contacts.slot_row[0, p, k]
            partner = -1
            if mask & (1 << k):
                if row < F.spill_base:  # a home row: it moved with the ball
                    row += (q - p) * F.home
                if ti.static(k >= S.WALLS):
                    partner = F.spatial.cell_of[0, F.contacts.slot_partner[0, p, k]]
            F.spatial.nbr[0, q, 2 + k] = row
            F.spatial.nbr[0, q, 2 + S.SLOTS + k] = partner


@ti.kernel
def _put_ints(F: ti.template()):
    """Also the grid's order: the rows are now in it (sorted_ids the identity)."""
    for q in range(F.model.n_balls[0]):
        F.contacts.slot_mask[0, q] = F.spatial.nbr[0, q, 0]
        if ti.static(F.prev_mask):
            F.contacts.slot_prev[0, q] = F.spatial.nbr[0, q, 0]
        u = F.spatial.nbr[0, q, 1]
        F.state.user_of[0, q] = u
        F.state.row_of[0, u] = q
        for k in ti.static(range(S.SLOTS)):
            F.contacts.slot_row[0, q, k] = F.spatial.nbr[0, q, 2 + k]
            F.contacts.slot_partner[0, q, k] = F.spatial.nbr[0, q, 2 + S.SLOTS + k]
        F.spatial.sorted_ids[0, q] = q


def permute(F):
    """Move every ball row of mill 0 to its place in the grid order (F.spatial.sorted_ids of
    the counting sort just done); the grid stays valid (cell_start, cell_count)."""
    _inverse(F)
    for a in (F.state.x, F.state.v, F.state.s, F.state.side_ref):
        _gather_vec(F, a)
        _put_vec(F, a)
    for group in ((F.model.r, F.model.m, F.model.inv_i), (F.state.drive_work, F.state.dissipated, F.state.elastic)):
        _gather_scalars(F, *group)
        _put_scalars(F, *group)
    for c0 in range(0, S.NMECH, 3):
        _gather_mech(F, c0)
        _put_mech(F, c0)
    _inverse_masses(F)
    for h in range(F.home):
        for c0 in range(0, F.pool_width, 3):
            _gather_home(F, h, c0)
            _put_home(F, h, c0)
    _gather_ints(F)  # last: it needs the old sorted_ids, _put_ints makes them the identity
    _put_ints(F)
