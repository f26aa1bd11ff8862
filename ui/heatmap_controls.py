"""The heatmap's control row: physical/virtual grid, colour range, shear arrows.

Only widgets; :class:`~tactile_studio.ui.heatmap.HeatmapView` connects them.
"""

from __future__ import annotations

from PySide6.QtCore import QSize
from PySide6.QtGui import QResizeEvent
from PySide6.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QDoubleSpinBox,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLayout,
    QToolButton,
    QWidget,
)

DEFAULT_MAX_KPA = 10.0  # the fixed range's first value when the user fixes it
# Auto range is the default: it rises at once to the strongest press (a 30 kPa press gets
# 0-30, not a saturated 0-10) and falls back after; never below this, so a typical touch
# (real people's peaks: 3-13 kPa) fills the scale and an idle sensor's noise stays dark.
AUTO_FLOOR_KPA = 5.0
# Arrow length in taxel pitches per kPa (2 kPa of shear is one pitch long). The same in
# both grids, so toggling physical/virtual does not change what an arrow means.
DEFAULT_ARROW_SCALE = 0.5


class HeatmapControls(QWidget):
    """Grid toggle, auto range / max, arrows on/off and their scale: one row, or two
    when the map is narrow (a dock beside it), so the map never pushes the device panel
    off the window."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.grid = QGridLayout(self)
        self.grid.setContentsMargins(4, 0, 4, 0)
        self.grid.setVerticalSpacing(2)
        self.grid.setSizeConstraint(QLayout.SizeConstraint.SetNoConstraint)
        self.range_row, self.arrow_row = QWidget(), QWidget()
        row = QHBoxLayout(self.range_row)
        row.setContentsMargins(0, 0, 0, 0)
        self.physical_button = QToolButton(text="Physical 6×6", checkable=True, checked=True)
        self.virtual_button = QToolButton(text="Virtual 11×11", checkable=True)
        group = QButtonGroup(self)
        group.setExclusive(True)
        for b in (self.physical_button, self.virtual_button):
            group.addButton(b)
            row.addWidget(b)
        row.addSpacing(16)
        self.auto_range = QCheckBox("Auto range", checked=True)
        self.auto_range.setToolTip(
            f"Follows the strongest press (in 1-2-3-5 steps), falls back after it; never "
            f"below 0-{AUTO_FLOOR_KPA:g} kPa. Untick to fix the range at max.")
        row.addWidget(self.auto_range)
        row.addWidget(QLabel("max"))
        self.max_spin = QDoubleSpinBox(decimals=1, minimum=0.5, maximum=500.0,
                                       singleStep=1.0, value=DEFAULT_MAX_KPA)
        self.max_spin.setSuffix(" kPa")
        row.addWidget(self.max_spin)
        arrows = QHBoxLayout(self.arrow_row)
        arrows.setContentsMargins(0, 0, 0, 0)
        self.arrows_check = QCheckBox("Shear arrows", checked=True)
        arrows.addWidget(self.arrows_check)
        self.scale_spin = QDoubleSpinBox(decimals=2, minimum=0.01, maximum=5.0,
                                         singleStep=0.05, value=DEFAULT_ARROW_SCALE)
        self.scale_spin.setSuffix(" pitch/kPa")
        self.scale_spin.setToolTip("Arrow length: taxel pitches per kPa of shear")
        arrows.addWidget(self.scale_spin)
        arrows.addStretch(1)
        row.addStretch(1)
        self.grid.addWidget(self.range_row, 0, 0)
        self.grid.addWidget(self.arrow_row, 0, 2)
        self.grid.setColumnMinimumWidth(1, 16)
        self.grid.setColumnStretch(3, 1)
        self.two_rows = False

    def _wide_width(self) -> int:
        m = self.grid.contentsMargins()
        return (self.range_row.minimumSizeHint().width() + 16
                + self.arrow_row.minimumSizeHint().width() + m.left() + m.right())

    def _place(self, two_rows: bool) -> None:
        if two_rows == self.two_rows:
            return
        self.two_rows = two_rows
        self.grid.removeWidget(self.arrow_row)
        if two_rows:
            self.grid.addWidget(self.arrow_row, 1, 0)
            self.grid.setColumnMinimumWidth(1, 0)
        else:
            self.grid.addWidget(self.arrow_row, 0, 2)
            self.grid.setColumnMinimumWidth(1, 16)
        self.updateGeometry()

    def minimumSizeHint(self) -> QSize:  # noqa: N802 - Qt name
        """The two-row width: the map may get narrower than one long row."""
        m = self.grid.contentsMargins()
        width = max(self.range_row.minimumSizeHint().width(),
                    self.arrow_row.minimumSizeHint().width()) + m.left() + m.right()
        rows = self.range_row.sizeHint().height() * (2 if self.two_rows else 1) + 2
        return QSize(width, rows)

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt name
        return QSize(self._wide_width(), self.minimumSizeHint().height())

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 - Qt name
        super().resizeEvent(event)
        self._place(event.size().width() < self._wide_width())


__all__ = ["AUTO_FLOOR_KPA", "DEFAULT_ARROW_SCALE", "DEFAULT_MAX_KPA", "HeatmapControls"]
