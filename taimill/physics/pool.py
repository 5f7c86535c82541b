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
def read_history(F: ti.template(), b, row, is_new):
    """(tangential history ξ, its stored energy, rolling history M_r, its stored energy)
    of the contact in pool row `row`: zero for a new contact or without a row."""
    xi = ti.Vector([0.0, 0.0, 0.0])
    m_r = ti.Vector([0.0, 0.0, 0.0])
    e_xi, e_mr = 0.0, 0.0
    if row >= 0 and not is_new:
        q = F.contacts.pool[b, row]
        xi = ti.Vector([q[S.SLOT_XI], q[S.SLOT_XI + 1], q[S.SLOT_XI + 2]])
        m_r = ti.Vector([q[S.SLOT_MR], q[S.SLOT_MR + 1], q[S.SLOT_MR + 2]])
        e_xi, e_mr = q[S.SLOT_EXI], q[S.SLOT_EMR]
    return xi, e_xi, m_r, e_mr


@ti.func
def write_history(F: ti.template(), b, row, xi, e_xi, m_r, e_mr):
    """Keep a contact's history in its pool row for the next step."""
    for c in ti.static(range(3)):
        F.contacts.pool[b, row][S.SLOT_XI + c] = xi[c]
        F.contacts.pool[b, row][S.SLOT_MR + c] = m_r[c]
    F.contacts.pool[b, row][S.SLOT_EXI] = e_xi
    F.contacts.pool[b, row][S.SLOT_EMR] = e_mr
