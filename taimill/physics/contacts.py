"""Neighbour loop: every contact force on one ball, gathered into its own slot (no
atomics), and the collision events the integrator detects itself
(docs/model.md, collision events). Ball i visits every ball on its Verlet list
(neighbours.py) that overlaps it, in list order; the pair function is antisymmetric
to the bit, so both visits of a pair give exactly opposite forces and momentum is
exact. (A half loop scattering to j was measured 40 % slower.)
In fused mode (one thread per mill, balls in index order) the owner leaves the
partner's force and torque in its slot and the partner's visit reads them
(partner_share): the same numbers without computing the contact twice.

The lower own index owns a pair (state.owns; in parallel mode the rows are in grid
order, reorder.py, and a ball's own index is F.user_of of its row): only it books the
event, the dissipation and the stored energy. Walls are owned by the ball. Open events live in per-ball slots flagged in a
bitmask: bits 0-2 the walls, 3.. the partners. An event opens at the first step with
overlap u > 0 — its onset normal speed u̇_n and slip u̇_t are taken from that step's
state, before its first force acts — and closes at the first step without overlap.

A slot holds only the index of its event's row in the mill's pool of open-contact rows
(state.pool_rows: at most 6 a ball in large mills; a dense bed has 2-3, not 15). A
contact that opens takes one of its owner's home rows (state.HOME_ROWS) if one is free,
else a released row from the shared stack, else a new one (atomic pop and count: in
parallel mode the balls of the mill do it concurrently); rows are released only after
the force pass, by release_rows in the integration pass, so pops and pushes never race.
Which row a contact gets changes nothing but where its sums are kept.
"""

import taichi as ti

from taimill.physics import state as S
from taimill.physics.frame import wall_velocity_ground
from taimill.physics.laws import ROLLING, TANGENTIAL, elastic_energy, normal_force
from taimill.physics.walls import wall_near


@ti.func
def respond(model: ti.template(), F: ti.template(), b, ct: ti.template(), u, udot, slip, m_eff, inv_mass_t, dt):
    """(F_n, elastic F_n, friction force) of the ContactModel `model` (compiled in)."""
    fn, fel = normal_force(model.normal, u, udot, F.law_k[b, ct], F.law_c[b, ct], F.law_d[b, ct], m_eff)
    ft = TANGENTIAL[model.tangential.name](slip, fn, F.mu_s[b, ct], F.mu_d[b, ct], F.v_s[b, ct],
                                                      F.v_d[b, ct], inv_mass_t, dt)
    return fn, fel, ft


@ti.func
def contact_response(F: ti.template(), b, ct: ti.template(), u, nrm, vrel, m_eff, inv_mass_t, dt):
    """Force on the first body at a contact of type ct (0 ball-ball, 1 ball-wall) with
    overlap u, unit normal nrm (first body → second), relative contact-point velocity
    vrel. Returns (force, u̇, slip, F_n, elastic F_n, friction force). The contact model
    is the engine's only one for ct (F.models[ct], compiled in), or, when a batch mixes
    models, the one F.variant[b, ct] picks among them. Rolling resistance (if on) is
    added by the caller, who knows the spins; its work is booked with the friction work
    (the shear part of the contact's dissipation)."""
    udot = vrel.dot(nrm)
    slip = vrel - udot * nrm
    fn, fel = 0.0, 0.0
    ft = ti.Vector([0.0, 0.0, 0.0])
    if ti.static(len(F.models[ct]) == 1):
        fn, fel, ft = respond(F.models[ct][0], F, b, ct, u, udot, slip, m_eff, inv_mass_t, dt)
    else:
        for v in ti.static(range(len(F.models[ct]))):
            if F.variant[b, ct] == v:
                fn, fel, ft = respond(F.models[ct][v], F, b, ct, u, udot, slip, m_eff, inv_mass_t, dt)
    return -fn * nrm + ft, udot, slip, fn, fel, ft


