"""Which heatmap cell is under the pointer: hover box, hover and click signals.

A mixin of :class:`~tactile_studio.ui.heatmap.HeatmapView`, which provides ``plot``,
``hover_box``, ``_shape``, ``_hover``, ``_cell_step`` and the ``cellHovered`` /
``cellClicked`` signals.
"""

from __future__ import annotations

import math

from PySide6.QtCore import QPointF, QRectF, Qt


class CellPointer:
    """Maps pointer positions to (row, col) cells of the displayed grid."""

    def _cell_at(self, scene_pos: QPointF) -> tuple[int, int]:
        if self._shape is None or not self.plot.sceneBoundingRect().contains(scene_pos):
            return (-1, -1)
        p = self.plot.vb.mapSceneToView(scene_pos)
        step = self._cell_step(self._shape)
        col = math.floor(p.x() / step + 0.5)
        row = math.floor(p.y() / step + 0.5)
        if 0 <= row < self._shape[0] and 0 <= col < self._shape[1]:
            return (row, col)
        return (-1, -1)

    def _on_mouse_moved(self, scene_pos: QPointF) -> None:
        cell = self._cell_at(scene_pos)
        if cell != self._hover:
            self._hover = cell
            self._draw_hover_box()
            self.cellHovered.emit(*cell)

    def _on_mouse_clicked(self, ev) -> None:  # noqa: ANN001 - pyqtgraph event
        cell = self._cell_at(ev.scenePos())
        if cell != (-1, -1) and ev.button() == Qt.MouseButton.LeftButton:
            self.cellClicked.emit(*cell)

    def hovered_cell(self) -> tuple[int, int]:
        return self._hover

    def hover_cell(self, row: int, col: int) -> None:
        """Act as if the pointer were over a cell (keyboard use, tests)."""
        if (row, col) != self._hover:
            self._hover = (row, col)
            self._draw_hover_box()
            self.cellHovered.emit(row, col)

    def _draw_hover_box(self) -> None:
        r, c = self._hover
        if r < 0 or self._shape is None:
            self.hover_box.set_cell(None)
            return
        s = self._cell_step(self._shape)
        self.hover_box.set_cell(QRectF(c * s - s / 2, r * s - s / 2, s, s))

    def leaveEvent(self, ev) -> None:  # noqa: ANN001 - Qt signature
        super().leaveEvent(ev)
        if self._hover != (-1, -1):
            self.hover_cell(-1, -1)


__all__ = ["CellPointer"]
