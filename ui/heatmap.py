"""A reusable normal-stress heatmap with shear arrows, for every screen that shows a sensor.

Give it arrays (``set_frame``) — it never decodes. Cells are drawn in taxel units: the
taxel in row r, column c is centred at (x=c, y=r), row 0 at the top, so the physical 6x6
and the virtual 11x11 grid line up and arrows point the way the skin is dragged
(x right = increasing column, y down = increasing row).
"""

from __future__ import annotations

import math
import string

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QRectF, Qt, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.sensor.layout import Layout
from tactile_studio.ui.arrow_field import ArrowField
from tactile_studio.ui.grid_image import CellMarks, GridImage
from tactile_studio.ui.heatmap_colors import (
    BACKGROUND,
    COLOR_SCHEMES,
    FOREGROUND,
    NEGATIVE_SHARE,
    diverging_colormap,
    nice_ceil,
    strip_colors,
)
from tactile_studio.ui.heatmap_controls import (
    AUTO_FLOOR_KPA,
    DEFAULT_ARROW_SCALE,
    HeatmapControls,
)
from tactile_studio.ui.heatmap_pointer import CellPointer
from tactile_studio.ui.map_overlays import AxisLabels, HoverBox


class _PaintNotifyingView(pg.GraphicsLayoutWidget):
    """A GraphicsLayoutWidget that says when it has painted (for paint latency)."""

    painted = Signal()

    def paintEvent(self, ev) -> None:  # noqa: ANN001 - Qt signature
        super().paintEvent(ev)
        self.painted.emit()


