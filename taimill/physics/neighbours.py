"""Verlet neighbour lists with a skin: ball j is on i's list if their surfaces are
closer than `skin`. Lists are rebuilt once any ball has moved more than skin/2 since
the last build, so no pair can come into contact unlisted: the contact set equals the
all-pairs one exactly. Candidates come from the spatial hash (grid.py) or, for a dozen
balls where it is cheaper, from all pairs.
"""

from taimill.physics import grid, reorder, state as S
from taimill.physics.grid import cell_coords, cell_index
from taimill.physics.ti import ti


@ti.func
def list_candidate(F: ti.template(), b, i, j):
    """Append j to i's list if within the skin; flags a full list."""
    d = F.state.x[b, j] - F.state.x[b, i]
    reach = F.model.r[b, i] + F.model.r[b, j] + F.spatial.skin[b]
    if d.norm_sqr() < reach * reach:
        q = F.spatial.nbr_count[b, i]
        if q < S.NEIGHBOURS:
            F.spatial.nbr[b, i, q] = j
            F.spatial.nbr_count[b, i] = q + 1
        else:
            F.state.status[b] = S.LIST_FULL
            F.state.bad_ball[b] = S.user_id(F, b, i)


@ti.func
def build_list(F: ti.template(), b, i, use_grid: ti.template()):
    """Neighbour list of ball i, in ascending own index of j (deterministic summation
    order, the same whatever order the rows are in)."""
    F.spatial.nbr_count[b, i] = 0
    F.spatial.x_ref[b, i] = F.state.x[b, i]
    if ti.static(use_grid):
        c0 = cell_coords(F, b, F.state.x[b, i])
        for dz, dy, dx in ti.ndrange((-1, 2), (-1, 2), (-1, 2)):
            c = c0 + ti.Vector([dx, dy, dz])
            if (c >= 0).all() and (c < F.spatial.grid_dim[b]).all():
                ci = cell_index(F, b, c)
                start = F.spatial.cell_start[b, ci]
                for q in range(start, start + F.spatial.cell_count[b, ci]):
                    j = F.spatial.sorted_ids[b, q]
                    if j != i:
                        list_candidate(F, b, i, j)
        sort_list(F, b, i)
    else:
        for j in range(F.model.n_balls[b]):
            if j != i:
                list_candidate(F, b, i, j)


@ti.func
def sort_list(F: ti.template(), b, i):
    """Insertion sort by own index (state.user_id): cells are visited in grid order."""
    n = F.spatial.nbr_count[b, i]
    for a in range(1, n):
        key = F.spatial.nbr[b, i, a]
        rank = S.user_id(F, b, key)
        k = a - 1
        while k >= 0:  # (Taichi's `and` evaluates both sides: no read at k = -1)
            if S.user_id(F, b, F.spatial.nbr[b, i, k]) <= rank:
                break
            F.spatial.nbr[b, i, k + 1] = F.spatial.nbr[b, i, k]
            k -= 1
        F.spatial.nbr[b, i, k + 1] = key


@ti.func
def moved_too_far(F: ti.template(), b, i):
    half = 0.5 * F.spatial.skin[b]
    return (F.state.x[b, i] - F.spatial.x_ref[b, i]).norm_sqr() > half * half


@ti.func
def rebuild_serial(F: ti.template(), b, use_grid: ti.template()):
    """All lists of mill b in one thread (fused mode)."""
    if ti.static(use_grid):
        grid.build_serial(F, b)
    for i in range(F.model.n_balls[b]):
        build_list(F, b, i, use_grid)
    F.spatial.rebuild[b] = 0


@ti.kernel
def build_lists_parallel(F: ti.template()):
    for i in range(F.model.n_balls[0]):
        build_list(F, 0, i, True)
    F.spatial.rebuild[0] = 0


def rebuild_parallel(F):
    """The grid, the ball rows put in its order (reorder.py, if F.reorder), the lists."""
    grid.build_parallel(F)
    if F.reorder:
        reorder.permute(F)
    build_lists_parallel(F)
