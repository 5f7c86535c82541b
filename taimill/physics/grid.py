"""Spatial hash: a uniform grid rebuilt every step by counting sort (count → prefix
sum → fill), as in Taichi's pbf2d example. The cell edge is at least the largest ball
diameter, so every touching pair lies in neighbouring cells. Ids inside a cell are in
ascending order in both builds, which makes the neighbour order, and so the force
summation order, deterministic."""

from taimill.physics.state import SCAN_BLOCK
from taimill.physics.ti import ti


@ti.func
def cell_coords(F: ti.template(), b, x):
    c = ti.cast(ti.floor((x - F.spatial.grid_lo[b]) / F.spatial.grid_h[b]), ti.i32)
    return ti.max(ti.min(c, F.spatial.grid_dim[b] - 1), 0)


@ti.func
def cell_index(F: ti.template(), b, c):
    d = F.spatial.grid_dim[b]
    return (c[2] * d[1] + c[1]) * d[0] + c[0]


@ti.func
def n_cells(F: ti.template(), b):
    d = F.spatial.grid_dim[b]
    return d[0] * d[1] * d[2]


@ti.func
def build_serial(F: ti.template(), b):
    """The whole counting sort for mill b in one thread (batched small mills)."""
    for c in range(n_cells(F, b)):
        F.spatial.cell_count[b, c] = 0
    for i in range(F.model.n_balls[b]):
        c = cell_index(F, b, cell_coords(F, b, F.state.x[b, i]))
        F.spatial.cell_of[b, i] = c
        F.spatial.cell_count[b, c] = F.spatial.cell_count[b, c] + 1  # one thread: no atomic
    running = 0
    for c in range(n_cells(F, b)):
        F.spatial.cell_start[b, c] = running
        running += F.spatial.cell_count[b, c]
        F.spatial.cell_count[b, c] = 0
    for i in range(F.model.n_balls[b]):
        c = F.spatial.cell_of[b, i]
        F.spatial.sorted_ids[b, F.spatial.cell_start[b, c] + F.spatial.cell_count[b, c]] = i
        F.spatial.cell_count[b, c] = F.spatial.cell_count[b, c] + 1


# ---- the same counting sort as parallel kernels, for one large mill (b = 0)
@ti.kernel
def clear_cells(F: ti.template()):
    for c in range(n_cells(F, 0)):
        F.spatial.cell_count[0, c] = 0


@ti.kernel
def count_cells(F: ti.template()):
    for i in range(F.model.n_balls[0]):
        c = cell_index(F, 0, cell_coords(F, 0, F.state.x[0, i]))
        F.spatial.cell_of[0, i] = c
        ti.atomic_add(F.spatial.cell_count[0, c], 1)


# The prefix sum of the cell counts in three levels: cells in blocks of SCAN_BLOCK, blocks
# in groups of SCAN_BLOCK. Each block's and each group's total, then the groups' offsets
# (one thread, over cells / SCAN_BLOCK² groups: a few dozen), then each group's blocks
# and each block's cells from their offsets; every pass but the short one a thread per
# block or group. Integers: the same starts as one running sum, on any number of
# threads or a GPU (where one thread over every cell or block would take milliseconds).
@ti.func
def span(k, n):
    """Items [k SCAN_BLOCK, min((k + 1) SCAN_BLOCK, n)) of block k."""
    return k * SCAN_BLOCK, ti.min((k + 1) * SCAN_BLOCK, n)


@ti.func
def scan(a: ti.template(), lo, hi, start):
    """a[lo:hi] ← its running sum from `start`, each item the sum before it."""
    running = start
    for k in range(lo, hi):
        total = a[k]
        a[k] = running
        running += total


@ti.kernel
def prefix_cells(F: ti.template()):
    cells = n_cells(F, 0)
    blocks = (cells + SCAN_BLOCK - 1) // SCAN_BLOCK
    groups = (blocks + SCAN_BLOCK - 1) // SCAN_BLOCK
    for k in range(blocks):
        lo, hi = span(k, cells)
        total = 0
        for c in range(lo, hi):
            total += F.spatial.cell_count[0, c]
        F.spatial.block_start[k] = total
    for g in range(groups):
        lo, hi = span(g, blocks)
        total = 0
        for k in range(lo, hi):
            total += F.spatial.block_start[k]
        F.spatial.group_start[g] = total
    ti.loop_config(serialize=True)
    for _ in range(1):
        scan(F.spatial.group_start, 0, groups, 0)
    for g in range(groups):
        lo, hi = span(g, blocks)
        scan(F.spatial.block_start, lo, hi, F.spatial.group_start[g])
    for k in range(blocks):
        lo, hi = span(k, cells)
        running = F.spatial.block_start[k]
        for c in range(lo, hi):
            F.spatial.cell_start[0, c] = running
            running += F.spatial.cell_count[0, c]
            F.spatial.cell_count[0, c] = 0


@ti.kernel
def fill_cells(F: ti.template()):
    for i in range(F.model.n_balls[0]):
        c = F.spatial.cell_of[0, i]
        F.spatial.sorted_ids[0, F.spatial.cell_start[0, c] + ti.atomic_add(F.spatial.cell_count[0, c], 1)] = i


@ti.kernel
def sort_cells(F: ti.template()):
    """Insertion sort inside each cell: the parallel fill leaves arbitrary order."""
    for c in range(n_cells(F, 0)):
        lo = F.spatial.cell_start[0, c]
        for a in range(lo + 1, lo + F.spatial.cell_count[0, c]):
            key = F.spatial.sorted_ids[0, a]
            k = a - 1
            while k >= lo and F.spatial.sorted_ids[0, k] > key:
                F.spatial.sorted_ids[0, k + 1] = F.spatial.sorted_ids[0, k]
                k -= 1
            F.spatial.sorted_ids[0, k + 1] = key


def build_parallel(F):
    clear_cells(F)
    count_cells(F)
    prefix_cells(F)
    fill_cells(F)
    sort_cells(F)