class HeatmapView(CellPointer, QWidget):
    """Normal stress image + colour bar with units + shear arrows + hover/click cells.

    Signals carry cells of the displayed grid (row, col); ``cellHovered`` sends
    (-1, -1) when the pointer leaves the map. ``virtualChanged`` fires when the user
    flips the physical/virtual toggle: the owner then feeds the other grid.
    """

    cellHovered = Signal(int, int)
    cellClicked = Signal(int, int)
    virtualChanged = Signal(bool)
    painted = Signal()

    def __init__(self, parent: QWidget | None = None, controls: bool = True,
                 colormap: str = "viridis") -> None:
        super().__init__(parent)
        self._units = "kPa"
        self._virtual = False
        self._fixed_max: float | None = None  # auto range (said on the bar and the max box)
        self._auto_hi = AUTO_FLOOR_KPA
        self._auto_lo = 0.0
        self._scheme = "sequential"
        self._levels = (0.0, AUTO_FLOOR_KPA)
        self._arrow_scale = DEFAULT_ARROW_SCALE
        self._arrows_on = True
        self.arrow_min_kpa = 0.3  # the paper's smallest detectable shear: hide noise
        self._shape: tuple[int, int] | None = None
        self._hover = (-1, -1)
        self._layout: Layout | None = None
        self._data: np.ndarray | None = None
        self._build_plot(colormap)
        self._build_layout(controls)

    # ---- the view's parts ----------------------------------------------------------
    def _build_plot(self, colormap: str) -> None:
        """The map: the plot, its row and column labels, the image and its colour bar,
        the arrows, the marks and the hover box."""
        self.view = _PaintNotifyingView()
        self.view.setBackground(BACKGROUND)
        self.view.painted.connect(self.painted)
        self.plot = self.view.addPlot()
        self.plot.setAspectLocked(True)
        self.plot.invertY(True)
        self.plot.setMenuEnabled(False)
        self.plot.setMouseEnabled(False, False)
        self.plot.hideButtons()
        self.plot.hideAxis("bottom")
        self.plot.hideAxis("left")
        label_font = QFont()
        label_font.setPointSizeF(10.5)
        label_font.setBold(True)
        self.row_labels = AxisLabels(FOREGROUND, label_font)  # A, B, ... left of the map
        self.col_labels = AxisLabels(FOREGROUND, label_font)  # 1, 2, ... above it
        for item in (self.row_labels, self.col_labels):
            self.plot.addItem(item)
        self.cmap = pg.colormap.get(colormap)
        self.image = GridImage(self.cmap)
        self.image.set_levels(0.0, AUTO_FLOOR_KPA)
        self.plot.addItem(self.image)
        # the bar only shows the map and levels; the image is coloured by GridImage
        self.colorbar = pg.ColorBarItem(values=(0.0, AUTO_FLOOR_KPA), colorMap=self.cmap,
                                        interactive=False,
                                        width=18, colorMapMenu=False)
        self.plot.layout.addItem(self.colorbar, 2, 5)  # right of the map
        self.plot.layout.setColumnFixedWidth(4, 5)
        bar_axis = self.colorbar.axis
        bar_axis.setPen(FOREGROUND)
        bar_axis.setTextPen(FOREGROUND)
        bar_axis.enableAutoSIPrefix(False)
        bar_axis.setLabel(self._bar_label(), color=FOREGROUND)
        self.arrows = ArrowField()  # every shear arrow in one item
        self.arrows.setZValue(10)
        self.plot.addItem(self.arrows)
        self.marks = CellMarks()
        self.marks.setZValue(8)
        self.plot.addItem(self.marks)
        self.hover_box = HoverBox()
        self.hover_box.setZValue(12)
        self.plot.addItem(self.hover_box)
        self.view.scene().sigMouseMoved.connect(self._on_mouse_moved)
        self.view.scene().sigMouseClicked.connect(self._on_mouse_clicked)

    def _build_layout(self, controls: bool) -> None:
        """The controls above the map; the readout and the colour map's box below."""
        self.readout = QLabel(" ")
        self.readout.setObjectName("readout")
        self.readout.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.readout.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)

        box = QVBoxLayout(self)
        box.setContentsMargins(0, 0, 0, 0)
        box.setSpacing(4)
        self.controls = self._build_controls()
        box.addWidget(self.controls)
        self.controls.setVisible(controls)
        box.addWidget(self.view, 1)
        bottom = QHBoxLayout()
        bottom.setContentsMargins(0, 0, 4, 0)
        bottom.addWidget(self.readout, 1)
        # under the colour bar: the colour map is chosen where it is read
        self.scheme_box = QComboBox()
        for key, label in COLOR_SCHEMES.items():
            self.scheme_box.addItem(label, key)
        self.scheme_box.setToolTip(
            "Colour map. viridis: 0 to max; stress below baseline shows as 0.\n"
            "diverging: white at 0, load in reds, stress below baseline (counts above "
            "the baseline, e.g. a neighbouring taxel lifted) in blues.")
        self.scheme_box.currentIndexChanged.connect(
            lambda _: self.set_color_scheme(str(self.scheme_box.currentData())))
        bottom.addWidget(self.scheme_box)
        box.addLayout(bottom)

    # ---- controls ------------------------------------------------------------------
    def _build_controls(self) -> QWidget:
        w = HeatmapControls()
        self.physical_button, self.virtual_button = w.physical_button, w.virtual_button
        self.auto_range, self.max_spin = w.auto_range, w.max_spin
        self.arrows_check, self.scale_spin = w.arrows_check, w.scale_spin
        self.virtual_button.toggled.connect(self._on_virtual_toggled)
        self.auto_range.toggled.connect(self._on_range_controls)
        self.max_spin.valueChanged.connect(self._on_range_controls)
        self.arrows_check.toggled.connect(self.set_arrows_visible)
        self.scale_spin.valueChanged.connect(self.set_arrow_scale)
        self.max_spin.setEnabled(False)  # auto range first: the box shows where it is
        self.max_spin.setValue(AUTO_FLOOR_KPA)
        return w

    def _on_virtual_toggled(self, on: bool) -> None:
        if on != self._virtual:
            self._virtual = on
            self.virtualChanged.emit(on)

    def _on_range_controls(self, *_: object) -> None:
        self.max_spin.setEnabled(not self.auto_range.isChecked())
        if self.auto_range.isChecked():
            self.set_range(None)
        else:  # fixing it: at what auto showed, or the user's value
            self.set_range(self.max_spin.value())

    # ---- public API ----------------------------------------------------------------
    def set_layout(self, layout: Layout | None) -> None:
        """Label the axes with the layout's taxel names (rows A.., columns 1..). None (no
        device) keeps the last sensor's layout: the map keeps its taxel names whether a
        device is connected or not."""
        if layout is not None:
            self._layout = layout
            vr, vc = layout.virtual_shape
            self.physical_button.setText(f"Physical {layout.rows}×{layout.cols}")
            self.virtual_button.setText(f"Virtual {vr}×{vc}")
            if self._shape is None:  # no frame yet: the empty grid is named already
                empty = layout.virtual_shape if self._virtual else (layout.rows, layout.cols)
                self._update_ticks(empty)
                self._set_view_range(empty)
                return
        self._update_ticks()

    @property
    def virtual(self) -> bool:
        return self._virtual

    def set_virtual(self, on: bool) -> None:
        """Show the toggle in this state (the owner feeds the matching grid)."""
        self._virtual = on
        (self.virtual_button if on else self.physical_button).setChecked(True)

    @property
    def fixed_max(self) -> float | None:
        """The fixed colour range top (kPa), or None for auto range."""
        return self._fixed_max

    def set_range(self, fixed_max: float | None) -> None:
        """Fix the colour range to 0..fixed_max, or None to follow the data."""
        self._fixed_max = fixed_max
        self.auto_range.blockSignals(True)
        self.auto_range.setChecked(fixed_max is None)
        self.auto_range.blockSignals(False)
        if fixed_max is not None:
            self._show_max(fixed_max)
            self._apply_levels(self._lo_for(fixed_max), fixed_max)
        self.max_spin.setEnabled(fixed_max is not None)
        self.colorbar.axis.setLabel(self._bar_label(), color=FOREGROUND)

    def _show_max(self, value: float) -> None:
        """The max box shows the range's top: the fixed one, or where auto is now."""
        self.max_spin.blockSignals(True)
        self.max_spin.setValue(value)
        self.max_spin.blockSignals(False)

    def levels(self) -> tuple[float, float]:
        """The colour range (low, high) in the display's units."""
        lo, hi = self.colorbar.levels()
        return float(lo), float(hi)

    @property
    def color_scheme(self) -> str:
        """"sequential" (0..max) or "diverging" (stress below baseline in blues)."""
        return self._scheme

    def set_color_scheme(self, scheme: str) -> None:
        if scheme not in COLOR_SCHEMES:
            raise ValueError(f"colour scheme must be one of {list(COLOR_SCHEMES)}")
        self._scheme = scheme
        i = self.scheme_box.findData(scheme)
        if i != self.scheme_box.currentIndex():
            self.scheme_box.blockSignals(True)
            self.scheme_box.setCurrentIndex(i)
            self.scheme_box.blockSignals(False)
        hi = self._fixed_max if self._fixed_max is not None else self._levels[1]
        lo = self._lo_for(hi) if self._fixed_max is not None else self._auto_low(hi)
        self._levels = (math.nan, math.nan)  # force: the map itself changes
        self._apply_levels(lo, hi)

    def _lo_for(self, hi: float) -> float:
        return -NEGATIVE_SHARE * hi if self._scheme == "diverging" else 0.0

    def _auto_low(self, hi: float) -> float:
        if self._scheme != "diverging":
            return 0.0
        return -max(NEGATIVE_SHARE * hi, nice_ceil(-self._auto_lo))

    def _apply_levels(self, lo: float, hi: float) -> None:
        """Set colour levels (and the diverging map's zero) only when they change."""
        if (lo, hi) == self._levels:
            return
        self._levels = (lo, hi)
        if self._fixed_max is None:
            self._show_max(hi)
        cmap = diverging_colormap(lo, hi) if self._scheme == "diverging" else self.cmap
        self.colorbar.setColorMap(cmap)
        self.colorbar.setLevels((lo, hi))
        self.image.set_colormap(cmap)
        self.image.set_levels(lo, hi)

    @property
    def arrow_scale(self) -> float:
        return self._arrow_scale

    def set_arrow_scale(self, cells_per_kpa: float) -> None:
        self._arrow_scale = float(cells_per_kpa)
        if abs(self.scale_spin.value() - cells_per_kpa) > 1e-9:
            self.scale_spin.setValue(cells_per_kpa)

    def set_arrows_visible(self, on: bool) -> None:
        self._arrows_on = bool(on)
        self.arrows_check.setChecked(on)
        if not on:
            self.arrows.clear()

    def set_readout_text(self, text: str) -> None:
        self.readout.setText(text or " ")

    def image_data(self) -> np.ndarray | None:
        """The array currently shown (rows x cols)."""
        return self._data

    def set_marked_cells(self, cells: list[tuple[int, int]], colors: list[str]) -> None:
        """Outline physical taxels (row, col) in colours, e.g. the strip chart's taxels."""
        self.marks.set_marks([QRectF(c - 0.43, r - 0.43, 0.86, 0.86) for r, c in cells],
                             colors)

    def clear(self) -> None:
        """Blank the map (no device)."""
        self._data = None
        self.image.clear()
        self.arrows.clear()

    def set_frame(self, normal: np.ndarray, shear_x: np.ndarray | None = None,
                  shear_y: np.ndarray | None = None, units: str = "kPa") -> None:
        """Draw one frame: ``normal`` (R, C), optional shear (R, C), row 0 at the top.

        A (2R-1, 2C-1) grid is drawn as a virtual grid between the physical centres.
        """
        normal = np.asarray(normal, dtype=np.float32)
        shape = normal.shape
        step = self._cell_step(shape)
        new_shape = shape != self._shape
        if units != self._units:
            self._units = units
            self.colorbar.axis.setLabel(self._bar_label(), color=FOREGROUND)
        self._data = normal
        if self._fixed_max is None and normal.size:
            # rise at once, fall slowly, in 1-2-5 steps: the scale does not flicker
            self._auto_hi = max(AUTO_FLOOR_KPA, float(np.nanmax(normal)), self._auto_hi * 0.97)
            self._auto_lo = min(0.0, float(np.nanmin(normal)), self._auto_lo * 0.97)
            hi = nice_ceil(self._auto_hi)
            self._apply_levels(self._auto_low(hi), hi)
        self.image.set_data(normal)
        if new_shape:  # after setImage: the rect maps the image's pixels to taxel units
            self._shape = shape
            self.image.set_rect(QRectF(-step / 2, -step / 2, shape[1] * step,
                                       shape[0] * step))
            self._update_ticks()
            self._set_view_range()
            r, c = self._hover
            if r >= shape[0] or c >= shape[1]:
                self.hover_cell(-1, -1)
            self._draw_hover_box()
        self._draw_arrows(shear_x, shear_y, step)

    # ---- drawing helpers -----------------------------------------------------------
    def _bar_label(self) -> str:
        auto = ", auto range" if self._fixed_max is None else ""
        return f"Normal stress ({self._units}){auto}"

    def _cell_step(self, shape: tuple[int, ...]) -> float:
        lay = self._layout
        if lay is not None:
            virtual = shape == lay.virtual_shape and shape != (lay.rows, lay.cols)
        else:
            virtual = self._virtual
        return 0.5 if virtual else 1.0

    def _set_view_range(self, shape: tuple[int, int] | None = None) -> None:
        shape = shape or self._shape
        if shape is None:
            return
        step = self._cell_step(shape)
        r, c = shape
        # leave room on the left and top for the row letters and column numbers
        self.plot.setRange(xRange=(-1.05, (c - 0.5) * step), yRange=(-1.0, (r - 0.5) * step),
                           padding=0.01)

    def _update_ticks(self, shape: tuple[int, int] | None = None) -> None:
        """Row letters and column numbers right next to the map (axes would sit at the
        edge of the aspect-locked view, far from the cells); ``shape``: a grid not drawn
        yet (a sensor connected, no frame so far)."""
        lay = self._layout
        shape = shape or self._shape
        if shape is None:
            self.row_labels.set_labels([], (1, 0.5), QRectF())
            self.col_labels.set_labels([], (0.5, 1), QRectF())
            return
        step = self._cell_step(shape)
        rows = round((shape[0] - 1) * step) + 1
        cols = round((shape[1] - 1) * step) + 1
        # bounds: the margin strips left of and above the map, clear of the cells
        # taxel names (A.. down, 1.. across) in every state, with or without a layout
        name = lay.taxel_name if lay is not None else _taxel_name
        self.row_labels.set_labels(
            [(name(r, 0)[:-1], -0.62, r) for r in range(rows)],
            (1, 0.5), QRectF(-1.5, -0.5, 1.0, rows))
        self.col_labels.set_labels(
            [(str(c + 1), c, -0.6) for c in range(cols)],
            (0.5, 1), QRectF(-0.5, -1.5, cols, 1.0))

    def _draw_arrows(self, sx: np.ndarray | None, sy: np.ndarray | None, step: float) -> None:
        if not self._arrows_on or sx is None or sy is None:
            self.arrows.clear()
            return
        rr, cc = np.nonzero(np.hypot(sx, sy) >= self.arrow_min_kpa)
        k = self._arrow_scale
        self.arrows.set_arrows(cc * step, rr * step, sx[rr, cc] * k, sy[rr, cc] * k,
                               head=0.35, min_head=0.08 * step, max_head=0.28 * step)


def _taxel_name(row: int, col: int) -> str:
    """A taxel's name before any sensor gave a layout (the layouts' own rule)."""
    letters = string.ascii_uppercase
    letter = letters[row] if row < 26 else letters[row // 26 - 1] + letters[row % 26]
    return f"{letter}{col + 1}"


__all__ = ["COLOR_SCHEMES", "HeatmapView", "diverging_colormap", "nice_ceil", "strip_colors"]
