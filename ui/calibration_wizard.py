"""The calibration wizard: set up loads, run (equilibrate with a plate or per taxel), fits."""

from __future__ import annotations

from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
    QWizardPage,
)

from tactile_studio.health.calibration import CalibrationSpec, coverage_line, replace_instead
from tactile_studio.health.runner import HealthRun
from tactile_studio.ui.array_picture import SERIES_COLOURS
from tactile_studio.ui.health_run_page import HealthRunPage, HealthWizard
from tactile_studio.ui.wellness_wizard import DeviceSetupPage


class CalibrationSetupPage(DeviceSetupPage):
    def __init__(self, device: str, settings: dict[str, Any]) -> None:
        super().__init__("Calibration: set up", device, settings)
        self.loads = QLineEdit("20,50,100,200,500")
        self.form.addRow("Loads (g, increasing)", self.loads)
        self.taxels = QLineEdit("all")
        self.form.addRow("Taxels", self.taxels)
        self.plate = QCheckBox("Uniform plate over the whole array (equilibration)")
        self.plate.toggled.connect(self._plate_toggled)
        self.form.addRow("", self.plate)
        self.out = QLineEdit("")
        self.out.setPlaceholderText("optional: also write CAL.json here")
        self.form.addRow("Calibration file", self.out)
        hint = QLabel("Each load is placed, left to settle, recorded and lifted; the next "
                      "load waits until the skin has recovered. Give at least 3 loads in "
                      "increasing order. A plate loads every taxel at once.")
        hint.setWordWrap(True)
        self.form.addRow(hint)

    def _plate_toggled(self, on: bool) -> None:
        self.taxels.setEnabled(not on)
        if on and self.loads.text() == "20,50,100,200,500":
            self.loads.setText("1000,2000,5000,10000,20000")

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

    def _make_run(self) -> HealthRun:
        s = self.setup
        return HealthRun(s.device, s.settings, s.spec(), auto=s.auto.isChecked(),
                         out=s.out.text().strip() or None)
