"""Neighbour loop: every contact force on one ball, gathered into its own slot (no
atomics), and the collision events the integrator detects itself
(docs/model.md, collision events). Ball i visits every ball on its Verlet list
(neighbours.py) that overlaps it, in list order; the pair function is antisymmetric
to the bit, so both visits of a pair give exactly opposite forces and momentum is
exact. (A half loop scattering to j was measured 40 % slower.)
In fused mode (one thread per mill, balls in index order) the owner leaves the
partner's force and torque in its slot and the partner's visit reads them
(partner_share): the same numbers without computing the contact twice. In parallel
mode both balls compute it; a contact model with history keeps its history in the
owner's pool row, in two blocks by step parity (pool.history_block), and the partner
reads the block the owner reads, through the owner's slots as they were at the step's
start (pool.owner_row), so it computes what the owner computes, on any thread.

The lower own index owns a pair (state.owns; in parallel mode the rows are in grid
order, reorder.py, and a ball's own index is F.state.user_of of its row): only it books the
event, the dissipation and the stored energy. Walls are owned by the ball. Open events live in per-ball slots flagged in a
bitmask: bits 0-2 the walls, 3.. the partners. An event opens at the first step with
overlap u > 0 — its onset normal speed u̇_n and slip u̇_t are taken from that step's
state, before its first force acts — and closes at the first step without overlap.

The contact response (response.py), the open-contact pool (pool.py) and the events
(events.py) are in their own modules.
"""

from taimill.physics import state as S
from taimill.physics.events import book_contact, book_mechanism, close_events
from taimill.physics.frame import wall_velocity_ground
from taimill.physics.pool import claim_row, history_block, owner_row, read_history, read_springs, slot_row, write_history
from taimill.physics.response import contact_energy, contact_response, rolling_response
from taimill.physics.ti import ti
from taimill.physics.walls import wall_near


@ti.func
def partner_share(F: ti.template(), b, i, j):
    """Slot of owner j holding its contact with ball i > j booked earlier in this step,
    whose force and torque on i it left there (share_with_partner); -1 if none or if
    the balls' forces are not computed in index order (F.share_pairs: the fused mode)."""
    found = -1
    if ti.static(F.share_pairs):
        if i > j:
            mask = F.contacts.slot_mask[b, j] >> S.WALLS
            k = S.WALLS
            while mask:
                if mask & 1 and F.contacts.slot_partner[b, j, k] == i:
                    found = k
                k += 1
                mask >>= 1
    return found


@ti.func
def share_with_partner(F: ti.template(), b, i, k, f, tq):
    """Leave the force and torque on the partner of ball i's slot k for its own visit
    (partner_share). The pair function is antisymmetric to the bit, so these are the
    values its visit would compute: -F and a_j × (-F)."""
    if ti.static(F.share_pairs):
        F.contacts.pair_f[b, i, k] = f
        F.contacts.pair_tq[b, i, k] = tq


