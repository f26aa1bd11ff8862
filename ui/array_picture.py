"""A picture of the taxel array: where to put the weight, where it is, how each spot did."""

from __future__ import annotations

from PySide6.QtCore import QRectF, QSize, Qt
from PySide6.QtGui import QColor, QFont, QPainter, QPen
from PySide6.QtWidgets import QWidget

from tactile_studio.sensor.layout import SHEARSENSE_6X6, Layout

VERDICT_COLOURS = {"pass": "#2e8b57", "warn": "#d89a00", "fail": "#c0392b",
                   "measured": "#7a8699"}
# readable on white, distinct for up to 10 series (spots, taxels)
SERIES_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
                  "#e377c2", "#17becf", "#7f7f7f", "#bcbd22")
TARGET, DETECTED, IDLE_CELL = "#2f6fdb", "#f08c00", "#d9dde3"


class ArrayPicture(QWidget):
    """Draws rows x cols taxels with names; cells can be marked target, detected or by
    verdict. Pure presentation: callers say what to mark."""

    def __init__(self, layout: Layout = SHEARSENSE_6X6, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.array_layout = layout
        self.target: str | None = None
        self.detected: str | None = None
        self.verdicts: dict[str, str] = {}
        self.setMinimumSize(220, 220)

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt name
        return QSize(260, 260)

    def mark(self, target: str | None = None, detected: str | None = None,
             verdicts: dict[str, str] | None = None) -> None:
        self.target, self.detected = target, detected
        if verdicts is not None:
            self.verdicts = dict(verdicts)
        self.update()

    def paintEvent(self, event) -> None:  # noqa: N802, ANN001 - Qt name
        lay = self.array_layout
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        side = min(self.width(), self.height()) - 8
        cell = side / max(lay.rows, lay.cols)
        x0 = (self.width() - cell * lay.cols) / 2
        y0 = (self.height() - cell * lay.rows) / 2
        font = QFont(p.font())
        font.setPointSizeF(max(7.0, cell * 0.22))
        font.setBold(True)
        p.setFont(font)
        for r in range(lay.rows):
            for c in range(lay.cols):
                name = lay.taxel_name(r, c)
                colour = VERDICT_COLOURS.get(self.verdicts.get(name, ""), IDLE_CELL)
                if name == self.target:
                    colour = TARGET
                rect = QRectF(x0 + c * cell + 2, y0 + r * cell + 2, cell - 4, cell - 4)
                p.setPen(Qt.PenStyle.NoPen)
                p.setBrush(QColor(colour))
                p.drawRoundedRect(rect, 5, 5)
                if name == self.detected:
                    p.setPen(QPen(QColor(DETECTED), 4))
                    p.setBrush(Qt.BrushStyle.NoBrush)
                    p.drawEllipse(rect.adjusted(6, 6, -6, -6))
                dark = colour == IDLE_CELL
                p.setPen(QColor("#333" if dark else "white"))
                p.drawText(rect, Qt.AlignmentFlag.AlignCenter, name)
        p.end()
