"""The calibration wizard: set up loads, run (equilibrate with a plate or per taxel), fits."""

from __future__ import annotations

from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import (
    QButtonGroup,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QRadioButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
    QWizardPage,
)

from tactile_studio.health.calibration import CalibrationSpec, coverage_line, replace_instead
from tactile_studio.health.health_check import HealthCheck
from tactile_studio.sensor.calibration import spread_line
from tactile_studio.ui.array_picture import SERIES_COLOURS
from tactile_studio.ui.health_run_page import HealthRunPage, HealthWizard
from tactile_studio.ui.wellness_wizard import DeviceSetupPage

PLATE_LOADS, TAXEL_LOADS = "1000,2000,5000,10000,20000", "20,50,100,200,500"


class CalibrationSetupPage(DeviceSetupPage):
    """Plate first, by default (equilibrate, then calibrate, as Tekscan's flow does: the
    README's new-sensor recipe); a weight on each taxel is the other choice. Each
    choice says how long it takes (per taxel on all 36: 180 placements, most of an
    hour; it used to be the default, without a word)."""

    def __init__(self, device: str, settings: dict[str, Any]) -> None:
        super().__init__("Calibration: set up", device, settings)
        self.plate = QRadioButton("Plate over the whole array: equilibrate, then calibrate "
                                  "every taxel at once")
        self.per_taxel = QRadioButton("A weight on each taxel in turn")
        self.plate_estimate, self.taxel_estimate = QLabel(""), QLabel("")
        self.method = QButtonGroup(self)
        for b, words in ((self.plate, self.plate_estimate),
                         (self.per_taxel, self.taxel_estimate)):
            self.method.addButton(b)
            words.setWordWrap(True)
            words.setStyleSheet("color: #555; margin-left: 22px")
            box = QVBoxLayout()
            box.setSpacing(0)
            box.addWidget(b)
            box.addWidget(words)
            self.form.addRow("Method" if b is self.plate else "", box)
        self.plate.setChecked(True)
        self.loads = QLineEdit(PLATE_LOADS)
        self.form.addRow("Loads (g, increasing)", self.loads)
        self.taxels = QLineEdit("all")
        self.taxels.setEnabled(False)
        self.form.addRow("Taxels", self.taxels)
        self.out = QLineEdit("")
        self.out.setPlaceholderText("optional: also write CAL.json here")
        self.form.addRow("Calibration file", self.out)
        hint = QLabel("Plate: a uniform plate over the whole array evens out the taxels' "
                      "gains (equilibration) and calibrates all of them at once. Each load "
                      "is placed, left to settle, recorded and lifted; the next load waits "
                      "until the skin has recovered. Give at least 3 loads in increasing "
                      "order.")
        hint.setWordWrap(True)
        self.form.addRow(hint)
        self.form.addRow("Takes", self.estimate)
        self.plate.toggled.connect(self._plate_toggled)
        for edit in (self.loads, self.taxels):
            edit.textChanged.connect(lambda _: self.update_estimate())
        self.update_estimate()

    def _plate_toggled(self, on: bool) -> None:
        self.taxels.setEnabled(not on)
        if self.loads.text() in (PLATE_LOADS, TAXEL_LOADS):  # not one the user typed
            self.loads.setText(PLATE_LOADS if on else TAXEL_LOADS)
        self.update_estimate()

    def _n_taxels(self) -> int:
        text = self.taxels.text().strip()
        if text.lower() in ("", "all"):
            return self.n_taxels
        return len([t for t in text.split(",") if t.strip()])

    def update_estimate(self) -> None:
        loads = max(1, len([v for v in self.loads.text().split(",") if v.strip()]))
        nl = len([v for v in PLATE_LOADS.split(",")])
        plate_loads = loads if self.plate.isChecked() else nl
        taxel_loads = loads if self.per_taxel.isChecked() else nl
        n = self._n_taxels() if self.per_taxel.isChecked() else self.n_taxels
        self.plate_estimate.setText(f"{plate_loads} placements, all {self.n_taxels} taxels "
                                    "under each: " + self.estimate_for("plate", plate_loads))
        self.taxel_estimate.setText(f"{n} taxel{'s' if n != 1 else ''} x {taxel_loads} "
                                    f"loads = {n * taxel_loads} placements: "
                                    + self.estimate_for("taxel", n * taxel_loads))
        chosen = self.plate_estimate if self.plate.isChecked() else self.taxel_estimate
        self.estimate.setText(chosen.text().split(": ", 1)[1])

    def spec(self) -> CalibrationSpec:
        try:
            loads = tuple(float(v) for v in self.loads.text().split(",") if v.strip())
        except ValueError:
            loads = ()
        text = self.taxels.text().strip()
        taxels = None if text.lower() in ("", "all") or self.plate.isChecked() else tuple(
            t.strip() for t in text.split(",") if t.strip())
        return CalibrationSpec(self.sensor.currentText().strip(), loads, taxels,
                               self.plate.isChecked())


