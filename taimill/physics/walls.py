"""Jar walls as signed distance functions (positive inside) with their gradients.

A jar is a 2-D profile extruded between the floor (z = 0) and the lid (z = height).
Each ball can touch three walls at once — side, floor, lid — each its own contact with
its own event slot, so a ball resting in the floor/side corner feels both.

The profile is the intersection of primitives read from the jar file (geometry is
data, STYLE rule 5). Primitive codes and parameters (m) in `prim_par`:
    0 circle: (R, 0, 0, 0) — interior ρ < R.
New primitives plug in here and in walls_np.py (the NumPy twin).
"""

import taichi as ti

SIDE, FLOOR, LID = 0, 1, 2
CIRCLE = 0
BIG = 1e9


@ti.func
def primitive_sdf(kind: ti.i32, par, p):
    """(φ, ∇φ) of one primitive at the 2-D point p."""
    phi = BIG
    grad = ti.Vector([0.0, 0.0])
    if kind == CIRCLE:
        rho = p.norm()
        phi = par[0] - rho
        if rho > 0.0:
            grad = -p / rho
    return phi, grad


@ti.func
def profile_sdf(F: ti.template(), b, p):
    """Intersection of the primitives: the smallest φ and its gradient."""
    phi = BIG
    grad = ti.Vector([0.0, 0.0])
    for k in range(F.n_prims[b]):
        pk, gk = primitive_sdf(F.prim_type[b, k], F.prim_par[b, k], p)
        if pk < phi:
            phi, grad = pk, gk
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
        phi, grad = F.height[b] - x[2], ti.Vector([0.0, 0.0, -1.0])
    return phi, grad
