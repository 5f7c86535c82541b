"""The jar drawn in braille: from above (x-y, the real profile outline, with a mark in
the direction ψ away from the plate axis, where the plate's centrifugal pull points)
or in section (x-z, between the profile's extreme x, floor and lid). Jar frame, balls
as discs of their true radius.

Drawn line by line (`render_line` from strips built once per frame): 20 frames a second
must cost the UI thread little, since it shares the GIL with the simulation."""

from __future__ import annotations

import numpy as np
from rich.segment import Segment
from rich.style import Style
from textual.strip import Strip
from textual.widget import Widget

from taimill.tui.braille import Plane, cells, to_text

COLOURS = (None, "grey70", "yellow", "red")  # empty, wall, ball, mark (topmost wins)
MAX_DRAWN = 20_000  # balls drawn per view at most (a stride sample beyond)


class JarView(Widget):
    """view: "top" or "section". `set_jar` once per jar, `show` per frame."""

    DEFAULT_CSS = """
    JarView { height: 1fr; width: 1fr; }
    """

    def __init__(self, view: str, **kw):
        super().__init__(**kw)
        self.view = view
        self.outline = None
        self.height_m = 0.0
        self.position = np.zeros((0, 3))
        self.sample = 1  #: every sample-th ball is drawn
        self.radius = np.zeros(0)
        self.psi = None
        self.drawn = 0  #: frames drawn (the app's frame-rate meter)
        self._static: tuple | None = None  # (size, plane, wall mask)
        self._strips: list[Strip] | None = None
        self._styles: list[Style] | None = None  # per layer, on the widget's background

    def set_jar(self, outline: np.ndarray, height: float, radius: np.ndarray):
        """outline: (M, 2) closed profile, m; height: m; radius: (N,) ball radii, m."""
        self.outline, self.height_m, self.radius = np.asarray(outline), height, np.asarray(radius)
        self.reach = float(np.hypot(*self.outline.T).max())  #: m, bounding radius
        self.position = np.zeros((0, 3))
        self._static = None
        self._strips = None
        self.refresh()

    def show(self, position: np.ndarray, psi: float | None = None):
        """Draw the balls at `position` (N, 3), m; beyond MAX_DRAWN balls a fixed sample
        (every k-th ball, the same ones every frame) keeps the view responsive."""
        step = -(-len(position) // MAX_DRAWN)
        self.position, self.psi = position[::step] if step > 1 else position, psi
        self.sample = max(step, 1)
        self._strips = None
        self.refresh()

    def on_resize(self):
        self._strips = None
        self._styles = None

    def _geometry(self, cols: int, rows: int):
        """Plane and wall dots for this size (cached: the outline has ~10⁴ points)."""
        if self._static is None or self._static[0] != (cols, rows):
            x = self.outline[:, 0]
            pad = 0.04 * np.ptp(x)
            if self.view == "top":
                R = self.reach + pad
                plane = Plane(cols, rows, (-R, R), (-R, R))
                walls = [self.outline]
            else:
                x0, x1, h = float(x.min()), float(x.max()), self.height_m
                plane = Plane(cols, rows, (x0 - pad, x1 + pad), (-pad, h + pad))
                walls = [np.array([[x0, h], [x0, 0.0], [x1, 0.0], [x1, h], [x0, h]])]
            mask = plane.blank()
            for w in walls:
                plane.polyline(mask, w)
            self._static = ((cols, rows), plane, cells(mask))
        return self._static[1], self._static[2]

    def _layers(self, cols: int, rows: int):
        plane, wall = self._geometry(cols, rows)
        balls, mark = plane.blank(), plane.blank()
        axes = (0, 1) if self.view == "top" else (0, 2)
        if len(self.position):
            plane.discs(balls, self.position[:, axes], self.radius[:: self.sample][: len(self.position)])
        if self.view == "top" and self.psi is not None:
            plane.plot(mark, np.outer(np.linspace(1.0, 1.06, 6), [np.cos(self.psi), np.sin(self.psi)]) * self.reach)
        return wall, cells(balls), cells(mark)

    def _build(self, cols: int, rows: int) -> list[Strip]:
        if self._styles is None:  # computing rich_style walks the DOM: once per size
            base = self.rich_style
            self._styles = [base] + [base + Style(color=c, bold=True) for c in COLOURS[1:]]
        styles = self._styles
        if self.outline is None or cols < 4 or rows < 2:
            return [Strip.blank(cols, styles[0])] * rows
        wall, balls, mark = self._layers(cols, rows)
        layer = np.where(mark > 0, 3, np.where(balls > 0, 2, np.where(wall > 0, 1, 0)))
        text = to_text(wall | balls | mark)
        # runs of one colour: (row, first column) where the layer changes, one pass
        starts = np.ones(layer.shape, dtype=bool)
        starts[:, 1:] = layer[:, 1:] != layer[:, :-1]
        run_row, run_col = np.nonzero(starts)
        segments = [[] for _ in range(layer.shape[0])]
        ends = np.append(run_col[1:], 0)
        ends[np.append(run_row[1:] != run_row[:-1], True)] = layer.shape[1]
        for r, a, b in zip(run_row.tolist(), run_col.tolist(), ends.tolist()):
            segments[r].append(Segment(text[r][a:b], styles[layer[r, a]]))
        self.drawn += 1
        return [Strip(segs, cols) for segs in segments]

    def render_line(self, y: int) -> Strip:
        cols, rows = self.size.width, self.size.height
        if self._strips is None or len(self._strips) != rows:
            self._strips = self._build(cols, rows)
        return self._strips[y] if y < len(self._strips) else Strip.blank(cols)