@ti.func
def ball_pair(F: ti.template(), b, i, j, was_open, seen, t, w, dt, block):
    """Contact of balls i and j: (force on i, torque on i, dissipated normal and by
    friction, whether it is an impact, stored, slot bit of i's event or 0). Events and
    the ledger are booked by the owner, i < j. block: the history block this step reads
    (pool.history_block)."""
    f = ti.Vector([0.0, 0.0, 0.0])
    tq = ti.Vector([0.0, 0.0, 0.0])
    diss_n, diss_t, impact, stored, bit = 0.0, 0.0, False, 0.0, 0
    xi, xj = F.state.x[b, i], F.state.x[b, j]
    ri, rj = F.model.r[b, i], F.model.r[b, j]
    d = xj - xi
    dist2 = d.norm_sqr()
    touching = dist2 < (ri + rj) * (ri + rj)
    shared = -1
    if touching:
        shared = partner_share(F, b, i, j)
    if shared >= 0:  # the owner j computed this contact in this step
        f, tq = F.contacts.pair_f[b, j, shared], F.contacts.pair_tq[b, j, shared]
    elif touching:
        dist = ti.sqrt(dist2)
        u = ri + rj - dist
        nrm = d / dist
        ai = nrm * (ri - 0.5 * u)
        aj = -nrm * (rj - 0.5 * u)
        wz = ti.Vector([0.0, 0.0, w])
        vrel = (F.state.v[b, i] + (F.state.s[b, i] - wz).cross(ai)) - (F.state.v[b, j] + (F.state.s[b, j] - wz).cross(aj))
        mi, mj = F.model.m[b, i], F.model.m[b, j]
        m_eff = mi * mj / (mi + mj)
        inv_mass_t = (F.model.inv_m[b, i] + F.model.inv_m[b, j]) + (ai.norm_sqr() * F.model.inv_i[b, i] + aj.norm_sqr() * F.model.inv_i[b, j])
        owner = S.owns(F, b, i, j)
        k, row, is_new = -1, -1, False
        hist_t, e_t, hist_r, e_r = ti.Vector([0.0, 0.0, 0.0]), 0.0, ti.Vector([0.0, 0.0, 0.0]), 0.0
        if ti.static(F.history[0]):  # the history is read before the response
            if owner:
                k, row, is_new = claim_row(F, b, i, j, was_open | seen, was_open)
                hist_t, e_t, hist_r, e_r = read_history(F, b, row, is_new, block)
            elif ti.static(F.prev_mask):
                # The partner reads the owner's history, negated: it is kept from the
                # owner's side, and the response is antisymmetric to the bit in it too
                # (ξ + slip dt, its projection and the cap; M_r + k_r dt ω_r and its
                # cap). No row: the contact opens in this step, with zero history,
                # exactly when the owner's claim finds it new: the owner's slots open
                # at the step's start (slot_mask then, slot_prev now) hold a slot for
                # ball i iff owner_row finds it, and the slots it opens in this step
                # before reaching i are for other balls (a list names a ball once).
                prev = owner_row(F, b, i, j)
                hist_t, hist_r = read_springs(F, b, prev, prev < 0, block)
                hist_t, hist_r = -hist_t, -hist_r
        fc, udot, slip, fn, fel, ft, new_t, new_e_t = contact_response(F, b, 0, u, nrm, vrel, m_eff, inv_mass_t, dt,
                                                                       hist_t)
        f, tq = fc, ai.cross(fc)
        m_roll = ti.Vector([0.0, 0.0, 0.0])  # rolling-resistance torque on i; on j it is -m_roll to the bit
        d_roll, new_r, new_e_r = 0.0, hist_r, 0.0
        if F.model.mu_r[b, 0] > 0.0:  # off: not computed, runs without it stay bit-identical
            m_roll, d_roll, new_r, new_e_r = rolling_response(F, b, 0, F.state.s[b, i] - F.state.s[b, j], nrm, fn, fel, u,
                                                              ri * rj / (ri + rj), F.model.inv_i[b, i] + F.model.inv_i[b, j], dt,
                                                              hist_r)
            tq += m_roll
        if owner:
            dn, dtf, el = contact_energy(F, b, 0, u, udot, slip, fn, fel, ft, m_eff, inv_mass_t, dt)
            if F.model.mu_r[b, 0] > 0.0:
                dtf += d_roll
            if ti.static(F.history[0]):  # what the springs store is not dissipated: the ledger holds it
                dtf -= (new_e_t - e_t) + (new_e_r - e_r)
                el += new_e_t + new_e_r
            else:
                k, row, is_new = claim_row(F, b, i, j, was_open | seen, was_open)
            diss_n, diss_t, stored = dn, dtf, el
            if row >= 0:
                bit = 1 << k
                impact = book_contact(F, b, row, is_new, t, u, udot, slip, xi + ai, fn, dn, dtf)
                if ti.static(F.history[0]):
                    write_history(F, b, row, block, new_t, new_e_t, new_r, new_e_r)
                share_with_partner(F, b, i, k, -fc, aj.cross(-fc) - m_roll)
    return f, tq, diss_n, diss_t, impact, stored, bit


