"""The wellness-check wizard: set up, run (rest, then the weight on each spot), verdict."""

from __future__ import annotations

import re
from typing import Any

from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
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

from tactile_studio.devices.registry import create_device
from tactile_studio.errors import UserError
from tactile_studio.health.estimate import estimate_text, simulated_speed
from tactile_studio.health.health_check import HealthCheck
from tactile_studio.health.report import write_report
from tactile_studio.health.wellness import REFERENCE_RULE, WellnessSpec
from tactile_studio.sensor.wellness import DEFAULT_SPOTS
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.ui.array_picture import VERDICT_COLOURS, ArrayPicture
from tactile_studio.ui.file_dialogs import ask_save_file
from tactile_studio.ui.health_run_page import HealthRunPage, HealthWizard
from tactile_studio.ui.write_faults import show_write_fault


def sensor_combo(current: str | None = None) -> QComboBox:
    """An editable list of the logbook's sensors (type a new ID to add one)."""
    box = QComboBox()
    box.setEditable(True)
    try:
        with Logbook() as book:
            box.addItems(book.sensor_ids())
    except UserError as exc:  # damaged: the check itself sets it aside and says so
        box.setToolTip(str(exc))
    if current:
        box.setCurrentText(current)
    return box


class DeviceSetupPage(QWizardPage):
    """Device, sensor, the 'simulated device places the weights' switch and, on the
    simulator, its speed: full speed by default (a wizard opened from the live view
    took its real-time speed: 34 s for a check the CLI does in 3 s). ``estimate`` says
    how long the procedure takes with the choices made (the pages keep it current)."""

    SPEEDS = (("Full speed (seconds)", 0.0), ("Real time, as at the bench", 1.0))

    def __init__(self, title: str, device: str, settings: dict[str, Any]) -> None:
        super().__init__()
        self.setTitle(title)
        self.device, self.settings = device, dict(settings)
        self.simulated = device == "simulated"
        self.form = QFormLayout(self)
        shown = {k: v for k, v in self.settings.items() if not (self.simulated and k == "speed")}
        self.device_label = QLabel(f"{device} " + " ".join(f"{k}={v}" for k, v in shown.items()))
        self.device_label.setWordWrap(True)
        self.form.addRow("Device", self.device_label)
        own = f"sim-{self.settings.get('seed', 0)}" if self.simulated else None
        self.sensor = sensor_combo(own)
        self.form.addRow("Sensor ID", self.sensor)
        self.auto = QCheckBox("The simulated device places the weights itself")
        self.auto.setChecked(self.simulated)
        self.auto.setEnabled(self.simulated)
        self.form.addRow("", self.auto)
        self.speed = QComboBox()
        for label, value in self.SPEEDS:
            self.speed.addItem(label, value)
        live = simulated_speed(self.settings)
        if live not in [v for _, v in self.SPEEDS]:
            self.speed.addItem(f"As the live view (speed {live:g})", live)
        self.speed.setToolTip("The simulator's speed for this procedure only (the live "
                              "view keeps its own)")
        self.speed.currentIndexChanged.connect(lambda _: self.update_estimate())
        if self.simulated:
            self.form.addRow("Simulator speed", self.speed)
        self.estimate = QLabel("")
        self.estimate.setWordWrap(True)
        self.estimate.setStyleSheet("font-weight: bold")
        try:  # "all" taxels in the estimates (nothing is opened: the run page does that)
            self.n_taxels = create_device(device, self.settings).layout.n_taxels
        except Exception:  # noqa: BLE001 - a prefill; the run page reports real errors
            self.n_taxels = 36

    @property
    def full_speed(self) -> bool:
        return self.simulated and float(self.speed.currentData()) <= 0

    def run_settings(self) -> dict[str, Any]:
        """The device settings the procedure opens its device with."""
        if not self.simulated:
            return dict(self.settings)
        return {**self.settings, "speed": float(self.speed.currentData())}

    def estimate_for(self, kind: str, n_placements: int) -> str:
        busy = self.simulated and self.settings.get("gesture", "auto") != "idle"
        return estimate_text(kind, n_placements, self.simulated, self.full_speed, busy)

    def update_estimate(self) -> None:
        """Subclasses: say in ``estimate`` how long the procedure takes."""


