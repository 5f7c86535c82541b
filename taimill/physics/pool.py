"""The open-contact pool of a mill: per-ball slots and the rows holding their event data.

A slot holds only the index of its event's row in the mill's pool of open-contact rows
(state.pool_rows: at most 6 a ball in large mills; a dense bed has 2-3, not 15). A
contact that opens takes one of its owner's home rows (state.HOME_ROWS) if one is free,
else a released row from the shared stack, else a new one (atomic pop and count: in
parallel mode the balls of the mill do it concurrently); rows are released only after
the force pass, by release_rows in the integration pass, so pops and pushes never race.
Which row a contact gets changes nothing but where its sums are kept.
"""

from taimill.physics import state as S
from taimill.physics.ti import ti


@ti.func
def slot_row(F: ti.template(), b, i, k, is_new, taken):
    """Pool row of the event in slot k of ball i: its own if open, else a home row of
    ball i that none of its slots holding a row (bits of `taken`: open before this step
    or opened in it; closed ones keep theirs until release_rows) has, else a row taken
    from the shared stack; -1 (and POOL_FULL flagged) if none is left. Only ball i's
    thread touches its home rows: no atomics."""
    row = -1
    if is_new:
        if ti.static(F.home > 0):
            used = 0
            mask = taken
            s = 0
            while mask:
                if mask & 1:
                    r = F.contacts.slot_row[b, i, s] - i * F.home
                    if 0 <= r and r < F.home:
                        used |= 1 << r
                mask >>= 1
                s += 1
            h = 0
            while h < F.home and used & (1 << h):
                h += 1
            if h < F.home:
                row = i * F.home + h
        if row < 0:
            e = ti.atomic_sub(F.contacts.pool_top[b], 1) - 1  # a released row first
            if e >= 0:
                row = F.contacts.pool_free[b, e]
            else:  # the stack is empty (its top goes negative until release_rows): a new row
                row = F.spill_base + ti.atomic_add(F.contacts.pool_used[b], 1)
                if row >= F.pool_capacity:
                    row = -1
                    F.state.status[b] = S.POOL_FULL
                    F.state.bad_ball[b] = S.user_id(F, b, i)
        if row >= 0:
            F.contacts.slot_row[b, i, k] = row
    else:
        row = F.contacts.slot_row[b, i, k]
    return row


@ti.func
def pool_settle(F: ti.template(), b):
    """After the force pass, before release_rows: the stack is empty if pops ran past it."""
    if F.contacts.pool_top[b] < 0:
        F.contacts.pool_top[b] = 0


@ti.func
def release_rows(F: ti.template(), b, i):
    """Give the pool rows of ball i's events closed in this step's force pass back: a
    home row to ball i, a shared one to the free stack (a pass without pops:
    pool_settle first)."""
    gone = F.contacts.slot_closed[b, i]
    if gone:
        k = 0
        while gone:
            if gone & 1:
                row = F.contacts.slot_row[b, i, k]
                if row >= F.spill_base:  # a home row is free once no slot holds it
                    F.contacts.pool_free[b, ti.atomic_add(F.contacts.pool_top[b], 1)] = row
            gone >>= 1
            k += 1
        F.contacts.slot_closed[b, i] = 0


@ti.func
def partner_slot(F: ti.template(), b, i, j, taken):
    """Slot of ball i holding partner j among the open ones (bits of `taken`), else the
    lowest free slot, now marked for j; -1 if every slot is taken. Walks only the set
    bits (a ball holds a few open contacts, not 12), then, for a new contact, the
    lowest clear bit."""
    found = -1
    mask = taken >> S.WALLS
    k = S.WALLS
    while mask:
        if mask & 1 and F.contacts.slot_partner[b, i, k] == j:
            found = k
        mask >>= 1
        k += 1
    if found < 0:
        free = -1
        k = S.WALLS
        while k < S.SLOTS and free < 0:
            if not taken & (1 << k):
                free = k
            k += 1
        if free >= 0:
            found = free
            F.contacts.slot_partner[b, i, free] = j
    return found


@ti.func
def claim_row(F: ti.template(), b, i, j, taken, was_open):
    """(slot, pool row, is_new) of owner i's contact with ball j (partner_slot, then
    slot_row); slot -1 and SLOTS_FULL flagged if ball i has no free slot, row -1 if the
    pool is full."""
    row, is_new = -1, False
    k = partner_slot(F, b, i, j, taken)
    if k < 0:
        F.state.status[b] = S.SLOTS_FULL
        F.state.bad_ball[b] = S.user_id(F, b, i)
    else:
        is_new = (was_open & (1 << k)) == 0
        row = slot_row(F, b, i, k, is_new, taken)
    return k, row, is_new


