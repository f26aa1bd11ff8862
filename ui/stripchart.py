"""Strip chart of selected taxels over the last seconds (pyqtgraph lines, no maths)."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from pyqtgraph.Qt.internals import PrimitiveArray
from PySide6.QtCore import QLineF, QRectF, Signal
from PySide6.QtGui import QPainter, QPen
from PySide6.QtWidgets import (
    QComboBox,
    QGraphicsItem,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.live import QUANTITIES, QUANTITY_LABELS, History
from tactile_studio.live.view import decimate_minmax
from tactile_studio.ui.heatmap_colors import BACKGROUND, FOREGROUND, strip_colors


class _Traces(pg.GraphicsObject):
    """Every line of the chart in one item: polylines from preallocated point arrays.

    A plain curve item per line recomputes its data bounds and a QPainterPath on every
    update; here a frame copies the samples into each line's segment array (x0 y0 x1 y1)
    and paints ``drawLines`` with a 1-px pen (Qt's fast path). The bounds are the plot's fixed
    x window and the y range the chart sets, so nothing is measured per frame.
    """

    def __init__(self) -> None:
        super().__init__()
        self._lines: list[tuple[QPen, PrimitiveArray]] = []
        self._rect = QRectF()

    def set_lines(self, t: np.ndarray, values: np.ndarray, pens: list[QPen]) -> None:
        """``values[:, k]`` at times ``t`` in ``pens[k]``; arrays are reused, not remade."""
        drawn_before = any(len(segments) for _, segments in self._lines)
        while len(self._lines) < len(pens):
            self._lines.append((pens[len(self._lines)], PrimitiveArray(QLineF, 4)))
        del self._lines[len(pens):]
        n = max(len(t) - 1, 0) if values.size else 0
        if n == 0 and not drawn_before:
            return  # nothing drawn before or now: no repaint
        for k, pen in enumerate(pens):
            segments = self._lines[k][1]
            self._lines[k] = (pen, segments)
            segments.resize(n)
            if n:
                xy = segments.ndarray()
                xy[:, 0], xy[:, 2] = t[:-1], t[1:]
                xy[:, 1], xy[:, 3] = values[:-1, k], values[1:, k]
        self.update()

    def set_bounds(self, rect: QRectF) -> None:
        if rect != self._rect:
            self.prepareGeometryChange()
            self._rect = QRectF(rect)

    def boundingRect(self) -> QRectF:  # noqa: N802 - Qt name
        return self._rect

    def paint(self, p: QPainter, *args: object) -> None:
        for pen, segments in self._lines:
            if len(segments):
                p.setPen(pen)
                p.drawLines(*segments.drawargs())


class StripChart(QWidget):
    """One line per selected taxel; the owner feeds :class:`History` at display rate."""

    quantityChanged = Signal(str)
    clearRequested = Signal()

    def __init__(self, parent: QWidget | None = None, seconds: float = 10.0) -> None:
        super().__init__(parent)
        self.seconds = seconds
        self._x = (-seconds, 0.0)  # the time axis: live, the last seconds up to now
        self.cursor_line: pg.InfiniteLine | None = None  # a player's cursor (set_window)
        self._spans: list[tuple[float, float, str, bool]] = []  # shaded stretches
        self._span_items: list[pg.GraphicsObject] = []
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
        # a little padding: the lines' bounds then stay clear of the axes, which are not
        # repainted when only the lines change
        self.plot.setXRange(-seconds, 0, padding=0.02)
        self.plot.disableAutoRange()
        self._y_range = (-1.0, 1.0)
        self.plot.setYRange(*self._y_range, padding=0.08)
        zero = pg.InfiniteLine(pos=0, angle=0, pen=pg.mkPen("#b0b0b0", width=1))
        self.plot.addItem(zero)
        for name in ("left", "bottom"):
            ax = self.plot.getAxis(name)
            ax.setPen(FOREGROUND)
            ax.setTextPen(FOREGROUND)
            ax.enableAutoSIPrefix(False)
        self.plot.setLabel("bottom", "time (s)", color=FOREGROUND)
        self.legend = self.plot.addLegend(offset=(8, 8), labelTextColor=FOREGROUND,
                                          # opaque: cheaper to repaint
                                          brush=pg.mkBrush(255, 255, 255))
        self.traces = _Traces()
        self.traces.set_bounds(QRectF(-seconds, -1.0, seconds, 2.0))
        self.plot.addItem(self.traces)
        self._legend_items: dict[str, pg.PlotDataItem] = {}  # legend entries only
        self._pens: list[QPen] = []
        self._names: list[str] = []
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

        Pens and legend entries change only when the set of taxels does: at display rate
        only the samples are copied, thinned to each pixel column's min and max. Lines are one
        pixel wide — Qt draws those on a fast
        path; wider lines cost 4-7x more to paint.
        """
        if history.names != self._names:
            self._set_names(list(history.names))
        # never more than two points per pixel column (its min and max: peaks stay)
        t, values = decimate_minmax(history.t, history.values, *self._x,
                                    self.pixel_columns())
        self.traces.set_lines(t, values, self._pens)
        self._update_y_range(history.values)
        label = f"{QUANTITY_LABELS[history.quantity]} ({history.units})"
        if label != self._units:
            self._units = label
            self.plot.setLabel("left", label, color=FOREGROUND)

    def _set_names(self, names: list[str]) -> None:
        """New set of lines: pens and legend entries change only here."""
        colors = strip_colors(len(names))
        self._pens = [pg.mkPen(c, width=1) for c in colors]
        for item in self._legend_items.values():
            self.legend.removeItem(item)
        self._legend_items = {}
        # more than 4 lines: two columns, so 8 names fit a short chart
        self.legend.setColumnCount(1 if len(names) <= 4 else 2)
        for name, pen in zip(names, self._pens):
            self._legend_items[name] = item = pg.PlotDataItem(pen=pen, name=name)
            self.legend.addItem(item, name)
        # the legend sits over the lines, so it is repainted with them: from a cached
        # pixmap, not by laying out its text again
        for legend_item in (self.legend, *self.legend.childItems()):
            legend_item.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        self._names = names

    def set_window(self, t0: float, t1: float, cursor: float | None = None) -> None:
        """Chart ``t0..t1`` instead of the last seconds (a player: session time, the
        stretch before and after its cursor), with a vertical line at ``cursor``; the
        next :meth:`set_history` gives t on the same axis."""
        if (t0, t1) != self._x:
            self._x = (float(t0), float(t1))
            self.plot.setXRange(t0, t1, padding=0.02)
            lo, hi = self._y_range
            self.traces.set_bounds(QRectF(t0, lo, t1 - t0, hi - lo))
        if cursor is not None:
            if self.cursor_line is None:
                self.cursor_line = pg.InfiniteLine(pos=cursor, angle=90,
                                                   pen=pg.mkPen(FOREGROUND, width=1))
                self.plot.addItem(self.cursor_line)
            self.cursor_line.setPos(cursor)

    def set_spans(self, spans: list[tuple[float, float, str, bool]]) -> None:
        """Shade stretches of the time axis (start, end, name, emphasised), each named at
        its top: a player's trials, the current one darker, so the trial jumped to is
        seen on the chart; remade only when they change."""
        if spans == self._spans:
            return
        for item in self._span_items:
            self.plot.removeItem(item)
        self._spans, self._span_items = list(spans), []
        for a, b, name, strong in spans:
            region = pg.LinearRegionItem((a, b), movable=False,
                                         brush=pg.mkBrush(70, 130, 200, 70 if strong else 22),
                                         pen=pg.mkPen(70, 130, 200, 90))
            region.setZValue(-10)  # under the lines
            label = pg.TextItem(name, color=FOREGROUND, anchor=(0, 0))
            label.setPos(a, self._y_range[1])
            self.plot.addItem(region)
            self.plot.addItem(label)
            self._span_items += [region, label]

    def span_names(self) -> list[str]:
        return [name for _, _, name, _ in self._spans]

    def pixel_columns(self) -> int:
        """How many pixel columns the chart's time window spans on screen."""
        (x0, x1), _ = self.plot.vb.viewRange()
        span = self._x[1] - self._x[0]
        return max(1, int(self.plot.vb.width() * span / max(x1 - x0, 1e-9)))

    def curve_names(self) -> list[str]:
        return list(self._names)

    def line_data(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of one charted line as drawn."""
        xy = self.traces._lines[self._names.index(name)][1].ndarray()
        if not len(xy):
            return np.empty(0), np.empty(0)
        return np.append(xy[:, 0], xy[-1, 2]), np.append(xy[:, 1], xy[-1, 3])

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
            self.plot.setYRange(*self._y_range, padding=0.08)
            lo, hi = self._y_range
            for item in self._span_items:
                if isinstance(item, pg.TextItem):
                    item.setPos(item.pos().x(), hi)
            self.traces.set_bounds(QRectF(self._x[0], lo, self._x[1] - self._x[0], hi - lo))


def _nice_step(x: float) -> float:
    """The 1-2-5 step at or above ``x``."""
    mag = 10.0 ** np.floor(np.log10(max(x, 1e-12)))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * mag >= x:
            return m * mag
    return 10.0 * mag