class WellnessSetupPage(DeviceSetupPage):
    def __init__(self, device: str, settings: dict[str, Any]) -> None:
        super().__init__("Wellness check: set up", device, settings)
        self.weight = QDoubleSpinBox()
        self.weight.setRange(1, 20000)
        self.weight.setValue(200)
        self.weight.setSuffix(" g")
        self.form.addRow("Known weight", self.weight)
        self.spots = QLineEdit(",".join(DEFAULT_SPOTS))
        self.form.addRow("Spots", self.spots)
        hint = QLabel("A 14 x 14 mm weight centred on each spot in turn. The check first "
                      "reads the unloaded sensor for 3 s, then asks for the weight on each "
                      "spot, waits for it to settle, records and asks you to lift it. "
                      f"Ratios are judged {REFERENCE_RULE}.")
        hint.setWordWrap(True)
        self.form.addRow(hint)
        self.form.addRow("Takes", self.estimate)
        self.spots.textChanged.connect(lambda _: self.update_estimate())
        self.update_estimate()

    def update_estimate(self) -> None:
        spots = [s for s in self.spots.text().split(",") if s.strip()]
        n = self.n_taxels if [s.strip().lower() for s in spots] == ["all"] else len(spots)
        self.estimate.setText(f"{n} spot{'s' if n != 1 else ''} after a 3 s rest: "
                              + self.estimate_for("spot", max(n, 1)))

    def spec(self) -> WellnessSpec:
        spots = tuple(s.strip() for s in self.spots.text().split(",") if s.strip())
        return WellnessSpec(self.sensor.currentText().strip(), self.weight.value(), spots)


class WellnessResultPage(QWizardPage):
    """The verdict, per-spot table and reasons; can save the HTML report."""

    def __init__(self, run_page: HealthRunPage) -> None:
        super().__init__()
        self.setTitle("Wellness check: result")
        self.run_page = run_page
        self.verdict = QLabel("")
        self.picture = ArrayPicture()
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["spot", "normal kPa", "shear kPa",
                                              "ratio", "verdict"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.verticalHeader().setVisible(False)
        self.reasons = QLabel("")
        self.reasons.setWordWrap(True)
        self.save = QPushButton("Save report…")
        self.save.clicked.connect(self.save_report)
        top = QHBoxLayout()
        top.addWidget(self.picture, 1)
        top.addWidget(self.table, 2)
        box = QVBoxLayout(self)
        box.addWidget(self.verdict)
        box.addLayout(top, 1)
        box.addWidget(self.reasons)
        box.addWidget(self.save)

    @property
    def result(self) -> dict[str, Any]:
        return self.run_page.run.result  # type: ignore[union-attr]

    def initializePage(self) -> None:  # noqa: N802 - Qt name
        res = self.result
        v = res["verdict"]
        self.verdict.setText(f"{res['sensor']}: {v.upper()}   (check #{res['check_id']})")
        self.verdict.setStyleSheet(f"font-size: 18pt; font-weight: bold; "
                                   f"color: {VERDICT_COLOURS[v]}")
        self.picture.mark(verdicts={s["taxel"]: s["verdict"] for s in res["spots"]})
        self.table.setRowCount(len(res["spots"]))
        for i, s in enumerate(res["spots"]):
            ratio = "-" if s["ratio"] is None else f"{s['ratio'] * 100:.0f}%"
            for j, text in enumerate((s["taxel"], f"{s['normal_kpa']:.2f}",
                                      f"{s['shear_kpa']:.2f}", ratio, s["verdict"])):
                self.table.setItem(i, j, QTableWidgetItem(text))
        ch = res["channels"]
        lines = [f"• {r}" for r in res["reasons"]] or ["• every spot and channel is healthy"]
        if res.get("tested"):  # a pass speaks only for the taxels loaded
            lines.insert(0, f"{res['tested']['line']}; ratios against "
                            f"{res.get('judged_against') or 'the reference'}")
        lines.append("channels: " + "; ".join(f"{k}: {', '.join(map(str, v)) or 'none'}"
                                             for k, v in ch.items()))
        self.reasons.setText("\n".join(lines))

    def save_report(self, path: str | None = None) -> str | None:
        if path is None:
            sensor = re.sub(r"[^\w.-]+", "_", str(self.result["sensor"]))
            name = f"wellness-{sensor}-{self.result['check_id']}.html"
            path = ask_save_file(self, "Save report", "report", name, "HTML (*.html)")
        if not path:
            return None
        try:
            write_report(path, f"Wellness check #{self.result['check_id']} of "
                               f"{self.result['sensor']}", self.result)
        except (OSError, UserError) as exc:
            if show_write_fault(self, "Report not saved", exc) is None:
                raise
            return None
        return path


class WellnessWizard(HealthWizard):
    """Set up → run → result, on its own connection to ``device``."""

    def __init__(self, device: str = "simulated", settings: dict[str, Any] | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__("Wellness check", WellnessSetupPage(device, settings or {}),
                         WellnessResultPage, (720, 620), parent)

    def _make_run(self) -> HealthCheck:
        s = self.setup
        return HealthCheck(s.device, s.run_settings(), s.spec(), auto=s.auto.isChecked())
