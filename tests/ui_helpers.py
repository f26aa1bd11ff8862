"""Drive the real mouse over heatmap cells in GUI tests."""

from __future__ import annotations

from PySide6.QtCore import QPointF


def point_at_cell(qtbot, heat, row: int, col: int, tries: list[int]) -> bool:
    """Move the pointer over a cell of ``heat``; True once the map reports that cell.

    Maps again on every call (the view settles its geometry after a shape change or
    after it is first shown) and jitters by a pixel, since a repeated move to the same
    point may not be delivered. Use inside ``qtbot.waitUntil``.
    """
    tries[0] += 1
    step = 0.5 if heat.virtual else 1.0
    scene = heat.plot.vb.mapViewToScene(QPointF(col * step, row * step))
    pos = heat.view.mapFromScene(scene)
    pos.setX(pos.x() + tries[0] % 3 - 1)
    qtbot.mouseMove(heat.view.viewport(), pos)
    return heat.hovered_cell() == (row, col)


def hover_cell_with_mouse(qtbot, heat, row: int, col: int, timeout: int = 5000) -> None:
    """Move the real mouse until the map shows ``(row, col)`` as hovered."""
    tries = [0]
    qtbot.waitUntil(lambda: point_at_cell(qtbot, heat, row, col, tries), timeout=timeout)
