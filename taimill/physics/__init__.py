"""The physics package: the only one that imports taichi (STYLE rule 7)."""

import os

# Taichi prints a banner on import and on ti.init; stdout belongs to `--json`.
os.environ.setdefault("ENABLE_TAICHI_HEADER_PRINT", "false")
