"""Every matplotlib figure of taimill: run reports (`report`), sweep curves (`sweep`),
jar drawings (`jars`) and calibration plots (`calibration`). Figures read NumPy data
from the analysis and the stores; nothing below this package imports matplotlib."""

import os

FIGURE_MAGIC = (b"\x89PNG\r\n\x1a\n", b"<?xml", b"<svg", b"%PDF")
MARK_BYTES = 1 << 16  #: matplotlib names itself near the start of a PNG or SVG, near the end of a PDF


def is_figure(path) -> bool:
    """True if `path` is a figure taimill (matplotlib) drew: a PNG, SVG or PDF that
    names matplotlib as its maker. Only such a file is replaced by --overwrite: a
    user's own picture at the same name is not (taimill.model.files.check_replaceable)."""
    try:
        with open(path, "rb") as f:
            head = f.read(MARK_BYTES)
            f.seek(max(0, os.fstat(f.fileno()).st_size - MARK_BYTES))
            tail = f.read(MARK_BYTES)
    except OSError:
        return False
    return head.startswith(FIGURE_MAGIC) and (b"matplotlib" in head.lower() or b"matplotlib" in tail.lower())
