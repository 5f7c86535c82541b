"""Collision events: a contact's accumulators opened and updated in its pool row, the
event record written when it closes, and the dissipation ledger by mechanism
(docs/model.md, collision events)."""

from taimill.model import spectra as SP
from taimill.physics import state as S
from taimill.physics.ti import ti


@ti.func
def book_contact(F: ti.template(), b, row, is_new, t, u, udot, slip, p, fn, dn, dtf):
    """Open (is_new) or update the event in pool row `row`. Returns the contact's
    class for the mechanism ledger: an impact while its onset normal speed reaches the
    stress-event threshold and it is younger than the impact age (model/mechanisms.py)."""
    impact = False
    if is_new:
        q = ti.Vector([t, udot, slip.norm(), p[0], p[1], p[2], fn, u, dn, dtf])
        if ti.static(F.pool_width == S.SLOT_DATA):
            F.contacts.pool[b, row] = q
        else:  # the history columns are the history model's (pool.write_history)
            for c in ti.static(range(S.SLOT_DATA)):
                F.contacts.pool[b, row][c] = q[c]
        impact = udot >= F.model.stress_un[b]
    else:
        q = F.contacts.pool[b, row]
        q[S.SLOT_FPEAK] = ti.max(q[S.SLOT_FPEAK], fn)
        q[S.SLOT_UPEAK] = ti.max(q[S.SLOT_UPEAK], u)
        q[S.SLOT_DN] += dn
        q[S.SLOT_DT] += dtf
        if ti.static(F.pool_width == S.SLOT_DATA):
            F.contacts.pool[b, row] = q
        else:  # not the history: in parallel mode the partner's thread reads it meanwhile
            for c in ti.static(range(S.SLOT_DATA)):
                F.contacts.pool[b, row][c] = q[c]
        impact = q[S.SLOT_UN] >= F.model.stress_un[b] and t - q[S.SLOT_T0] <= F.model.impact_age[b]
    return impact


@ti.func
def emit_event(F: ti.template(), b, i, k, t):
    q = F.contacts.pool[b, F.contacts.slot_row[b, i, k]]
    mi = F.model.m[b, i]
    body_j, kind, m_eff = -1.0 - k, 1.0, mi
    if k >= S.WALLS:
        j = F.contacts.slot_partner[b, i, k]
        body_j, kind, m_eff = ti.cast(S.user_id(F, b, j), ti.f64), 0.0, mi * F.model.m[b, j] / (mi + F.model.m[b, j])
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
    e = ti.atomic_add(F.out.n_events[b], 1)
    if e < F.event_capacity:
        F.out.events[b, e] = row
    if q[S.SLOT_T0] >= F.model.spectra_from[b]:
        add_to_spectra(F, b, ti.cast(kind, ti.i32), q, m_eff)


@ti.func
def add_to_spectra(F: ti.template(), b, kind, q, m_eff):
    """Add a closing event to its mill's spectra: its class by its onset normal speed,
    its four energies (taimill.model.spectra.event_energies computes them the same way)."""
    cls = ti.select(q[S.SLOT_UN] >= F.model.stress_un[b], 0, 1)
    half_m = 0.5 * m_eff
    add_energy(F, b, kind, cls, 0, q[S.SLOT_DN])
    add_energy(F, b, kind, cls, 1, q[S.SLOT_DT])
    add_energy(F, b, kind, cls, 2, half_m * (q[S.SLOT_UN] * q[S.SLOT_UN]))
    add_energy(F, b, kind, cls, 3, half_m * (q[S.SLOT_UT] * q[S.SLOT_UT]))


@ti.func
def add_energy(F: ti.template(), b, kind, cls, measure, e):
    """One event of energy e (J) into its bin: the number of edges at or below e (a
    binary search, as numpy.searchsorted side="right"), its energy in the bin's fixed
    point. Integers: the sums do not depend on the order the events arrive in."""
    lo, hi = 0, ti.static(len(SP.EDGES))
    while lo < hi:
        mid = (lo + hi) // 2
        if F.model.spectrum_edges[mid] <= e:
            lo = mid + 1
        else:
            hi = mid
    ti.atomic_add(F.out.spectrum_count[b, kind, cls, measure, lo], 1)
    ti.atomic_add(F.out.spectrum_fixed[b, kind, cls, measure, lo],
                  ti.cast(ti.floor(e * F.model.spectrum_scale[lo] + 0.5), ti.i64))


@ti.func
def close_events(F: ti.template(), b, i, was_open, seen, t):
    """Contacts open before this step and not seen in it have separated: their events
    are written, their rows released after the pass (release_rows)."""
    gone = was_open & ~seen
    F.contacts.slot_closed[b, i] = gone
    k = 0
    while gone:
        if gone & 1:
            emit_event(F, b, i, k, t)
        gone >>= 1
        k += 1
    F.contacts.slot_mask[b, i] = seen


@ti.func
def book_mechanism(F: ti.template(), b, i, kind, impact, dn, dtf):
    """Add a contact's normal and friction dissipation of this step to its kind and
    class in ball i's mechanism ledger (state.NMECH layout). Booked here, in the force
    pass, so a frame's mechanism columns include its own step, which `dissipated`
    books after the frame: they differ by at most one step's dissipation."""
    c = kind * 4 + ti.select(impact, 0, 2)
    F.state.mech[b, i, c] = F.state.mech[b, i, c] + dn  # one writer per ball: no atomic (integrator.integrate)
    F.state.mech[b, i, c + 1] = F.state.mech[b, i, c + 1] + dtf
