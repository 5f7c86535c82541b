"""A frame of a mill: every ball's position, velocity and spin by own index, and the
energy ledger (ground-frame kinetic energy, m g z, stored elastic energy, drive work,
dissipation, dissipation by mechanism), J, taken after a step's forces and before its
integration (engine.py)."""

from taimill.physics import state as S
from taimill.physics.frame import ramp_at, wall_velocity_ground
from taimill.physics.ti import ti

# A frame's energy ledger sums every ball's share in own-index order, in blocks of
# state.LEDGER_BLOCK balls: each block from 0.0, then the blocks' sums in block order. Parallel
# mode sums the blocks on all threads and the fused mode one after another, with the
# same additions: both modes and every thread count give the same bits, and a mill of
# up to LEDGER_BLOCK balls the one running sum it always had.


@ti.func
def sum_blocks(F: ti.template(), b):
    return (F.model.n_balls[b] + S.LEDGER_BLOCK - 1) // S.LEDGER_BLOCK


@ti.func
def row(F: ti.template(), b, u):
    """The row of ball u (own index): its own index unless the rows are in grid order."""
    i = u
    if ti.static(F.reorder):
        i = F.state.row_of[b, u]
    return i


@ti.func
def frame_ball(F: ti.template(), b, k, u):
    """Ball u (own index) into frame k."""
    i = row(F, b, u)
    F.out.frame_x[b, k, u] = F.state.x[b, i]
    F.out.frame_v[b, k, u] = F.state.v[b, i]
    F.out.frame_s[b, k, u] = F.state.s[b, i]


@ti.func
def ledger_block(F: ti.template(), b, blk, dr):
    """The energy sums (S.LEDGER_SUMS: ground-frame kinetic energy, m g z, stored elastic
    energy, drive work, dissipation, dissipation by mechanism), J, of the balls of
    block blk, in own-index order."""
    sums = ti.Vector.zero(ti.f64, S.LEDGER_SUMS)
    for u in range(blk * S.LEDGER_BLOCK, ti.min((blk + 1) * S.LEDGER_BLOCK, F.model.n_balls[b])):
        i = row(F, b, u)
        x, v, s, m = F.state.x[b, i], F.state.v[b, i], F.state.s[b, i], F.model.m[b, i]
        vg = v + wall_velocity_ground(x, dr, F.model.plate_radius[b])
        sums[0] += 0.5 * m * vg.norm_sqr() + 0.5 * s.norm_sqr() / F.model.inv_i[b, i]
        sums[1] += m * F.model.gravity[b] * x[2]
        sums[2] += F.state.elastic[b, i]
        sums[3] += F.state.drive_work[b, i]
        sums[4] += F.state.dissipated[b, i]
        for c in ti.static(range(S.NMECH)):
            sums[5 + c] += F.state.mech[b, i, c]
    return sums


@ti.func
def frame_record(F: ti.template(), b, k, t, sums):
    """Frame k's time, drive and energy ledger (the schema's ledger columns, by name)
    from the blocks' total `sums`; the frame is then taken."""
    F.out.frame_t[b, k] = t
    om, _, phi_p = ramp_at(F.model.plate_ramp[b], t)
    w, _, phi_j = ramp_at(F.model.jar_ramp[b], t)
    F.out.frame_drive[b, k] = ti.Vector([phi_p, om, phi_j, w])  # DRIVE_FIELDS order
    row = ti.Vector.zero(ti.f64, S.NLEDGER)
    row[S.LEDGER["kinetic"]] = sums[0]
    row[S.LEDGER["potential"]] = sums[1]
    row[S.LEDGER["elastic"]] = sums[2]
    row[S.LEDGER["drive_work"]] = sums[3]
    row[S.LEDGER["dissipated"]] = sums[4]
    for c in ti.static(range(S.NMECH)):
        row[S.LEDGER[S.MECHANISM_COLUMNS[c]]] = sums[5 + c]
    F.out.frame_ledger[b, k] = row
    F.out.n_frames[b] = k + 1


@ti.func
def snapshot(F: ti.template(), b, t, dr):
    """Store a frame (balls by own index) and the energy ledger, in one thread."""
    k = F.out.n_frames[b]
    for u in range(F.model.n_balls[b]):
        frame_ball(F, b, k, u)
    sums = ledger_block(F, b, 0, dr)
    for blk in range(1, sum_blocks(F, b)):
        sums += ledger_block(F, b, blk, dr)
    frame_record(F, b, k, t, sums)
