"""All shear arrows of a heatmap as ONE graphics item, redrawn without new scene items.

Each vector is drawn as a dot at the taxel centre, a line to the tip and a small filled
head — a glyph that cannot be taken for the mouse pointer (a pointer has no dot at its
tail and a large head on a short stem). Vectors too short to carry a head are drawn as
dot and line only: the dot marks the tail, so the direction still reads. The geometry is
kept in preallocated arrays (pyqtgraph's ``PrimitiveArray``), so a frame costs a few
numpy operations and five draw calls whatever the number of arrows.
"""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from pyqtgraph.Qt.internals import PrimitiveArray
from PySide6.QtCore import QLineF, QRectF, Qt
from PySide6.QtGui import QBrush, QColor, QPainter, QPainterPath, QPen

HALO = QColor("#101010")
INK = QColor("#ffffff")


def arrow_geometry(cx: np.ndarray, cy: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                   head: float, min_head: float, max_head: float,
                   half_angle_deg: float = 24.0) -> dict[str, np.ndarray]:
    """Shaft segments, head triangles and tail dots for arrows from (cx, cy) by (dx, dy).

    Heads are ``head`` x the arrow length, clipped to ``max_head``; an arrow whose head
    would be shorter than ``min_head`` gets none (``has_head`` False) and its shaft runs
    to the tip. Returns ``shaft`` (n, 4) x0 y0 x1 y1, ``heads`` (m, 3, 2) tip-left-right
    and ``dots`` (n, 2).
    """
    length = np.hypot(dx, dy)
    safe = np.where(length > 0, length, 1.0)
    ux, uy = dx / safe, dy / safe
    h = np.minimum(head * length, max_head)
    has_head = h >= min_head
    tx, ty = cx + dx, cy + dy
    hh = np.where(has_head, h, 0.0)
    bx, by = tx - hh * ux, ty - hh * uy          # the head's base centre: the shaft ends here
    shaft = np.stack([cx, cy, bx, by], axis=1)
    w = math.tan(math.radians(half_angle_deg)) * h
    k = has_head
    heads = np.empty((int(k.sum()), 3, 2))
    heads[:, 0, 0], heads[:, 0, 1] = tx[k], ty[k]
    heads[:, 1, 0], heads[:, 1, 1] = bx[k] - w[k] * uy[k], by[k] + w[k] * ux[k]
    heads[:, 2, 0], heads[:, 2, 1] = bx[k] + w[k] * uy[k], by[k] - w[k] * ux[k]
    return {"shaft": shaft, "heads": heads, "dots": np.stack([cx, cy], axis=1)}


class ArrowField(pg.GraphicsObject):
    """One item drawing every arrow; ``set_arrows`` replaces the field in place."""

    def __init__(self) -> None:
        super().__init__()
        self._lines = PrimitiveArray(QLineF, 4)
        # dots are very short lines with round caps (drawPoints has no array overload)
        self._dots = PrimitiveArray(QLineF, 4)
        self._heads = QPainterPath()
        self._n = 0
        self._rect = QRectF()
        self._halo_line = self._pen(HALO, 4.5)
        self._ink_line = self._pen(INK, 2.0)
        self._halo_dot = self._pen(HALO, 8.0)
        self._ink_dot = self._pen(INK, 4.5)
        self._head_pen = self._pen(HALO, 1.5)
        self._head_pen.setJoinStyle(Qt.PenJoinStyle.MiterJoin)
        self._head_brush = QBrush(INK)
        self.geometry: dict[str, np.ndarray] = arrow_geometry(*(np.empty(0),) * 4, 0.3, 0, 0)

    @staticmethod
    def _pen(color: QColor, width: float) -> QPen:
        pen = QPen(color)
        pen.setWidthF(width)
        pen.setCosmetic(True)  # widths in screen pixels, whatever the zoom
        pen.setCapStyle(Qt.PenCapStyle.RoundCap)
        return pen

    def count(self) -> int:
        """Arrows currently drawn."""
        return self._n

    def set_arrows(self, cx: np.ndarray, cy: np.ndarray, dx: np.ndarray, dy: np.ndarray,
                   head: float = 0.35, min_head: float = 0.08, max_head: float = 0.3) -> None:
        """Draw arrows from (cx, cy) by (dx, dy), in data units (flat arrays)."""
        g = arrow_geometry(np.asarray(cx, float), np.asarray(cy, float),
                           np.asarray(dx, float), np.asarray(dy, float),
                           head, min_head, max_head)
        self.geometry = g
        n = len(g["dots"])
        self._n = n
        self._lines.resize(n)
        self._lines.ndarray()[:] = g["shaft"]
        self._dots.resize(n)
        dots = self._dots.ndarray()
        dots[:, :2] = g["dots"]
        dots[:, 2:] = g["dots"]
        dots[:, 2] += 1e-3  # a zero-length line draws nothing; a tiny one draws its caps
        heads = g["heads"]
        if len(heads):
            pts = np.concatenate([heads, heads[:, :1]], axis=1).reshape(-1, 2)
            connect = np.ones(len(pts), dtype=bool)
            connect[3::4] = False  # close each triangle, then start the next
            self._heads = pg.arrayToQPath(pts[:, 0], pts[:, 1], connect=connect)
        else:
            self._heads = QPainterPath()
        self._grow_rect(g)
        self.update()

    def clear(self) -> None:
        """Draw no arrows (keeps the item)."""
        if self._n:
            self.set_arrows(*(np.empty(0),) * 4)

    def _grow_rect(self, g: dict[str, np.ndarray]) -> None:
        """Bounds that only grow, in half cells (so the scene does not re-index the item
        every frame)."""
        if not self._n:
            return
        xs = np.concatenate([g["shaft"][:, 0], g["shaft"][:, 2], g["heads"][:, :, 0].ravel()])
        ys = np.concatenate([g["shaft"][:, 1], g["shaft"][:, 3], g["heads"][:, :, 1].ravel()])
        # half-cell steps with a quarter-cell margin for the pens: arrows inside the grid
        # stay inside the image, so the row and column labels are not repainted
        x0, x1 = math.floor(2 * xs.min() - 0.5) / 2, math.ceil(2 * xs.max() + 0.5) / 2
        y0, y1 = math.floor(2 * ys.min() - 0.5) / 2, math.ceil(2 * ys.max() + 0.5) / 2
        r = self._rect
        if r.isNull() or x0 < r.left() or y0 < r.top() or x1 > r.right() or y1 > r.bottom():
            self.prepareGeometryChange()
            self._rect = QRectF(x0, y0, x1 - x0, y1 - y0).united(r) if not r.isNull() \
                else QRectF(x0, y0, x1 - x0, y1 - y0)

    def boundingRect(self) -> QRectF:  # noqa: N802 - Qt name
        return self._rect

    def paint(self, p: QPainter, *args: object) -> None:
        if not self._n:
            return
        p.setRenderHint(QPainter.RenderHint.Antialiasing, True)
        lines, dots = self._lines.drawargs(), self._dots.drawargs()
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.setPen(self._halo_line)
        p.drawLines(*lines)
        p.setPen(self._halo_dot)
        p.drawLines(*dots)
        p.setPen(self._ink_line)
        p.drawLines(*lines)
        p.setPen(self._head_pen)
        p.setBrush(self._head_brush)
        p.drawPath(self._heads)
        p.setPen(self._ink_dot)
        p.drawLines(*dots)


__all__ = ["ArrowField", "arrow_geometry"]
