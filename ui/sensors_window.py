"""The Sensors window: every sensor's hours, checks, calibrations and notes over time.

Degradation shows as a trend: each spot's sensitivity (ratio to the sensor's reference)
against hours of use, and the verdict timeline, before it ruins a participant's data.
"""

from __future__ import annotations

from itertools import groupby

import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QComboBox,
    QGridLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.health.history import SensorHistory, covers_text, sensor_history
from tactile_studio.storage.books.logbook import NOTE_KINDS, Logbook, age_text
from tactile_studio.ui.array_picture import SERIES_COLOURS, VERDICT_COLOURS

_VERDICT_Y = {"pass": 0, "warn": 1, "fail": 2}


class SensorsWindow(QWidget):
    """Sensor list on the left; the chosen sensor's history on the right."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Sensors")
        self.sensors = QListWidget()
        self.sensors.currentTextChanged.connect(self.show_sensor)
        self.title = QLabel("")
        self.title.setStyleSheet("font-size: 15pt; font-weight: bold")
        self.facts = QLabel("")
        self.facts.setWordWrap(True)
        self.trend = pg.PlotWidget(background="w")
        self.trend.setTitle("per-spot sensitivity: ratio to each check's reference", color="#333")
        self.trend.setLabel("bottom", "hours of use")
        self.trend.setLabel("left", "ratio to reference")
        self.trend.addLegend(offset=(10, -10))  # bottom left: ratios start near 1
        # what the plots show, for a reader (and the tests): segments of one spot against
        # one reference, where the reference changed, and every check's square
        self.segments: list[tuple[str, str, pg.PlotDataItem]] = []
        self.reference_marks: list[tuple[float, str]] = []
        self.verdict_points: list[tuple[float, float, int]] = []
        self.reference_note = QLabel("")
        self.reference_note.setWordWrap(True)
        self.reference_note.setStyleSheet("color: #555")
        self.timeline = pg.PlotWidget(background="w")
        self.timeline.setTitle("check verdicts", color="#333")
        self.timeline.setLabel("bottom", "hours of use")
        self.timeline.getAxis("left").setTicks([[(0, "pass"), (1, "warn"), (2, "fail")]])
        self.timeline.setYRange(-0.5, 2.8)  # room for the check numbers over "fail"
        self.timeline.setMaximumHeight(170)
        for plot in (self.trend, self.timeline):  # hours as hours: no "(x0.001)" prefix
            plot.getAxis("bottom").enableAutoSIPrefix(False)
        self.calibrations = QTableWidget(0, 5)
        self.calibrations.setHorizontalHeaderLabels(["#", "when", "kind", "taxels",
                                                     "rms % range"])
        self.calibrations.horizontalHeader().setSectionResizeMode(
            QHeaderView.ResizeMode.ResizeToContents)
        self.calibrations.horizontalHeader().setStretchLastSection(True)
        self.calibrations.verticalHeader().setVisible(False)
        self.notes = QListWidget()
        self.note_kind = QComboBox()
        self.note_kind.addItems(NOTE_KINDS)
        self.note_text = QLineEdit()
        self.note_text.setPlaceholderText("repair, replaced, re-covered, anything")
        self.add_note_button = QPushButton("Add note")
        self.add_note_button.clicked.connect(self.add_note)

        right = QWidget()
        grid = QGridLayout(right)
        grid.addWidget(self.title, 0, 0, 1, 2)
        grid.addWidget(self.facts, 1, 0, 1, 2)
        grid.addWidget(self.trend, 2, 0, 1, 2)
        grid.addWidget(self.reference_note, 3, 0, 1, 2)
        grid.addWidget(self.timeline, 4, 0, 1, 2)
        grid.addWidget(QLabel("Calibrations"), 5, 0)
        grid.addWidget(QLabel("Notes"), 5, 1)
        grid.addWidget(self.calibrations, 6, 0)
        grid.addWidget(self.notes, 6, 1)
        note_row = QHBoxLayout()
        note_row.addWidget(self.note_kind)
        note_row.addWidget(self.note_text, 1)
        note_row.addWidget(self.add_note_button)
        grid.addLayout(note_row, 7, 0, 1, 2)
        grid.setRowStretch(2, 3)
        grid.setRowStretch(6, 1)
        split = QSplitter(Qt.Orientation.Horizontal)
        split.addWidget(self.sensors)
        split.addWidget(right)
        split.setSizes([180, 900])
        self.problem = QLabel("")  # a logbook that cannot be read: one line, in red
        self.problem.setStyleSheet("color: #b00020")
        self.problem.setWordWrap(True)
        self.problem.hide()
        box = QVBoxLayout(self)
        box.addWidget(self.problem)
        box.addWidget(split)
        self.resize(1100, 760)
        self.reload()

    def reload(self) -> None:
        current = self.sensors.currentItem().text() if self.sensors.currentItem() else None
        try:
            with Logbook() as book:
                ids = book.sensor_ids()
        except UserError as exc:  # damaged or unreadable: said, never overwritten
            self.show_problem(str(exc))
            ids = []
        self.sensors.clear()
        self.sensors.addItems(ids)
        if ids:
            self.sensors.setCurrentRow(ids.index(current) if current in ids else 0)

    def show_sensor(self, sensor: str) -> None:
        if not sensor:
            return
        try:
            h = sensor_history(sensor)
        except UserError as exc:
            self.show_problem(str(exc))
            return
        s = h.summary
        self.title.setText(sensor)
        last = (f"{s['last_verdict'].upper()} {age_text(s['last_check_at'])}"
                if s["last_verdict"] else "never checked")
        active = next((c for c in h.calibrations if c["active"]), None)
        covers = f" ({active['taxels']} of {active['of']} taxels)" if active and \
            active.get("taxels") is not None else ""
        self.facts.setText(f"{s['hours']:.2f} h of use · last check {last} · active "
                           f"calibration {s['active_calibration'] or 'none'}{covers} · "
                           f"registered {s['created'][:10]}")
        self._draw_trend(h)
        self._draw_verdicts(h)
        # hours of use start at 0 and span at least one hour: a new sensor's few minutes
        # showed as "(x0.001)" with negative ticks
        seen = [float(s["hours"] or 0)] + [float(v) for v, _, _ in h.verdicts]
        seen += [float(v) for hours, _ in h.spot_series.values() for v in hours]
        top = max(1.0, 1.1 * max(seen))
        for plot in (self.trend, self.timeline):  # a little room left of 0 h for marks
            plot.setXRange(-top / 40, top, padding=0)
        self._space_verdicts(top)
        self.calibrations.setRowCount(len(h.calibrations))
        for i, c in enumerate(h.calibrations):
            covers = covers_text(c)
            for j, text in enumerate((f"{c['id']}{' (active)' if c['active'] else ''}",
                                      c["at"][:16].replace("T", " "), c["kind"],
                                      covers.split(" taxels")[0], f"{c['rms_pct']:.2f}")):
                item = QTableWidgetItem(text)
                item.setToolTip(covers)  # which were measured, which kept from where
                self.calibrations.setItem(i, j, item)
        self.notes.clear()
        self.notes.addItems([f"{n['at'][:10]} [{n['kind']}] {n['text']}" for n in h.notes])

    def _draw_trend(self, h: SensorHistory) -> None:
        """Each spot's ratios, one line per stretch against one reference (a calibration
        resets the scale: joining across it drew a calibration as drift); ratios to the
        nominal curve hollow and dashed; a labelled line where the reference changed."""
        self.trend.clear()
        self.segments, self.reference_marks = [], []
        self.trend.addLine(y=1.0, pen=pg.mkPen("#999", style=Qt.PenStyle.DashLine))
        for i, (spot, points) in enumerate(sorted(h.spot_points.items())):
            colour = SERIES_COLOURS[i % len(SERIES_COLOURS)]
            for k, (ref, run) in enumerate(groupby(points, key=lambda p: p.reference)):
                run = list(run)
                nominal = ref == "nominal"
                item = self.trend.plot(
                    [p.hours for p in run], [p.ratio for p in run],
                    pen=pg.mkPen(colour, width=2, style=Qt.PenStyle.DashLine if nominal
                                 else Qt.PenStyle.SolidLine),
                    symbol="o", symbolSize=7, symbolPen=pg.mkPen(colour, width=2),
                    symbolBrush=None if nominal else colour, name=spot if k == 0 else None)
                self.segments.append((spot, ref, item))
        for hours, check_id, words in h.reference_changes:
            # a short label on the line; the words go under the plot (text over the
            # lines hid the data and the legend)
            line = pg.InfiniteLine(pos=hours, angle=90, movable=False,
                                   pen=pg.mkPen("#7a5195", width=1, style=Qt.PenStyle.DotLine),
                                   label=f"#{check_id}", labelOpts={
                                       "position": 0.97, "color": "#7a5195",
                                       "anchors": [(0, 0), (0, 0)]})
            self.trend.addItem(line)
            self.reference_marks.append((hours, words))
        refs = sorted({ref for _, ref, _ in self.segments})
        changes = "; ".join(f"check #{i} at {hours:g} h: {words}"
                            for hours, i, words in h.reference_changes)
        self.reference_note.setText(
            ("Each ratio is against its check's reference (" + ", ".join(
                "the nominal curve: hollow, dashed" if r == "nominal" else r for r in refs)
             + "); a new reference starts a new line"
             + (f". Reference changed (dotted lines): {changes}." if changes else "."))
            if refs else "")

    def _draw_verdicts(self, h: SensorHistory) -> None:
        """A square per check, numbered; checks at the same hours (no recording between)
        sit side by side instead of on top of each other."""
        self.timeline.clear()
        self.verdict_points = []
        for hours, verdict, check_id in h.verdicts:
            self.verdict_points.append((hours, float(_VERDICT_Y[verdict]), check_id))

    def _space_verdicts(self, x_span: float) -> None:
        """Draw the squares, spreading checks closer than a square's width apart."""
        gap = x_span / 35.0
        placed: list[tuple[float, float, int]] = []
        for hours, y, check_id in self.verdict_points:
            x = hours
            while any(abs(x - px) < gap and py == y for px, py, _ in placed):
                x += gap
            placed.append((x, y, check_id))
        self.verdict_points = placed
        by_verdict = {v: k for k, v in _VERDICT_Y.items()}
        for x, y, check_id in placed:
            colour = VERDICT_COLOURS[by_verdict[int(y)]]
            self.timeline.plot([x], [y], pen=None, symbol="s", symbolSize=12,
                               symbolBrush=colour)
            label = pg.TextItem(f"#{check_id}", color="#444", anchor=(0.5, 1.3))
            label.setPos(x, y)
            self.timeline.addItem(label)

    def show_problem(self, text: str | None) -> None:
        """One line above the lists (None hides it)."""
        self.problem.setText(text or "")
        self.problem.setVisible(bool(text))

    def add_note(self) -> None:
        item = self.sensors.currentItem()
        text = self.note_text.text().strip()
        if item is None or not text:
            return
        try:
            with Logbook() as book:
                book.add_note(item.text(), text, self.note_kind.currentText())
        except UserError as exc:
            self.show_problem(str(exc))
            return
        self.note_text.clear()
        self.show_sensor(item.text())