@ti.func
def stored_energy(F: ti.template(), b, ct: ti.template(), u, fel):
    """Energy (J) in the spring of a contact of type ct with overlap u, elastic force fel."""
    el = 0.0
    if ti.static(len(F.models[ct]) == 1):
        el = elastic_energy(u, fel, ti.static(F.models[ct][0].normal.n))
    else:
        for v in ti.static(range(len(F.models[ct]))):
            if F.variant[b, ct] == v:
                el = elastic_energy(u, fel, ti.static(F.models[ct][v].normal.n))
    return el


@ti.func
def rolling_response(F: ti.template(), b, ct: ti.template(), spin_rel, nrm, fn, r_eff, inv_inertia, dt):
    """(torque on the first body, energy dissipated over the step) of the rolling model
    of contact type ct; the caller calls it only while F.mu_r[b, ct] > 0."""
    tq = ti.Vector([0.0, 0.0, 0.0])
    d = 0.0
    if ti.static(len(F.models[ct]) == 1):
        tq, d = ROLLING[F.models[ct][0].rolling.name](spin_rel, nrm, fn, F.mu_r[b, ct], r_eff, inv_inertia, dt)
    else:
        for v in ti.static(range(len(F.models[ct]))):
            if F.variant[b, ct] == v:
                tq, d = ROLLING[F.models[ct][v].rolling.name](spin_rel, nrm, fn, F.mu_r[b, ct], r_eff,
                                                                          inv_inertia, dt)
    return tq, d


@ti.func
def contact_energy(F: ti.template(), b, ct: ti.template(), u, udot, slip, fn, fel, ft, m_eff, inv_mass_t, dt):
    """What a contact's owner books of its response (contact_response): (normal
    dissipation, friction dissipation, stored elastic energy U). Dissipation over the
    step, (F - F_el) u̇ (damper and clamp) and -F_t · slip (friction), with u̇ and slip at
    mid-step as this contact's own impulse changes them: start-of-step values overstate
    it, most for stiff near-stick friction. (Only the owner's visit computes it: 3 %
    of a bed's force pass.)"""
    udot_mid = udot - 0.5 * fn * dt / m_eff
    dn = (fn - fel) * udot_mid * dt
    dtf = (-ft.dot(slip) - 0.5 * ft.norm_sqr() * inv_mass_t * dt) * dt
    return dn, dtf, stored_energy(F, b, ct, u, fel)


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
                    r = F.slot_row[b, i, s] - i * F.home
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
            e = ti.atomic_sub(F.pool_top[b], 1) - 1  # a released row first
            if e >= 0:
                row = F.pool_free[b, e]
            else:  # the stack is empty (its top goes negative until release_rows): a new row
                row = F.spill_base + ti.atomic_add(F.pool_used[b], 1)
                if row >= F.pool_capacity:
                    row = -1
                    F.status[b] = S.POOL_FULL
                    F.bad_ball[b] = S.user_id(F, b, i)
        if row >= 0:
            F.slot_row[b, i, k] = row
    else:
        row = F.slot_row[b, i, k]
    return row


@ti.func
def pool_settle(F: ti.template(), b):
    """After the force pass, before release_rows: the stack is empty if pops ran past it."""
    if F.pool_top[b] < 0:
        F.pool_top[b] = 0


@ti.func
def release_rows(F: ti.template(), b, i):
    """Give the pool rows of ball i's events closed in this step's force pass back: a
    home row to ball i, a shared one to the free stack (a pass without pops:
    pool_settle first)."""
    gone = F.slot_closed[b, i]
    if gone:
        k = 0
        while gone:
            if gone & 1:
                row = F.slot_row[b, i, k]
                if row >= F.spill_base:  # a home row is free once no slot holds it
                    F.pool_free[b, ti.atomic_add(F.pool_top[b], 1)] = row
            gone >>= 1
            k += 1
        F.slot_closed[b, i] = 0


