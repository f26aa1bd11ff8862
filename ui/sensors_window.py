"""The Sensors window: every sensor's hours, checks, calibrations and notes over time.

Degradation shows as a trend: each spot's sensitivity (ratio to the sensor's reference)
against hours of use, and the verdict timeline, before it ruins a participant's data.
"""

from __future__ import annotations

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
from tactile_studio.health.history import covers_text, sensor_history
from tactile_studio.storage.logbook import NOTE_KINDS, Logbook, age_text
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
        self.trend.setTitle("per-spot sensitivity (ratio to reference)", color="#333")
        self.trend.setLabel("bottom", "hours of use")
        self.trend.setLabel("left", "ratio")
        self.trend.addLegend(offset=(10, -10))  # bottom left: ratios start near 1
        self.timeline = pg.PlotWidget(background="w")
        self.timeline.setTitle("check verdicts", color="#333")
        self.timeline.setLabel("bottom", "hours of use")
        self.timeline.getAxis("left").setTicks([[(0, "pass"), (1, "warn"), (2, "fail")]])
        self.timeline.setYRange(-0.5, 2.5)
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
        grid.addWidget(self.timeline, 3, 0, 1, 2)
        grid.addWidget(QLabel("Calibrations"), 4, 0)
        grid.addWidget(QLabel("Notes"), 4, 1)
        grid.addWidget(self.calibrations, 5, 0)
        grid.addWidget(self.notes, 5, 1)
        note_row = QHBoxLayout()
        note_row.addWidget(self.note_kind)
        note_row.addWidget(self.note_text, 1)
        note_row.addWidget(self.add_note_button)
        grid.addLayout(note_row, 6, 0, 1, 2)
        grid.setRowStretch(2, 3)
        grid.setRowStretch(5, 1)
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
        self.trend.clear()
        self.trend.addLine(y=1.0, pen=pg.mkPen("#999", style=Qt.PenStyle.DashLine))
        for i, (spot, (hours, ratios)) in enumerate(sorted(h.spot_series.items())):
            colour = SERIES_COLOURS[i % len(SERIES_COLOURS)]
            self.trend.plot(hours, ratios, pen=pg.mkPen(colour, width=2), symbol="o",
                            symbolSize=7, symbolBrush=colour, name=spot)
        self.timeline.clear()
        for hours, verdict, _ in h.verdicts:
            self.timeline.plot([hours], [_VERDICT_Y[verdict]], pen=None, symbol="s",
                               symbolSize=12, symbolBrush=VERDICT_COLOURS[verdict])
        # hours of use start at 0 and span at least one hour: a new sensor's few minutes
        # showed as "(x0.001)" with negative ticks
        seen = [float(s["hours"] or 0)] + [float(v) for v, _, _ in h.verdicts]
        seen += [float(v) for hours, _ in h.spot_series.values() for v in hours]
        top = max(1.0, 1.1 * max(seen))
        for plot in (self.trend, self.timeline):
            plot.setXRange(0.0, top, padding=0)
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
