"""The Taichi package, the only one that imports taichi: fields (`state`), the laws and
frame as Taichi functions, walls, the spatial hash and neighbour lists, the contact
loop, the integrator, the kernels (`engine`), loading a mill into the fields (`mill`)
and the launcher (`runner`). `ti.init` runs inside `taichi_start.init_taichi`, never at import."""

import os

# Taichi prints a banner on import and on ti.init; stdout belongs to `--json`.
os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "false")
