"""Small helpers for the workspace's read-only, sortable tables."""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QAbstractItemView, QHeaderView, QTableWidget, QTableWidgetItem


class SortItem(QTableWidgetItem):
    """Sorts by the value it was made from (numbers as numbers, None last)."""

    def __init__(self, value: Any, text: str | None = None) -> None:
        super().__init__(text if text is not None else ("" if value is None else str(value)))
        self.value = value

    def __lt__(self, other: QTableWidgetItem) -> bool:
        a, b = self.value, getattr(other, "value", None)
        if isinstance(a, (int, float)) and isinstance(b, (int, float)):
            return a < b
        if a is None or b is None:
            return b is None and a is not None
        return str(a) < str(b)


def make_table(columns: list[str]) -> QTableWidget:
    t = QTableWidget(0, len(columns))
    t.setHorizontalHeaderLabels(columns)
    t.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
    t.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
    t.verticalHeader().hide()
    t.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
    t.horizontalHeader().setStretchLastSection(True)
    return t


def fill_row(table: QTableWidget, r: int, values: list[Any], texts: list[str | None],
             error: str = "") -> None:
    for c, (v, txt) in enumerate(zip(values, texts)):
        item = SortItem(v, txt)
        if isinstance(v, (int, float)) and not isinstance(v, bool):  # numbers line up right
            item.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        if error:
            item.setForeground(QColor(170, 0, 0))
            item.setToolTip(error)
        item.setData(Qt.ItemDataRole.UserRole, r)
        table.setItem(r, c, item)