@ti.func
def ball_forces(F: ti.template(), b, i, t, dr, dt):
    """Contact forces and torques on ball i of mill b from the walls and the balls on
    its neighbour list; books events and the energy ledger (drive work, dissipation,
    stored elastic energy)."""
    xi, vi, si, ri, mi = F.state.x[b, i], F.state.v[b, i], F.state.s[b, i], F.model.r[b, i], F.model.m[b, i]
    w = dr.w
    wz = ti.Vector([0.0, 0.0, w])
    f = ti.Vector([0.0, 0.0, 0.0])
    tq = ti.Vector([0.0, 0.0, 0.0])
    drive, diss, stored = 0.0, 0.0, 0.0
    was_open = F.contacts.slot_mask[b, i]
    seen = 0
    block = 0
    if ti.static(F.history[0] or F.history[1]):
        block = history_block(F, b)
    for wall in ti.static(range(S.WALLS)):
        phi, grad = wall_near(F, b, i, wall, xi, ri)  # exact where φ < r: all that matters here
        u = ri - phi
        if phi < -ri:  # centre beyond the wall: it tunnelled (dt too large for the stiffness)
            F.state.status[b] = S.ESCAPED
            F.state.bad_ball[b] = S.user_id(F, b, i)
        elif u > 0.0:
            nrm = -grad
            a = nrm * (ri - 0.5 * u)
            vrel = vi + (si - wz).cross(a)
            inv_mass_t = F.model.inv_m[b, i] + a.norm_sqr() * F.model.inv_i[b, i]
            is_new = (was_open & (1 << wall)) == 0
            row = -1
            hist_t, e_t, hist_r, e_r = ti.Vector([0.0, 0.0, 0.0]), 0.0, ti.Vector([0.0, 0.0, 0.0]), 0.0
            if ti.static(F.history[1]):
                row = slot_row(F, b, i, wall, is_new, was_open | seen)
                hist_t, e_t, hist_r, e_r = read_history(F, b, row, is_new, block)
            fc, udot, slip, fn, fel, ft, new_t, new_e_t = contact_response(F, b, 1, u, nrm, vrel, mi, inv_mass_t, dt,
                                                                           hist_t)
            dn, dtf, el = contact_energy(F, b, 1, u, udot, slip, fn, fel, ft, mi, inv_mass_t, dt)
            f += fc
            tq += a.cross(fc)
            p = xi + a
            drive += fc.dot(wall_velocity_ground(p, dr, F.model.plate_radius[b])) * dt
            new_r, new_e_r = hist_r, 0.0
            if F.model.mu_r[b, 1] > 0.0:  # the wall turns with the jar: its torque's power w ẑ·M is drive work
                mr, d_roll, new_r_w, new_e_r_w = rolling_response(F, b, 1, si - wz, nrm, fn, fel, u, ri, F.model.inv_i[b, i],
                                                                  dt, hist_r)
                new_r, new_e_r = new_r_w, new_e_r_w
                tq += mr
                dtf += d_roll
                drive += mr.dot(wz) * dt
            if ti.static(F.history[1]):  # what the springs store is not dissipated: the ledger holds it
                dtf -= (new_e_t - e_t) + (new_e_r - e_r)
                el += new_e_t + new_e_r
            else:
                row = slot_row(F, b, i, wall, is_new, was_open | seen)
            diss += dn + dtf
            stored += el
            impact = False
            if row >= 0:
                seen |= 1 << wall
                impact = book_contact(F, b, row, is_new, t, u, udot, slip, p, fn, dn, dtf)
                if ti.static(F.history[1]):
                    write_history(F, b, row, block, new_t, new_e_t, new_r, new_e_r)
            book_mechanism(F, b, i, 1 + wall, impact, dn, dtf)
    # The neighbours that touch are gathered first, without a branch: whether one
    # touches is often a coin toss (on a bed 4.7 of 11.6), and a mispredicted branch
    # per list entry kept the CPU from overlapping the contacts' evaluations.
    touching = ti.Vector([0] * S.NEIGHBOURS, dt=ti.i32)
    n_touching = 0
    for q in range(F.spatial.nbr_count[b, i]):
        j = F.spatial.nbr[b, i, q]
        rr = ri + F.model.r[b, j]
        touching[n_touching] = j
        n_touching += ti.cast((F.state.x[b, j] - xi).norm_sqr() < rr * rr, ti.i32)
    for q in range(n_touching):
        j = touching[q]
        fj, tj, dnj, dtj, impact, ej, bit = ball_pair(F, b, i, j, was_open, seen, t, w, dt, block)
        f += fj
        tq += tj
        diss += dnj + dtj
        if dnj != 0.0 or dtj != 0.0:
            book_mechanism(F, b, i, 0, impact, dnj, dtj)
        stored += ej
        seen |= bit
    close_events(F, b, i, was_open, seen, t)
    F.state.f[b, i] = f
    F.state.tau[b, i] = tq
    F.state.drive_step[b, i] = drive
    F.state.diss_step[b, i] = diss
    F.state.elastic[b, i] = stored
