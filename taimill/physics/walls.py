"""Jar walls as signed distance functions (positive inside) with their gradients.

A jar is a 2-D profile extruded between the floor (z = 0) and the lid (z = height).
Each ball can touch three walls at once — side, floor, lid — each its own contact with
its own event slot, so a ball resting in the floor/side corner feels both.

The profile is a G1 boundary of line and arc pieces built from the jar file's
primitives by taimill.model.geometry (geometry is data: a new jar needs no code); this is the Taichi
twin of geometry.profile_sdf, piece rows as documented there.
"""

from taimill.physics.ti import ti

SIDE, FLOOR, LID = 0, 1, 2
LINE, ARC = 0, 1
BIG = 1e9
# Slack of the bounds below, m: far beyond the rounding of distances of a few cm
# (≈ 1e-17 m), so a pruned piece or a skipped evaluation could never have changed a
# result, which stays bit-identical to the full scan.
BOUND_SLACK = 1e-9


@ti.func
def piece_closest(row, p):
    """(closest point, inward normal there) of one boundary piece to the 2-D point p."""
    q = ti.Vector([0.0, 0.0])
    n = ti.Vector([0.0, 0.0])
    if row[0] == LINE:
        a = ti.Vector([row[1], row[2]])
        ab = ti.Vector([row[3], row[4]]) - a
        t = ti.min(ti.max((p - a).dot(ab) / ab.dot(ab), 0.0), 1.0)
        q = a + t * ab
        n = ti.Vector([row[5], row[6]])
    else:
        c = ti.Vector([row[1], row[2]])
        d = p - c
        r = d.norm()
        u = ti.Vector([row[5], row[6]])  # at the centre every point is nearest: take the mid one
        if r > 0.0:
            u = d / r
        if u[0] * row[5] + u[1] * row[6] >= row[7]:
            q = c + row[3] * u
        else:
            e0 = ti.Vector([row[8], row[9]])
            e1 = ti.Vector([row[10], row[11]])
            q = e0 if (p - e0).norm_sqr() <= (p - e1).norm_sqr() else e1
        n = -row[4] * (q - c) / row[3]
    return q, n


@ti.func
def profile_sdf(F: ti.template(), b, p):
    """(φ, ∇φ) of the profile at the 2-D point p: the nearest piece, signed by its
    inward normal. Pieces that cannot be the nearest are skipped: each has a point m
    on it and a radius ρ around m holding it (F.model.piece_bound, geometry.piece_bounds);
    the nearest m bounds the distance from above, |p - m| - ρ a piece's from below."""
    n_pieces = F.model.n_pieces[b]
    reach = BIG
    if n_pieces > 1:
        near = BIG
        for k in range(n_pieces):
            m = F.model.piece_bound[b, k]
            near = ti.min(near, (p - ti.Vector([m[0], m[1]])).norm_sqr())
        reach = ti.sqrt(near) + BOUND_SLACK
    best = BIG
    phi = BIG
    grad = ti.Vector([0.0, 0.0])
    for k in range(n_pieces):
        m = F.model.piece_bound[b, k]
        lim = reach + m[2]
        if (p - ti.Vector([m[0], m[1]])).norm_sqr() <= lim * lim:
            q, n = piece_closest(F.model.piece[b, k], p)
            v = p - q
            dist = v.norm()
            if dist < best:
                sign = 1.0 if v.dot(n) >= 0.0 else -1.0
                best = dist
                phi = sign * dist
                grad = n
                if dist > 1e-12:
                    grad = sign * v / dist
    return phi, grad


@ti.func
def side_wall_near(F: ti.template(), b, i, x, reach):
    """(φ, ∇φ) of the side wall at ball i's centre x where φ < reach, else (reach, 0):
    beyond reach only "no contact" matters. φ is 1-Lipschitz, so φ(x) ≥ φ(x₀) - |x - x₀|
    from the last exact value at x₀ (F.state.side_ref) decides that without the profile
    while the ball is far from the wall."""
    ref = F.state.side_ref[b, i]  # x₀, y₀, φ(x₀) - BOUND_SLACK
    dx, dy = x[0] - ref[0], x[1] - ref[1]
    slack = ref[2] - reach
    phi = reach
    grad = ti.Vector([0.0, 0.0, 0.0])
    if not (slack > 0.0 and dx * dx + dy * dy < slack * slack):
        p2, g2 = profile_sdf(F, b, ti.Vector([x[0], x[1]]))
        phi, grad = p2, ti.Vector([g2[0], g2[1], 0.0])
        F.state.side_ref[b, i] = ti.Vector([x[0], x[1], p2 - BOUND_SLACK])
    return phi, grad


@ti.func
def wall_near(F: ti.template(), b, i, wall: ti.template(), x, reach):
    """wall_sdf for ball i where it matters: exact where φ < reach, else (reach, 0)."""
    phi = 0.0
    grad = ti.Vector([0.0, 0.0, 0.0])
    if ti.static(wall == SIDE):
        phi, grad = side_wall_near(F, b, i, x, reach)
    else:
        phi, grad = wall_sdf(F, b, wall, x)
    return phi, grad


@ti.func
def wall_sdf(F: ti.template(), b, wall: ti.template(), x):
    """(φ, ∇φ) of wall SIDE, FLOOR or LID at x; ∇φ points into the jar."""
    phi = 0.0
    grad = ti.Vector([0.0, 0.0, 0.0])
    if ti.static(wall == SIDE):
        p2, g2 = profile_sdf(F, b, ti.Vector([x[0], x[1]]))
        phi, grad = p2, ti.Vector([g2[0], g2[1], 0.0])
    elif ti.static(wall == FLOOR):
        phi, grad = x[2], ti.Vector([0.0, 0.0, 1.0])
    else:
        phi, grad = F.model.height[b] - x[2], ti.Vector([0.0, 0.0, -1.0])
    return phi, grad
