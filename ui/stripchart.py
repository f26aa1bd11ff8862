"""Strip chart of selected taxels over the last seconds (pyqtgraph lines, no maths)."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Signal
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from tactile_studio.live import QUANTITIES, QUANTITY_LABELS, History
from tactile_studio.ui.heatmap import BACKGROUND, FOREGROUND, strip_colors


class StripChart(QWidget):
    """One line per selected taxel; the owner feeds :class:`History` at display rate."""

    quantityChanged = Signal(str)
    clearRequested = Signal()

    def __init__(self, parent: QWidget | None = None, seconds: float = 10.0) -> None:
        super().__init__(parent)
        self.seconds = seconds
        self.quantity_box = QComboBox()
        for q in QUANTITIES:
            self.quantity_box.addItem(QUANTITY_LABELS[q], q)
        self.quantity_box.currentIndexChanged.connect(
            lambda _: self.quantityChanged.emit(self.quantity()))
        self.hint = QLabel("Click taxels on the map to add or remove them.")
        self.hint.setObjectName("hint")
        clear = QPushButton("Clear")
        clear.clicked.connect(self.clearRequested)
        top = QHBoxLayout()
        top.setContentsMargins(4, 0, 4, 0)
        top.addWidget(QLabel("Show"))
        top.addWidget(self.quantity_box)
        top.addWidget(self.hint, 1)
        top.addWidget(clear)

        self.plot_widget = pg.PlotWidget(background=BACKGROUND)
        self.plot = self.plot_widget.getPlotItem()
        self.plot.setMenuEnabled(False)
        self.plot.setMouseEnabled(False, False)
        self.plot.hideButtons()
        # No grid and a y range that only moves in steps: a grid or a range that
        # changes every frame makes pyqtgraph repaint the axes at display rate.
        self.plot.setXRange(-seconds, 0, padding=0)
        self.plot.disableAutoRange()
        self._y_range = (-1.0, 1.0)
        self.plot.setYRange(*self._y_range, padding=0)
        zero = pg.InfiniteLine(pos=0, angle=0, pen=pg.mkPen("#b0b0b0", width=1))
        self.plot.addItem(zero)
        for name in ("left", "bottom"):
            ax = self.plot.getAxis(name)
            ax.setPen(FOREGROUND)
            ax.setTextPen(FOREGROUND)
            ax.enableAutoSIPrefix(False)
        self.plot.setLabel("bottom", "time (s)", color=FOREGROUND)
        self.legend = self.plot.addLegend(offset=(8, 8), labelTextColor=FOREGROUND,
                                          brush=pg.mkBrush(255, 255, 255, 200))
        self._curves: dict[str, pg.PlotCurveItem] = {}
        self._colors: dict[str, str] = {}
        box = QVBoxLayout(self)
        box.setContentsMargins(0, 0, 0, 0)
        box.addLayout(top)
        box.addWidget(self.plot_widget, 1)
        self._units = ""

    def quantity(self) -> str:
        return str(self.quantity_box.currentData())

    def set_quantity(self, quantity: str) -> None:
        i = self.quantity_box.findData(quantity)
        if i >= 0:
            self.quantity_box.setCurrentIndex(i)

    def set_history(self, history: History) -> None:
        """Redraw the lines; taxels that are no longer selected disappear.

        Curves are created only when a taxel is added, and pens only when a line's colour
        changes: at display rate only the data are replaced. Lines are one pixel wide —
        Qt draws those on a fast path; wider lines cost 4-7x more to paint.
        """
        colors = strip_colors(len(history.names))
        for name in list(self._curves):
            if name not in history.names:
                self.legend.removeItem(self._curves[name])
                self.plot.removeItem(self._curves.pop(name))
                self._colors.pop(name, None)
        empty = history.values.size == 0
        for k, name in enumerate(history.names):
            curve = self._curves.get(name)
            if curve is None:
                curve = pg.PlotCurveItem(name=name, skipFiniteCheck=True)
                self.plot.addItem(curve)
                self._curves[name] = curve
            if self._colors.get(name) != colors[k]:
                self._colors[name] = colors[k]
                curve.setPen(pg.mkPen(colors[k], width=1))
            curve.setData(history.t, np.empty(0) if empty else history.values[:, k],
                          skipFiniteCheck=True)
        self._update_y_range(history.values)
        label = f"{QUANTITY_LABELS[history.quantity]} ({history.units})"
        if label != self._units:
            self._units = label
            self.plot.setLabel("left", label, color=FOREGROUND)

    def curve_names(self) -> list[str]:
        return list(self._curves)

    def _update_y_range(self, values: np.ndarray) -> None:
        """Grow at once to a rounded range; shrink only when the data use under a third."""
        if values.size == 0:
            return
        lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
        span = max(max(hi, 0.0) - min(lo, 0.0), 1.0)
        lo = lo if lo < -0.05 * span else 0.0  # noise just under zero: keep zero the floor
        hi = hi if hi > 0.05 * span else 0.0
        step = _nice_step(span / 4)
        want = (step * np.floor(lo / step), step * np.ceil(hi / step))
        cur_lo, cur_hi = self._y_range
        grow = want[0] < cur_lo or want[1] > cur_hi
        shrink = (want[1] - want[0]) < (cur_hi - cur_lo) / 3
        if grow or shrink:
            self._y_range = (float(want[0]), float(want[1]))
            self.plot.setYRange(*self._y_range, padding=0.05)


def _nice_step(x: float) -> float:
    """The 1-2-5 step at or above ``x``."""
    mag = 10.0 ** np.floor(np.log10(max(x, 1e-12)))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * mag >= x:
            return m * mag
    return 10.0 * mag