@ti.func
def book_contact(F: ti.template(), b, row, is_new, t, u, udot, slip, p, fn, dn, dtf):
    """Open (is_new) or update the event in pool row `row`. Returns the contact's
    class for the mechanism ledger: an impact while its onset normal speed reaches the
    stress-event threshold and it is younger than the impact age (model/mechanisms.py)."""
    impact = False
    if is_new:
        F.pool[b, row] = ti.Vector([t, udot, slip.norm(), p[0], p[1], p[2], fn, u, dn, dtf])
        impact = udot >= F.stress_un[b]
    else:
        q = F.pool[b, row]
        q[S.SLOT_FPEAK] = ti.max(q[S.SLOT_FPEAK], fn)
        q[S.SLOT_UPEAK] = ti.max(q[S.SLOT_UPEAK], u)
        q[S.SLOT_DN] += dn
        q[S.SLOT_DT] += dtf
        F.pool[b, row] = q
        impact = q[S.SLOT_UN] >= F.stress_un[b] and t - q[S.SLOT_T0] <= F.impact_age[b]
    return impact


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
        if mask & 1 and F.slot_partner[b, i, k] == j:
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
            F.slot_partner[b, i, free] = j
    return found


@ti.func
def emit_event(F: ti.template(), b, i, k, t):
    q = F.pool[b, F.slot_row[b, i, k]]
    mi = F.m[b, i]
    body_j, kind, m_eff = -1.0 - k, 1.0, mi
    if k >= S.WALLS:
        j = F.slot_partner[b, i, k]
        body_j, kind, m_eff = ti.cast(S.user_id(F, b, j), ti.f64), 0.0, mi * F.m[b, j] / (mi + F.m[b, j])
    row = ti.Vector.zero(ti.f64, S.NCOL)  # the schema's event columns, by name
    row[S.EV["t_start"]] = q[S.SLOT_T0]
    row[S.EV["duration"]] = t - q[S.SLOT_T0]
    row[S.EV["body_i"]] = ti.cast(S.user_id(F, b, i), ti.f64)
    row[S.EV["body_j"]] = body_j
    row[S.EV["kind"]] = kind
    row[S.EV["x"]] = q[S.SLOT_PX]
    row[S.EV["y"]] = q[S.SLOT_PY]
    row[S.EV["z"]] = q[S.SLOT_PZ]
    row[S.EV["un"]] = q[S.SLOT_UN]
    row[S.EV["ut"]] = q[S.SLOT_UT]
    row[S.EV["m_eff"]] = m_eff
    row[S.EV["peak_force"]] = q[S.SLOT_FPEAK]
    row[S.EV["peak_penetration"]] = q[S.SLOT_UPEAK]
    row[S.EV["dissipated_normal"]] = q[S.SLOT_DN]
    row[S.EV["dissipated_friction"]] = q[S.SLOT_DT]
    e = ti.atomic_add(F.n_events[b], 1)
    if e < F.event_capacity:
        F.events[b, e] = row


@ti.func
def close_events(F: ti.template(), b, i, was_open, seen, t):
    """Contacts open before this step and not seen in it have separated: their events
    are written, their rows released after the pass (release_rows)."""
    gone = was_open & ~seen
    F.slot_closed[b, i] = gone
    k = 0
    while gone:
        if gone & 1:
            emit_event(F, b, i, k, t)
        gone >>= 1
        k += 1
    F.slot_mask[b, i] = seen


@ti.func
def book_mechanism(F: ti.template(), b, i, kind, impact, dn, dtf):
    """Add a contact's normal and friction dissipation of this step to its kind and
    class in ball i's mechanism ledger (state.NMECH layout). Booked here, in the force
    pass, so a frame's mechanism columns include its own step, which `dissipated`
    books after the frame: they differ by at most one step's dissipation."""
    c = kind * 4 + ti.select(impact, 0, 2)
    F.mech[b, i, c] = F.mech[b, i, c] + dn  # one writer per ball: no atomic (integrator.integrate)
    F.mech[b, i, c + 1] = F.mech[b, i, c + 1] + dtf