@ti.func
def history_block(F: ti.template(), b):
    """The history block (0 or 1) of a pool row that mill b's contacts read in this step;
    they write the other, which the next step reads. In parallel mode both balls of a
    contact compute it, each on its own thread: the partner reads the block the owner
    reads, which no thread writes in this step. The step's parity picks it;
    contacts.history_shift keeps that parity when mill.set_clock sets the step. With
    one block (state.Fields.history_copies: no partner reads it) always 0."""
    block = 0
    if ti.static(F.history_copies == 2):
        block = ti.cast((F.state.step[b] + F.contacts.history_shift[b]) & 1, ti.i32)
    return block


@ti.func
def _springs_at(F: ti.template(), b, row, col: ti.template()):
    return ti.Vector([F.contacts.pool[b, row][col + c] for c in ti.static(range(S.HISTORY))])


@ti.func
def _keep_springs_at(F: ti.template(), b, row, col: ti.template(), h):
    for c in ti.static(range(S.HISTORY)):
        F.contacts.pool[b, row][col + c] = h[c]


@ti.func
def read_springs(F: ti.template(), b, row, is_new, block):
    """(tangential spring ξ, rolling spring M_r) of the contact in pool row `row`, from
    history block `block`: zero for a new contact or without a row. Kept from the
    owner's side (the ball of lower own index)."""
    h = ti.Vector.zero(ti.f64, S.HISTORY)
    if row >= 0 and not is_new:
        if ti.static(F.history_copies == 1):
            h = _springs_at(F, b, row, S.SLOT_SPRINGS)
        elif block == 0:
            h = _springs_at(F, b, row, S.SLOT_SPRINGS)
        else:
            h = _springs_at(F, b, row, S.SLOT_SPRINGS + S.HISTORY)
    xi = ti.Vector([h[S.HIST_XI + c] for c in ti.static(range(3))])
    m_r = ti.Vector([h[S.HIST_MR + c] for c in ti.static(range(3))])
    return xi, m_r


@ti.func
def read_history(F: ti.template(), b, row, is_new, block):
    """(tangential history ξ, its stored energy, rolling history M_r, its stored energy)
    of the contact in pool row `row` as its owner reads it: the springs (read_springs)
    and the energies they stored at the last step."""
    xi, m_r = read_springs(F, b, row, is_new, block)
    e_xi, e_mr = 0.0, 0.0
    if row >= 0 and not is_new:
        e_xi, e_mr = F.contacts.pool[b, row][S.SLOT_EXI], F.contacts.pool[b, row][S.SLOT_EMR]
    return xi, e_xi, m_r, e_mr


@ti.func
def write_history(F: ti.template(), b, row, block, xi, e_xi, m_r, e_mr):
    """Keep a contact's history in its pool row for the next step: the springs in the
    block that this step does not read (with two)."""
    h = ti.Vector([xi[0], xi[1], xi[2], m_r[0], m_r[1], m_r[2]])
    if ti.static(F.history_copies == 1):
        _keep_springs_at(F, b, row, S.SLOT_SPRINGS, h)
    elif block == 0:
        _keep_springs_at(F, b, row, S.SLOT_SPRINGS + S.HISTORY, h)
    else:
        _keep_springs_at(F, b, row, S.SLOT_SPRINGS, h)
    F.contacts.pool[b, row][S.SLOT_EXI] = e_xi
    F.contacts.pool[b, row][S.SLOT_EMR] = e_mr


@ti.func
def owner_row(F: ti.template(), b, i, j):
    """Pool row of the contact of ball i with its owner j if it was open when this step
    began, else -1: a walk of j's slots as they were then (contacts.slot_prev), whose
    partners and rows no thread changes in this step (j's thread claims only slots free
    then, partner_slot, and rewrites slot_mask, not slot_prev). Ball i's visit reads
    the owner's history from that row (parallel mode)."""
    row = -1
    mask = F.contacts.slot_prev[b, j] >> S.WALLS
    k = S.WALLS
    while mask:
        if mask & 1 and F.contacts.slot_partner[b, j, k] == i:
            row = F.contacts.slot_row[b, j, k]
        mask >>= 1
        k += 1
    return row


@ti.func
def keep_open_mask(F: ti.template(), b, i):
    """Ball i's open slots as the next step begins, for its partners' owner_row (after
    release_rows; reorder.py and mill.py keep it too)."""
    if ti.static(F.prev_mask):
        F.contacts.slot_prev[b, i] = F.contacts.slot_mask[b, i]