class CalibrationResultPage(QWizardPage):
    """Per-taxel model, sensitivity, gain and rms; residuals against load."""

    def __init__(self, run_page: HealthRunPage) -> None:
        super().__init__()
        self.setTitle("Calibration: result")
        self.run_page = run_page
        self.summary = QLabel("")
        self.summary.setStyleSheet("font-size: 13pt; font-weight: bold")
        self.summary.setWordWrap(True)
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["taxel", "model", "sensitivity", "gain",
                                              "rms %"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.verticalHeader().setVisible(False)
        self.plot = pg.PlotWidget(background="w")
        self.plot.setLabel("bottom", "applied load (kPa)")
        self.plot.setLabel("left", "residual (kPa)")
        self.plot.setTitle("residuals after calibration", color="#333")
        self.plot.setMinimumHeight(200)
        self.plot.getAxis("left").enableAutoSIPrefix(False)
        row = QHBoxLayout()
        row.addWidget(self.table, 1)
        row.addWidget(self.plot, 1)
        self.coverage = QLabel("")
        self.coverage.setWordWrap(True)
        # a partial calibration merged with the active one; replacing is the user's choice
        self.replace = QPushButton("Replace the earlier calibration instead")
        self.replace.setToolTip("Keep only the taxels measured now: the others then read "
                                "with the nominal curve")
        self.replace.clicked.connect(self.replace_instead)
        choice = QHBoxLayout()
        choice.addWidget(self.coverage, 1)
        choice.addWidget(self.replace)
        box = QVBoxLayout(self)
        box.addWidget(self.summary)
        box.addLayout(choice)
        box.addLayout(row, 1)

    @property
    def result(self) -> dict[str, Any]:
        return self.run_page.run.result  # type: ignore[union-attr]

    def replace_instead(self) -> None:
        """Cut the merged calibration back to the taxels measured now (same version)."""
        run = self.run_page.run
        run.result = replace_instead(run.result, run.out)  # type: ignore[union-attr]
        self.initializePage()

    def initializePage(self) -> None:  # noqa: N802 - Qt name
        cal = self.result
        merged = bool(cal.get("coverage", {}).get("kept"))
        self.coverage.setText(coverage_line(cal, "merged by default; the button on the "
                                                 "right replaces instead"))
        self.replace.setVisible(merged)
        self.summary.setText(
            f"Calibration #{cal['calibration_id']} of {cal['sensor']} ({cal['kind']}): "
            f"rms error median {cal['rms_pct_median']:.2f}%, worst {cal['rms_pct_max']:.2f}% "
            "of range. It is now the sensor's active calibration.")
        if spread_line(cal):  # how much the taxels differ, measured: under the headline
            self.coverage.setText(f"{spread_line(cal)}\n{self.coverage.text()}")
        skipped = cal.get("skipped", [])
        fits = [f for f in cal["fits"] if f.get("from_calibration") is None]  # measured now
        if skipped:
            self.summary.setText(self.summary.text() + "\nNot calibrated: " + "; ".join(
                s["reason"] for s in skipped))
        self.table.setRowCount(len(fits) + len(skipped))
        rows = [(f["taxel"], f["model"], f"{f['sensitivity']:.3f}",
                 f"{cal['gains'][f['taxel']]:.3f}", f"{f['rms_pct']:.2f}") for f in fits]
        rows += [(s["taxel"], "not calibrated", "-", "-", "-") for s in skipped]
        for i, row in enumerate(rows):
            for j, text in enumerate(row):
                self.table.setItem(i, j, QTableWidgetItem(text))
        self.plot.clear()
        self.plot.addLine(y=0, pen=pg.mkPen("#999"))
        for i, f in enumerate(fits):
            colour = SERIES_COLOURS[i % len(SERIES_COLOURS)]
            self.plot.plot(np.array(f["loads_kpa"]), np.array(f["residuals_kpa"]),
                           pen=pg.mkPen(colour, width=1), symbol="o", symbolSize=5,
                           symbolBrush=colour)


class CalibrationWizard(HealthWizard):
    """Set up → run → result, on its own connection to ``device``."""

    def __init__(self, device: str = "simulated", settings: dict[str, Any] | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__("Calibration", CalibrationSetupPage(device, settings or {}),
                         CalibrationResultPage, (820, 640), parent)

    def _make_run(self) -> HealthCheck:
        s = self.setup
        return HealthCheck(s.device, s.run_settings(), s.spec(), auto=s.auto.isChecked(),
                           out=s.out.text().strip() or None)
