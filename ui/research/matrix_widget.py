"""A painted class x class matrix with labels, per-row margin columns, hover and click.

Used for the confusion matrix (sequential colours) and the difference between two runs
(diverging colours). It paints to any QPaintDevice, so PNG and SVG exports are the same
picture as the screen.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QPoint, QRect, QRectF, QSize, Qt, Signal
from PySide6.QtGui import QColor, QFont, QFontMetrics, QMouseEvent, QPainter, QPaintEvent
from PySide6.QtWidgets import QSizePolicy, QToolTip, QWidget

PAD = 6


def _seq(v: float) -> QColor:
    """White -> deep blue for 0..1."""
    v = float(min(max(v, 0.0), 1.0))
    return QColor(int(255 - 222 * v), int(255 - 160 * v), int(255 - 75 * v))


def _div(v: float) -> QColor:
    """Red (negative) - white - green (positive) for -1..1."""
    v = float(min(max(v, -1.0), 1.0))
    if v >= 0:
        return QColor(int(255 - 200 * v), int(255 - 90 * v), int(255 - 200 * v))
    v = -v
    return QColor(int(255 - 40 * v), int(255 - 200 * v), int(255 - 200 * v))


class MatrixWidget(QWidget):
    cellClicked = Signal(int, int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setMouseTracking(True)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.labels: list[str] = []
        self.values = np.zeros((0, 0))
        self.texts: list[list[str]] = []
        self.margins: dict[str, list[str]] = {}
        self.diverging = False
        self.scale = 1.0
        self.title = ""
        self.x_title, self.y_title = "predicted", "true"
        self.tooltip: Callable[[int, int], str] | None = None
        self.selected: tuple[int, int] | None = None

    def set_matrix(self, labels: list[str], values: np.ndarray, texts: list[list[str]],
                   margins: dict[str, list[str]] | None = None, diverging: bool = False,
                   scale: float = 1.0, title: str = "") -> None:
        """``values`` drive the colours (0..scale, or -scale..scale when diverging)."""
        self.labels, self.values, self.texts = list(labels), np.asarray(values, float), texts
        self.margins, self.diverging = dict(margins or {}), diverging
        self.scale, self.title = max(scale, 1e-12), title
        if self.selected and max(self.selected) >= len(self.labels):
            self.selected = None
        self.updateGeometry()
        self.update()

    # --- geometry ----------------------------------------------------------------------
    def _fonts(self) -> tuple[QFont, QFont]:
        label = QFont(self.font())
        label.setPointSize(9)
        cell = QFont(label)
        cell.setPointSize(8 if len(self.labels) > 10 else 9)
        return label, cell

    def _layout(self, width: int, height: int) -> tuple[int, int, int, int]:
        """(left, top, cell size, margin column width)."""
        label_font, cell_font = self._fonts()
        fm = QFontMetrics(label_font)
        text_w = max([fm.horizontalAdvance(s) for s in self.labels] + [20])
        left = text_w + 2 * PAD + fm.height()
        top = text_w + 2 * PAD + (fm.height() + PAD if self.title else 0)
        margin_w = QFontMetrics(cell_font).horizontalAdvance("0.000") + 2 * PAD
        n = max(len(self.labels), 1)
        avail_w = width - left - PAD - margin_w * len(self.margins)
        avail_h = height - top - PAD - fm.height()
        min_cell = QFontMetrics(cell_font).horizontalAdvance("100%") + 3
        cell = max(min(avail_w // n, avail_h // n, 70), min_cell)
        return left, top, cell, margin_w

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt name
        n = max(len(self.labels), 3)
        return QSize(240 + 46 * n + 60 * len(self.margins), 220 + 46 * n)

    def minimumSizeHint(self) -> QSize:  # noqa: N802 - Qt name
        left, top, cell, mw = self._layout(0, 0)
        n = max(len(self.labels), 1)
        return QSize(left + n * cell + mw * len(self.margins) + PAD, top + n * cell + 30)

    def cell_at(self, pos: QPoint) -> tuple[int, int] | None:
        left, top, cell, _ = self._layout(self.width(), self.height())
        col, row = (pos.x() - left) // cell, (pos.y() - top) // cell
        n = len(self.labels)
        if pos.x() >= left and pos.y() >= top and 0 <= row < n and 0 <= col < n:
            return int(row), int(col)
        return None

    def cell_center(self, row: int, col: int) -> QPoint:
        left, top, cell, _ = self._layout(self.width(), self.height())
        return QPoint(left + col * cell + cell // 2, top + row * cell + cell // 2)

    # --- events ------------------------------------------------------------------------
    def mouseMoveEvent(self, event: QMouseEvent) -> None:  # noqa: N802 - Qt name
        hit = self.cell_at(event.position().toPoint())
        if hit is not None and self.tooltip is not None:
            QToolTip.showText(event.globalPosition().toPoint(), self.tooltip(*hit), self)
        else:
            QToolTip.hideText()

    def mousePressEvent(self, event: QMouseEvent) -> None:  # noqa: N802 - Qt name
        hit = self.cell_at(event.position().toPoint())
        if hit is not None:
            self.selected = hit
            self.update()
            self.cellClicked.emit(*hit)

    def paintEvent(self, event: QPaintEvent) -> None:  # noqa: N802 - Qt name
        p = QPainter(self)
        p.fillRect(self.rect(), QColor("white"))
        self.paint(p, self.width(), self.height())
        p.end()

    # --- painting ----------------------------------------------------------------------
    def paint(self, p: QPainter, width: int, height: int) -> None:
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        label_font, cell_font = self._fonts()
        fm = QFontMetrics(label_font)
        left, top, cell, mw = self._layout(width, height)
        n = len(self.labels)
        p.setPen(QColor("black"))
        if self.title:
            p.setFont(label_font)
            p.drawText(QRect(PAD, PAD, width - 2 * PAD, fm.height()),
                       Qt.AlignmentFlag.AlignLeft, self.title)
        for i in range(n):
            for j in range(n):
                v = self.values[i, j] / self.scale
                colour = _div(v) if self.diverging else _seq(v)
                r = QRect(left + j * cell, top + i * cell, cell, cell)
                p.fillRect(r, colour)
                p.setPen(QColor(220, 220, 220))
                p.drawRect(r)
                dark = (not self.diverging and v > 0.55) or (self.diverging and abs(v) > 0.7)
                p.setPen(QColor("white") if dark else QColor("black"))
                p.setFont(cell_font)
                p.drawText(r, Qt.AlignmentFlag.AlignCenter, self.texts[i][j])
        if self.selected is not None:
            i, j = self.selected
            p.setPen(QColor(230, 120, 0))
            p.drawRect(QRect(left + j * cell + 1, top + i * cell + 1, cell - 2, cell - 2))
        p.setPen(QColor("black"))
        p.setFont(label_font)
        for i, name in enumerate(self.labels):
            p.drawText(QRect(PAD + fm.height(), top + i * cell, left - 2 * PAD - fm.height(), cell),
                       Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter, name)
            p.save()
            p.translate(left + j_center(i, cell), top - PAD)
            p.rotate(-90)
            p.drawText(QRectF(0, -fm.height() / 2, top, fm.height()),
                       Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, name)
            p.restore()
        # axis titles
        p.save()
        p.translate(PAD, top + n * cell / 2)
        p.rotate(-90)
        p.drawText(QRectF(-60, 0, 120, fm.height()), Qt.AlignmentFlag.AlignCenter, self.y_title)
        p.restore()
        p.drawText(QRect(left, top + n * cell + 2, n * cell, fm.height() + 4),
                   Qt.AlignmentFlag.AlignCenter, self.x_title)
        x0 = left + n * cell + PAD
        p.setFont(cell_font)
        for k, (name, col) in enumerate(self.margins.items()):
            x = x0 + k * mw
            p.setFont(label_font)
            p.drawText(QRect(x, top - fm.height() - PAD, mw, fm.height()),
                       Qt.AlignmentFlag.AlignCenter, name)
            p.setFont(cell_font)
            for i, txt in enumerate(col):
                p.drawText(QRect(x, top + i * cell, mw, cell), Qt.AlignmentFlag.AlignCenter, txt)


def j_center(j: int, cell: int) -> float:
    return j * cell + cell / 2
