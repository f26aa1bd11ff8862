"""A small colour-mapped grid image that is cheap to repaint at display rate.

pyqtgraph's ImageItem builds an indexed QImage with a new colour table for every frame,
and Qt scales an indexed image to the screen on a slow generic path (about 1.5 ms for a
6x6 map filling the view on this machine). Here values are mapped through a 256-entry
RGB32 table with numpy into a preallocated buffer, and Qt scales an RGB32 image on its
fast path. No Qt object is created per frame.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QRectF, Qt
from PySide6.QtGui import QColor, QImage, QPainter, QPen


def rgb32_table(cmap: pg.ColorMap, n: int = 256) -> np.ndarray:
    """(n,) uint32 0xffRRGGBB colours of a colour map, low to high."""
    rgb = cmap.getLookupTable(0.0, 1.0, n, alpha=False).astype(np.uint32)
    return (0xFF000000 | (rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]).astype(np.uint32)


class GridImage(pg.GraphicsObject):
    """Values (rows x cols, row 0 at the top) drawn as cells of a rectangle."""

    def __init__(self, cmap: pg.ColorMap) -> None:
        super().__init__()
        self._table = rgb32_table(cmap)
        self._levels = (0.0, 1.0)
        self._data: np.ndarray | None = None
        self._buf = np.zeros((0, 0), dtype=np.uint32)
        self._qimage: QImage | None = None
        self._rect = QRectF()
        self._scratch = np.zeros((0, 0), dtype=np.float32)

    # ---- what to show --------------------------------------------------------------
    def set_colormap(self, cmap: pg.ColorMap) -> None:
        self._table = rgb32_table(cmap)
        self._remap()

    def set_levels(self, lo: float, hi: float) -> None:
        """Values at or below ``lo`` get the first colour, at or above ``hi`` the last."""
        self._levels = (float(lo), float(hi))
        self._remap()

    def levels(self) -> tuple[float, float]:
        return self._levels

    def set_rect(self, rect: QRectF) -> None:
        """Where the whole grid is drawn, in data units."""
        self.prepareGeometryChange()
        self._rect = QRectF(rect)
        self.update()

    def set_data(self, values: np.ndarray) -> None:
        """Show ``values`` (rows x cols); the image buffer is reused while the shape holds."""
        values = np.asarray(values, dtype=np.float32)
        if values.shape != self._buf.shape:
            self._buf = np.zeros(values.shape, dtype=np.uint32)
            self._scratch = np.zeros(values.shape, dtype=np.float32)
            rows, cols = values.shape
            self._qimage = QImage(self._buf.data, cols, rows, cols * 4,
                                  QImage.Format.Format_RGB32)
        self._data = values
        self._remap()

    def clear(self) -> None:
        self._data = None
        self.update()

    def data(self) -> np.ndarray | None:
        return self._data

    def colors(self) -> np.ndarray:
        """(rows, cols) uint32 0xffRRGGBB of what is drawn (for tests and readouts)."""
        return self._buf.copy()

    def _remap(self) -> None:
        if self._data is None:
            return
        lo, hi = self._levels
        n = len(self._table)
        scale = (n - 1) / (hi - lo) if hi > lo else 0.0
        s = self._scratch
        np.subtract(self._data, lo, out=s)
        np.multiply(s, scale, out=s)
        np.fmax(s, 0.0, out=s)  # fmax, not clip: NaN becomes 0 too
        np.fmin(s, n - 1, out=s)
        np.take(self._table, s.astype(np.intp), out=self._buf)
        self.update()

    # ---- QGraphicsItem -------------------------------------------------------------
    def boundingRect(self) -> QRectF:  # noqa: N802 - Qt name
        return self._rect

    def paint(self, p: QPainter, *args: object) -> None:
        if self._data is None or self._qimage is None:
            return
        p.drawImage(self._rect, self._qimage)




class CellMarks(pg.GraphicsObject):
    """Coloured square outlines around cells (the strip chart's taxels), one cheap item.

    Drawn on every repaint of the map, so it is a handful of ``drawRect`` calls rather
    than a scatter plot item; it changes only when the marked cells do.
    """

    def __init__(self) -> None:
        super().__init__()
        self._marks: list[tuple[QPen, QRectF]] = []
        self._rect = QRectF()

    def set_marks(self, rects: list[QRectF], colors: list[str], width: float = 3.0) -> None:
        self.prepareGeometryChange()
        self._marks = []
        for rect, color in zip(rects, colors):
            pen = QPen(QColor(color))
            pen.setWidthF(width)
            pen.setCosmetic(True)
            self._marks.append((pen, QRectF(rect)))
        bounds = QRectF()
        for _, rect in self._marks:
            bounds = bounds.united(rect)
        self._rect = bounds.adjusted(-0.1, -0.1, 0.1, 0.1) if self._marks else QRectF()
        self.update()

    def count(self) -> int:
        return len(self._marks)

    def boundingRect(self) -> QRectF:  # noqa: N802 - Qt name
        return self._rect

    def paint(self, p: QPainter, *args: object) -> None:
        p.setBrush(Qt.BrushStyle.NoBrush)
        for pen, rect in self._marks:
            p.setPen(pen)
            p.drawRect(rect)


__all__ = ["CellMarks", "GridImage", "rgb32_table"]
