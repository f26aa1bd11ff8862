"""The heatmap's control row: physical/virtual grid, colour range, shear arrows.

Only widgets; :class:`~tactile_studio.ui.heatmap.HeatmapView` connects them.
"""

from __future__ import annotations

from PySide6.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QToolButton,
    QWidget,
)

DEFAULT_MAX_KPA = 10.0
# Arrow length in taxel pitches per kPa (2 kPa of shear is one pitch long). The same in
# both grids, so toggling physical/virtual does not change what an arrow means.
DEFAULT_ARROW_SCALE = 0.5


class HeatmapControls(QWidget):
    """Grid toggle, auto range / max, arrows on/off and their scale, in one row."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        row = QHBoxLayout(self)
        row.setContentsMargins(4, 0, 4, 0)
        self.physical_button = QToolButton(text="Physical 6×6", checkable=True, checked=True)
        self.virtual_button = QToolButton(text="Virtual 11×11", checkable=True)
        group = QButtonGroup(self)
        group.setExclusive(True)
        for b in (self.physical_button, self.virtual_button):
            group.addButton(b)
            row.addWidget(b)
        row.addSpacing(16)
        self.auto_range = QCheckBox("Auto range")
        row.addWidget(self.auto_range)
        row.addWidget(QLabel("max"))
        self.max_spin = QDoubleSpinBox(decimals=1, minimum=0.5, maximum=500.0,
                                       singleStep=1.0, value=DEFAULT_MAX_KPA)
        self.max_spin.setSuffix(" kPa")
        row.addWidget(self.max_spin)
        row.addSpacing(16)
        self.arrows_check = QCheckBox("Shear arrows", checked=True)
        row.addWidget(self.arrows_check)
        self.scale_spin = QDoubleSpinBox(decimals=2, minimum=0.01, maximum=5.0,
                                         singleStep=0.05, value=DEFAULT_ARROW_SCALE)
        self.scale_spin.setSuffix(" pitch/kPa")
        self.scale_spin.setToolTip("Arrow length: taxel pitches per kPa of shear")
        row.addWidget(self.scale_spin)
        row.addStretch(1)


__all__ = ["DEFAULT_ARROW_SCALE", "DEFAULT_MAX_KPA", "HeatmapControls"]