@ti.func
def partner_share(F: ti.template(), b, i, j):
    """Slot of owner j holding its contact with ball i > j booked earlier in this step,
    whose force and torque on i it left there (share_with_partner); -1 if none or if
    the balls' forces are not computed in index order (F.share_pairs: the fused mode)."""
    found = -1
    if ti.static(F.share_pairs):
        if i > j:
            mask = F.slot_mask[b, j] >> S.WALLS
            k = S.WALLS
            while mask:
                if mask & 1 and F.slot_partner[b, j, k] == i:
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
        F.pair_f[b, i, k] = f
        F.pair_tq[b, i, k] = tq


@ti.func
def ball_pair(F: ti.template(), b, i, j, was_open, seen, t, w, dt):
    """Contact of balls i and j: (force on i, torque on i, dissipated normal and by
    friction, whether it is an impact, stored, slot bit of i's event or 0). Events and
    the ledger are booked by the owner, i < j."""
    f = ti.Vector([0.0, 0.0, 0.0])
    tq = ti.Vector([0.0, 0.0, 0.0])
    diss_n, diss_t, impact, stored, bit = 0.0, 0.0, False, 0.0, 0
    xi, xj = F.x[b, i], F.x[b, j]
    ri, rj = F.r[b, i], F.r[b, j]
    d = xj - xi
    dist2 = d.norm_sqr()
    touching = dist2 < (ri + rj) * (ri + rj)
    shared = -1
    if touching:
        shared = partner_share(F, b, i, j)
    if shared >= 0:  # the owner j computed this contact in this step
        f, tq = F.pair_f[b, j, shared], F.pair_tq[b, j, shared]
    elif touching:
        dist = ti.sqrt(dist2)
        u = ri + rj - dist
        nrm = d / dist
        ai = nrm * (ri - 0.5 * u)
        aj = -nrm * (rj - 0.5 * u)
        wz = ti.Vector([0.0, 0.0, w])
        vrel = (F.v[b, i] + (F.s[b, i] - wz).cross(ai)) - (F.v[b, j] + (F.s[b, j] - wz).cross(aj))
        mi, mj = F.m[b, i], F.m[b, j]
        m_eff = mi * mj / (mi + mj)
        inv_mass_t = (F.inv_m[b, i] + F.inv_m[b, j]) + (ai.norm_sqr() * F.inv_i[b, i] + aj.norm_sqr() * F.inv_i[b, j])
        fc, udot, slip, fn, fel, ft = contact_response(F, b, 0, u, nrm, vrel, m_eff, inv_mass_t, dt)
        f, tq = fc, ai.cross(fc)
        m_roll = ti.Vector([0.0, 0.0, 0.0])  # rolling-resistance torque on i; on j it is -m_roll to the bit
        d_roll = 0.0
        if F.mu_r[b, 0] > 0.0:  # off: not computed, runs without it stay bit-identical
            m_roll, d_roll = rolling_response(F, b, 0, F.s[b, i] - F.s[b, j], nrm, fn, ri * rj / (ri + rj),
                                              F.inv_i[b, i] + F.inv_i[b, j], dt)
            tq += m_roll
        if S.owns(F, b, i, j):
            dn, dtf, el = contact_energy(F, b, 0, u, udot, slip, fn, fel, ft, m_eff, inv_mass_t, dt)
            if F.mu_r[b, 0] > 0.0:
                dtf += d_roll
            diss_n, diss_t, stored = dn, dtf, el
            k = partner_slot(F, b, i, j, was_open | seen)
            if k < 0:
                F.status[b] = S.SLOTS_FULL
                F.bad_ball[b] = S.user_id(F, b, i)
            else:
                is_new = (was_open & (1 << k)) == 0
                row = slot_row(F, b, i, k, is_new, was_open | seen)
                if row >= 0:
                    bit = 1 << k
                    impact = book_contact(F, b, row, is_new, t, u, udot, slip, xi + ai, fn, dn, dtf)
                    share_with_partner(F, b, i, k, -fc, aj.cross(-fc) - m_roll)
    return f, tq, diss_n, diss_t, impact, stored, bit


