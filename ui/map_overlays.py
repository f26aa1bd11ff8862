"""Light items drawn over the heatmap: taxel labels beside the grid and the hover box.

pyqtgraph's TextItem re-maps itself on every repaint of the scene (a Python slot per label
per paint) and a PlotDataItem is a curve plus a scatter item; at display rate those cost
more than the map itself. Each item here is one object that only paints: labels are
drawn upright at a fixed pixel size, the box is two rectangle outlines.
"""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QFont, QPainter, QPen
from PySide6.QtWidgets import QGraphicsItem

_ALIGN = {  # anchor (x, y) of the text box at the label's point -> Qt alignment
    (1.0, 0.5): Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter,
    (0.5, 1.0): Qt.AlignmentFlag.AlignHCenter | Qt.AlignmentFlag.AlignBottom,
    (0.5, 0.5): Qt.AlignmentFlag.AlignCenter,
}
_BOX = 200.0  # pixels: room for the text around its anchor point


class AxisLabels(pg.GraphicsObject):
    """Texts at points in data units (e.g. row letters left of the map), one item.

    ``area`` is where the labels live in data units (a margin strip beside the map): it is
    the item's bounds, so repainting the map does not repaint the labels.
    """

    def __init__(self, color: str, font: QFont) -> None:
        super().__init__()
        self._labels: list[tuple[str, QPointF, Qt.AlignmentFlag]] = []
        self._rect = QRectF()
        self._pen = QPen(QColor(color))
        self._font = QFont(font)
        # arrows at the grid's edge reach into the margins, so the labels are repainted
        # with the map: from a cached pixmap, not by laying out their text again
        self.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)

    def set_labels(self, labels: list[tuple[str, float, float]],
                   anchor: tuple[float, float], area: QRectF) -> None:
        """``labels``: (text, x, y); ``anchor`` (1, 0.5) puts the text left of its point,
        (0.5, 1) above it."""
        self.prepareGeometryChange()
        align = _ALIGN[anchor]
        self._labels = [(text, QPointF(x, y), align) for text, x, y in labels]
        self._rect = QRectF(area)
        self.update()

    def texts(self) -> list[str]:
        return [text for text, _, _ in self._labels]

    def boundingRect(self) -> QRectF:  # noqa: N802 - Qt name
        return self._rect

    def paint(self, p: QPainter, *args: object) -> None:
        if not self._labels:
            return
        to_device = p.transform()
        p.save()
        p.resetTransform()  # upright, fixed-size text whatever the view's scale
        p.setFont(self._font)
        p.setPen(self._pen)
        for text, point, align in self._labels:
            at = to_device.map(point)
            if align & Qt.AlignmentFlag.AlignRight:
                box = QRectF(at.x() - _BOX, at.y() - _BOX / 2, _BOX, _BOX)
            else:
                box = QRectF(at.x() - _BOX / 2, at.y() - _BOX, _BOX, _BOX)
            p.drawText(box, int(align), text)
        p.restore()


class HoverBox(pg.GraphicsObject):
    """The hovered cell's outline: white dashes over a dark line, so it shows on white
    (0 in the diverging map) and on dark cells alike."""

    def __init__(self) -> None:
        super().__init__()
        self._cell = QRectF()
        self._halo = pg.mkPen("#202020", width=2)
        self._dashes = pg.mkPen("#ffffff", width=2, style=Qt.PenStyle.DashLine)
        self.setVisible(False)

    def set_cell(self, rect: QRectF | None) -> None:
        """Outline ``rect`` (data units), or hide with None."""
        if rect is None:
            self.setVisible(False)
            return
        if rect != self._cell:
            self.prepareGeometryChange()
            self._cell = QRectF(rect)
        self.setVisible(True)
        self.update()

    def cell_rect(self) -> QRectF | None:
        """The outlined rectangle, or None when hidden."""
        return QRectF(self._cell) if self.isVisible() else None

    def boundingRect(self) -> QRectF:  # noqa: N802 - Qt name
        pad = 0.05 * max(self._cell.width(), 1e-9)
        return self._cell.adjusted(-pad, -pad, pad, pad)

    def paint(self, p: QPainter, *args: object) -> None:
        p.setBrush(Qt.BrushStyle.NoBrush)
        for pen in (self._halo, self._dashes):
            p.setPen(pen)
            p.drawRect(self._cell)


__all__ = ["AxisLabels", "HoverBox"]