@ti.func
def ball_forces(F: ti.template(), b, i, t, dr, dt):
    """Contact forces and torques on ball i of mill b from the walls and the balls on
    its neighbour list; books events and the energy ledger (drive work, dissipation,
    stored elastic energy)."""
    xi, vi, si, ri, mi = F.x[b, i], F.v[b, i], F.s[b, i], F.r[b, i], F.m[b, i]
    w = dr.w
    wz = ti.Vector([0.0, 0.0, w])
    f = ti.Vector([0.0, 0.0, 0.0])
    tq = ti.Vector([0.0, 0.0, 0.0])
    drive, diss, stored = 0.0, 0.0, 0.0
    was_open = F.slot_mask[b, i]
    seen = 0
    for wall in ti.static(range(S.WALLS)):
        phi, grad = wall_near(F, b, i, wall, xi, ri)  # exact where φ < r: all that matters here
        u = ri - phi
        if phi < -ri:  # centre beyond the wall: it tunnelled (dt too large for the stiffness)
            F.status[b] = S.ESCAPED
            F.bad_ball[b] = S.user_id(F, b, i)
        elif u > 0.0:
            nrm = -grad
            a = nrm * (ri - 0.5 * u)
            vrel = vi + (si - wz).cross(a)
            inv_mass_t = F.inv_m[b, i] + a.norm_sqr() * F.inv_i[b, i]
            fc, udot, slip, fn, fel, ft = contact_response(F, b, 1, u, nrm, vrel, mi, inv_mass_t, dt)
            dn, dtf, el = contact_energy(F, b, 1, u, udot, slip, fn, fel, ft, mi, inv_mass_t, dt)
            f += fc
            tq += a.cross(fc)
            p = xi + a
            drive += fc.dot(wall_velocity_ground(p, dr, F.plate_radius[b])) * dt
            if F.mu_r[b, 1] > 0.0:  # the wall turns with the jar: its torque's power w ẑ·M is drive work
                mr, d_roll = rolling_response(F, b, 1, si - wz, nrm, fn, ri, F.inv_i[b, i], dt)
                tq += mr
                dtf += d_roll
                drive += mr.dot(wz) * dt
            diss += dn + dtf
            stored += el
            is_new = (was_open & (1 << wall)) == 0
            row = slot_row(F, b, i, wall, is_new, was_open | seen)
            impact = False
            if row >= 0:
                seen |= 1 << wall
                impact = book_contact(F, b, row, is_new, t, u, udot, slip, p, fn, dn, dtf)
            book_mechanism(F, b, i, 1 + wall, impact, dn, dtf)
    # The neighbours that touch are gathered first, without a branch: whether one
    # touches is often a coin toss (on a bed 4.7 of 11.6), and a mispredicted branch
    # per list entry kept the CPU from overlapping the contacts' evaluations.
    touching = ti.Vector([0] * S.NEIGHBOURS, dt=ti.i32)
    n_touching = 0
    for q in range(F.nbr_count[b, i]):
        j = F.nbr[b, i, q]
        rr = ri + F.r[b, j]
        touching[n_touching] = j
        n_touching += ti.cast((F.x[b, j] - xi).norm_sqr() < rr * rr, ti.i32)
    for q in range(n_touching):
        j = touching[q]
        fj, tj, dnj, dtj, impact, ej, bit = ball_pair(F, b, i, j, was_open, seen, t, w, dt)
        f += fj
        tq += tj
        diss += dnj + dtj
        if dnj != 0.0 or dtj != 0.0:
            book_mechanism(F, b, i, 0, impact, dnj, dtj)
        stored += ej
        seen |= bit
    close_events(F, b, i, was_open, seen, t)
    F.f[b, i] = f
    F.tau[b, i] = tq
    F.drive_step[b, i] = drive
    F.diss_step[b, i] = diss
    F.elastic[b, i] = stored
