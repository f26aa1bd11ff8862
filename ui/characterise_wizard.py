"""The characterisation wizard: instruments → plan → run (live plot, pause, abort) → report.

It only presents tactile_studio.characterise: the run happens in a worker thread through
``run_characterisation``; points, progress and the result come back as Qt signals.
"""

from __future__ import annotations

import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import pyqtgraph as pg
from PySide6.QtCore import QObject, Qt, QUrl, Signal
from PySide6.QtGui import QDesktopServices, QPixmap, QResizeEvent
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWizard,
    QWizardPage,
)

from tactile_studio.characterise import CharacterisationRequest, RunControl, run_characterisation
from tactile_studio.characterise.folder import describe_run
from tactile_studio.characterise.plan import Plan, plan_text
from tactile_studio.characterise.prepare import (
    plan_fields,
    plugin_names,
    prepare,
    settings_from_text,
)
from tactile_studio.characterise.procedure import check_sensor_request, save_calibration
from tactile_studio.characterise.report import TABLE_KEYS, column_title, format_value
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.paths import data_dir
from tactile_studio.sensor.characterise import parse_taxels
from tactile_studio.sensor.layout import get_layout
from tactile_studio.ui.settings import app_settings
from tactile_studio.ui.write_faults import fault_text

PAPER_TAXELS = "B2,B5,E2,E5,A1,C4"
KEY_PARENT = "characterise/parent_dir"  # where the last run folder was made


def default_out_dir(sensor: str = "") -> Path:
    """A new run folder, named by sensor and time, in the folder the last run went to
    (first time: ``characterisation`` under the app's data folder, not the home folder)."""
    parent = str(app_settings().value(KEY_PARENT) or "") or str(data_dir() / "characterisation")
    return Path(parent) / f"{sensor or 'run'}-{time.strftime('%Y%m%d-%H%M')}"


def _device_sensor_id(device: str, settings: str) -> str:
    """The sensor ID the chosen device reports without opening it ("" if none)."""
    try:
        return create_device(device, settings_from_text(settings)).sensor_id() or ""
    except Exception:  # noqa: BLE001 - a prefill only; the plan page reports real errors
        return ""


class _Bridge(QObject):
    """Worker thread → GUI thread (queued signals)."""

    point = Signal(str, object)
    progress = Signal(float, str)
    done = Signal(object, str)  # result dict or None, error text ("" when fine)


class SetupPage(QWizardPage):
    def __init__(self, out_dir: str | None, sensor_id: str = "") -> None:
        super().__init__()
        self.setTitle("Instruments")
        self.setSubTitle("The sensor, the stage carrying the indenter, and the load cell.")
        names = plugin_names()
        form = QFormLayout(self)
        self.combos: dict[str, QComboBox] = {}
        self.sets: dict[str, QLineEdit] = {}
        defaults = {"device": "speed=0 gesture=idle"}
        for kind in ("device", "stage", "force"):
            combo = QComboBox()
            combo.addItems(names[kind])
            combo.setCurrentText("simulated")
            edit = QLineEdit(defaults.get(kind, ""))
            edit.setPlaceholderText("key=value key=value")
            self.combos[kind], self.sets[kind] = combo, edit
            form.addRow(f"{kind.capitalize()}:", combo)
            form.addRow(f"{kind.capitalize()} settings:", edit)
        sensor_id = sensor_id or _device_sensor_id("simulated", defaults["device"])
        self.sensor = QLineEdit(sensor_id)
        self.sensor.setPlaceholderText("sensor id for the report (optional)")
        self.out = QLineEdit(out_dir or str(default_out_dir(sensor_id)))
        form.addRow("Sensor id:", self.sensor)
        form.addRow("Output folder:", self.out)
        self.error = QLabel()
        self.error.setStyleSheet("color: #b00020")
        self.error.setWordWrap(True)
        form.addRow(self.error)

    def validatePage(self) -> bool:
        if not self.wizard().confirm_out_dir():
            return False
        app_settings().setValue(KEY_PARENT, str(self.out_dir().expanduser().resolve().parent))
        return True

    def instruments(self) -> list[str]:
        """Plugin name and settings text of the device, stage and load cell, in order."""
        return [t for kind in ("device", "stage", "force")
                for t in (self.combos[kind].currentText(), self.sets[kind].text())]

    def sensor_id(self) -> str | None:
        return self.sensor.text().strip() or None

    def out_dir(self) -> Path:
        return Path(self.out.text().strip() or "characterisation")


class PlanPage(QWizardPage):
    def __init__(self) -> None:
        super().__init__()
        self.setTitle("Plan")
        self.setSubTitle("The paper's sequences and defaults; edit any value.")
        lay = QVBoxLayout(self)
        form = QFormLayout()
        self.taxels = QLineEdit(PAPER_TAXELS)
        form.addRow("Taxels (names or 'all'):", self.taxels)
        lay.addLayout(form)
        rows = plan_fields()
        self.table = QTableWidget(len(rows), 2)
        self.table.setHorizontalHeaderLabels(["parameter", "value"])
        self.table.verticalHeader().hide()
        self.table.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        for i, (name, value) in enumerate(rows):
            item = QTableWidgetItem(name)
            item.setFlags(item.flags() & ~Qt.ItemIsEditable)
            self.table.setItem(i, 0, item)
            self.table.setItem(i, 1, QTableWidgetItem(value))
        lay.addWidget(self.table)
        cycles = dict(rows)["cycles"]
        note = QLabel(f"The paper's 'repeat' sequence ({int(cycles):,} cycles, about 11 h of "
                      "stage time per taxel) is left out: add it to sequences, with the "
                      "cycles you want, for a repeatability run.")
        note.setWordWrap(True)
        note.setStyleSheet("color: #606770;")
        lay.addWidget(note)
        # what the plan does and how long it takes, kept current as it is edited
        self.estimate = QLabel()
        self.estimate.setWordWrap(True)
        self.estimate.setStyleSheet("font-weight: bold")
        lay.addWidget(self.estimate)
        self.layout_for_count = None  # the device's layout, for 'all' (set when shown)
        self.taxels.textChanged.connect(lambda _: self.update_estimate())
        self.table.itemChanged.connect(lambda _: self.update_estimate())
        self.save_calibration = QCheckBox(
            "Save the calibration to the sensor's logbook (it becomes the active one)")
        self.save_calibration.setToolTip("The CLI's --save-calibration; needs a sensor id")
        lay.addWidget(self.save_calibration)
        self.error = QLabel()
        self.error.setStyleSheet("color: #b00020")
        self.error.setWordWrap(True)
        lay.addWidget(self.error)

    def initializePage(self) -> None:  # noqa: N802 - Qt name
        try:
            device, settings = self.wizard().setup.instruments()[:2]
            self.layout_for_count = create_device(device, settings_from_text(settings)).layout
        except Exception:  # noqa: BLE001 - a prefill; validatePage reports real errors
            self.layout_for_count = None
        self.update_estimate()

    def update_estimate(self) -> None:
        """The plan in one line with its stage time (what the CLI prints as it starts)."""
        try:
            plan = Plan.with_overrides(self.params())
            layout = self.layout_for_count or get_layout("shearsense-6x6")
            n = len(parse_taxels(layout, self.taxels_text()))
        except (UserError, ValueError) as exc:
            self.estimate.setText(f"Takes: (not yet: {exc})")
            return
        self.estimate.setText(f"Takes: {plan_text(plan, n)}")

    def set_param(self, name: str, value: str) -> None:
        for i in range(self.table.rowCount()):
            if self.table.item(i, 0).text() == name:
                self.table.item(i, 1).setText(value)
                return
        raise KeyError(name)

    def taxels_text(self) -> str:
        return self.taxels.text()

    def params(self) -> dict[str, str]:
        defaults = dict(plan_fields())
        out = {}
        for i in range(self.table.rowCount()):
            name, value = self.table.item(i, 0).text(), self.table.item(i, 1).text().strip()
            if value != defaults[name]:
                out[name] = value
        return out

    def validatePage(self) -> bool:
        wiz: CharacteriseWizard = self.wizard()
        if self.save_calibration.isChecked() and not wiz.setup.sensor_id():
            self.error.setText("Saving the calibration needs a sensor id (the logbook files "
                               "it there): enter one on the Instruments page")
            return False
        try:
            wiz.prepared = wiz.prepare_run()
            check_sensor_request(wiz.setup.sensor_id(), wiz.prepared.plan,
                                 self.save_calibration.isChecked())
        except UserError as exc:
            self.error.setText(str(exc))
            return False
        self.error.clear()
        return True


class RunPage(QWizardPage):
    def __init__(self) -> None:
        super().__init__()
        self.setTitle("Run")
        self.setSubTitle("Sensor against load cell at every step. Pause waits for the end of "
                         "the taxel; abort lifts the indenter first.")
        lay = QVBoxLayout(self)
        # normal (tens of kPa) and shear (a few kPa either way) each on its own axes: on
        # one plot the shear points were a smudge at the normal axis's origin
        plots = QHBoxLayout()
        self.plot = pg.PlotWidget(background="w", title="Normal")
        self.plot.setLabel("bottom", "load cell normal stress (kPa)")
        self.plot.setLabel("left", "sensor normal (relative change)")
        self.shear_plot = pg.PlotWidget(background="w", title="Shear (along the drag)")
        self.shear_plot.setLabel("bottom", "load cell shear stress (kPa)")
        self.shear_plot.setLabel("left", "sensor shear (relative change)")
        self.normal = self.plot.plot([], [], pen=None, symbol="o", symbolSize=6,
                                     symbolBrush="#1f77b4", name="normal")
        self.shear = self.shear_plot.plot([], [], pen=None, symbol="t", symbolSize=6,
                                          symbolBrush="#2ca02c", name="shear (along the drag)")
        for plot in (self.plot, self.shear_plot):  # relative changes as they are, no "(x0.001)"
            plot.getAxis("left").enableAutoSIPrefix(False)
        plots.addWidget(self.plot, 1)
        plots.addWidget(self.shear_plot, 1)
        lay.addLayout(plots, 1)
        self.status = QLabel("Ready")
        self.bar = QProgressBar()
        self.bar.setRange(0, 1000)
        lay.addWidget(self.status)
        lay.addWidget(self.bar)
        row = QHBoxLayout()
        self.pause = QPushButton("Pause")
        self.resume = QPushButton("Resume")
        self.abort = QPushButton("Abort")
        self.resume.setEnabled(False)
        for b in (self.pause, self.resume, self.abort):
            row.addWidget(b)
        row.addStretch(1)
        lay.addLayout(row)
        self.finished_run = False
        self._xy: dict[str, tuple[list[float], list[float]]] = {"n": ([], []), "s": ([], [])}

    def add_point(self, taxel: str, p: dict[str, Any]) -> None:
        if p.get("sequence") == "normal":
            key, x, y = "n", p["pz"], p["normal"]
        else:
            axis = "x" if "x" in p.get("direction", "x") else "y"
            key, x, y = "s", p["p" + axis], p["shear_" + axis]
        xs, ys = self._xy[key]
        xs.append(x)
        ys.append(y)
        (self.normal if key == "n" else self.shear).setData(xs, ys)

    def isComplete(self) -> bool:
        return self.finished_run


class FittedPicture(QLabel):
    """A picture scaled to the space it is given (aspect kept): the all-taxel maps grow
    with the window (they were scaled once to 900 px and left half the page empty)."""

    def __init__(self) -> None:
        super().__init__()
        self.setAlignment(Qt.AlignCenter)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.setMinimumSize(240, 120)
        self._picture = QPixmap()

    def set_picture(self, picture: QPixmap) -> None:
        self._picture = picture
        self._fit()

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 - Qt name
        super().resizeEvent(event)
        self._fit()

    def _fit(self) -> None:
        if self._picture.isNull():
            self.clear()
            return
        self.setPixmap(self._picture.scaled(self.size(), Qt.KeepAspectRatio,
                                            Qt.SmoothTransformation))


def header_text(key: str, width: int = 11) -> str:
    """A column title wrapped to a few short lines, the unit on its own: the columns stay
    as narrow as their numbers, so the table fits the page without scrolling sideways."""
    title = column_title(key)
    unit = ""
    if title.endswith(")") and " (" in title:
        title, unit = title[:-1].rsplit(" (", 1)
    lines = textwrap.wrap(title, width, break_long_words=False)
    lines += textwrap.wrap(f"({unit})", width, break_long_words=False) if unit else []
    return "\n".join(lines)


class ReportPage(QWizardPage):
    """The run's summary with buttons to the files, the per-taxel table (as tall as its
    rows, never wider than the page), and below it the all-taxel maps beside the page of
    the taxel chosen in the table, both filling the rest of the page."""

    def __init__(self) -> None:
        super().__init__()
        self.setTitle("Report")
        lay = QVBoxLayout(self)
        top = QHBoxLayout()
        self.summary = QLabel()
        self.summary.setWordWrap(True)
        self.summary.setTextInteractionFlags(Qt.TextSelectableByMouse)
        top.addWidget(self.summary, 1)
        self.open_report = QPushButton("Open report.html")
        self.open_report.setToolTip("The full report (every taxel's figures) in the browser")
        self.open_folder = QPushButton("Open folder")
        for b in (self.open_report, self.open_folder):
            b.setEnabled(False)
            top.addWidget(b, 0, Qt.AlignTop)
        self.open_report.clicked.connect(lambda: self._open("report.html"))
        self.open_folder.clicked.connect(lambda: self._open(""))
        lay.addLayout(top)
        self.table = QTableWidget(0, len(TABLE_KEYS) + 1)
        self.table.setHorizontalHeaderLabels(["Taxel", *[header_text(k) for k in TABLE_KEYS]])
        self.table.verticalHeader().hide()
        header = self.table.horizontalHeader()
        small = header.font()
        small.setPointSizeF(small.pointSizeF() * 0.85)
        small.setBold(False)
        header.setFont(small)
        header.setSectionResizeMode(QHeaderView.ResizeMode.Interactive)
        header.setMinimumSectionSize(36)
        self.table.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
        self.table.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        lay.addWidget(self.table)
        self.maps, self.taxel_page = FittedPicture(), FittedPicture()
        self.taxel_title = QLabel("")
        self.taxel_title.setAlignment(Qt.AlignCenter)
        side = QVBoxLayout()
        side.addWidget(self.taxel_title)
        side.addWidget(self.taxel_page, 1)
        pictures = QHBoxLayout()
        pictures.addWidget(self.maps, 55)
        pictures.addLayout(side, 45)
        lay.addLayout(pictures, 1)
        self.table.itemSelectionChanged.connect(self._show_taxel)
        self.out: Path | None = None

    def _show_taxel(self) -> None:
        """The chosen row's page: its staircase and drags, fits and neighbours."""
        rows = self.table.selectionModel().selectedRows() if self.table.selectionModel() else []
        row = rows[0].row() if rows else 0
        item = self.table.item(row, 0)
        if item is None or self.out is None:
            return
        page = self.out / "figures" / f"{item.text()}.png"
        self.taxel_title.setText(f"{item.text()} (choose a row for another taxel)")
        self.taxel_page.set_picture(QPixmap(str(page)) if page.exists() else QPixmap())

    def _open(self, name: str) -> bool:
        if self.out is None:
            return False
        return QDesktopServices.openUrl(QUrl.fromLocalFile(str(self.out / name)))

    def _fit_columns(self) -> None:
        """Each column as wide as its header or numbers, the room left shared out: the
        table is exactly as wide as the page (it scrolled sideways before)."""
        t = self.table
        t.resizeColumnsToContents()
        widths = [t.columnWidth(c) for c in range(t.columnCount())]
        free = t.viewport().width() - sum(widths)
        if free > 0:
            for c, w in enumerate(widths):
                t.setColumnWidth(c, w + free // len(widths))

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 - Qt name
        super().resizeEvent(event)
        self._fit_columns()

    def _fit_table_height(self, max_rows: int = 12) -> None:
        """As tall as its rows (up to ``max_rows``, then it scrolls): no empty grey box."""
        t = self.table
        rows = min(t.rowCount(), max_rows)
        height = t.horizontalHeader().height() + 2 * t.frameWidth()
        height += sum(t.rowHeight(r) for r in range(rows))
        t.setFixedHeight(height + 2)

    def show_result(self, result: dict[str, Any] | None, error: str, out: Path) -> None:
        taxels = (result or {}).get("taxels", {})
        self.out = out
        state = "complete" if result and result.get("complete") else f"stopped: {error}"
        self.summary.setText(f"Run {state}. {len(taxels)} taxel(s) characterised. Files in "
                             f"{out}: characterisation.json, calibration.json, session.h5, "
                             "report.html, figures/.")
        self.open_report.setEnabled((out / "report.html").exists())
        self.open_folder.setEnabled(out.is_dir())
        self.table.setRowCount(len(taxels))
        for r, (name, m) in enumerate(taxels.items()):
            self.table.setItem(r, 0, QTableWidgetItem(name))
            for c, key in enumerate(TABLE_KEYS, start=1):
                item = QTableWidgetItem(format_value(key, m.get(key)))
                item.setTextAlignment(Qt.AlignRight | Qt.AlignVCenter)
                self.table.setItem(r, c, item)
        self.table.resizeRowsToContents()
        self._fit_columns()
        self._fit_table_height()
        self.table.setSelectionBehavior(QTableWidget.SelectRows)
        if taxels:
            self.table.selectRow(0)
        self._show_taxel()
        maps = out / "figures" / "maps.png"
        if maps.exists():
            self.maps.set_picture(QPixmap(str(maps)))


class CharacteriseWizard(QWizard):
    """Instruments → plan → run → report, on the core's characterisation API."""

    def __init__(self, out_dir: str | None = None, parent=None,  # noqa: ANN001
                 sensor_id: str = "") -> None:
        super().__init__(parent)
        self.setWindowTitle("Characterise taxels")
        self.setOption(QWizard.NoBackButtonOnLastPage, True)
        self.setup, self.plan_page = SetupPage(out_dir, sensor_id), PlanPage()
        self._auto_out = "" if out_dir else self.setup.out.text()
        self.setup.sensor.textEdited.connect(self._name_folder)
        self.saved_calibration: int | None = None
        self.run_page, self.report = RunPage(), ReportPage()
        for page in (self.setup, self.plan_page, self.run_page, self.report):
            self.addPage(page)
        self.prepared = None
        self.overwrite = False  # the user agreed to replace the run the folder holds
        self.control = RunControl()
        self.result: dict[str, Any] | None = None
        self.error = ""
        self._bridge = _Bridge()
        self._bridge.point.connect(self.run_page.add_point)
        self._bridge.progress.connect(self._on_progress)
        self._bridge.done.connect(self._on_done)
        self.run_page.pause.clicked.connect(self._pause)
        self.run_page.resume.clicked.connect(self._resume)
        self.run_page.abort.clicked.connect(self.control.cancel)
        self.currentIdChanged.connect(self._page_changed)
        self._thread: threading.Thread | None = None

    @property
    def out_dir(self) -> Path:
        return self.setup.out_dir()

    def _name_folder(self, sensor: str) -> None:
        """A folder the wizard named follows the sensor id typed (one typed by hand stays)."""
        if self.setup.out.text() == self._auto_out:
            self._auto_out = str(Path(self._auto_out).parent / default_out_dir(sensor.strip()).name)
            self.setup.out.setText(self._auto_out)

    def confirm_out_dir(self) -> bool:
        """True when the output folder can take the run: it holds none, or the user
        answered Yes to replacing the one it holds (asked in a message box)."""
        out, error = self.out_dir, self.setup.error
        error.clear()
        if out.exists() and not out.is_dir():
            error.setText(f"{out} exists and is not a folder")
            return False
        held = describe_run(out)
        self.overwrite = False
        if held is None:
            return True
        box = QMessageBox(QMessageBox.Icon.Question, "Replace the earlier run?",
                          f"{out} holds {held}.\n\nReplace it? Its session.h5, results, "
                          "raw/ and figures/ are deleted before the new run starts.",
                          QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No, self)
        box.setDefaultButton(QMessageBox.StandardButton.No)
        self.overwrite = box.exec() == QMessageBox.StandardButton.Yes
        if not self.overwrite:
            error.setText(f"{out} holds {held}: choose another folder")
        return self.overwrite

    def prepare_run(self):  # noqa: ANN201
        return prepare(*self.setup.instruments(), self.plan_page.taxels_text(),
                       self.plan_page.params())

    def _page_changed(self, page_id: int) -> None:
        if self.page(page_id) is self.run_page and self._thread is None:
            self._start()
        if self.page(page_id) is self.report:
            self.report.show_result(self.result, self.error, self.out_dir)
            if self.saved_calibration is not None:
                self.report.summary.setText(
                    f"{self.report.summary.text()} Calibration #{self.saved_calibration} of "
                    f"{self.setup.sensor_id()} saved to the logbook (active).")

    def _start(self) -> None:
        p, bridge, out = self.prepared, self._bridge, self.out_dir
        sensor, overwrite = self.setup.sensor_id(), self.overwrite

        def work() -> None:
            result, error = None, ""
            try:
                result = run_characterisation(
                    p.device, p.stage, p.force,
                    CharacterisationRequest(p.plan, p.taxels, out, sensor_id=sensor,
                                            overwrite=overwrite),
                    progress=lambda f, m: bridge.progress.emit(f, m), control=self.control,
                    on_point=lambda name, pt: bridge.point.emit(name, pt))
            except (UserError, Cancelled) as exc:
                error = str(exc) or "aborted"
            except Exception as exc:  # the folder cannot be written: one line; a bug keeps
                error = fault_text(exc) or f"{type(exc).__name__}: {exc}"  # its traceback
                if fault_text(exc) is None:
                    raise
            finally:  # either way the run page ends
                bridge.done.emit(result, error)
        self.button(QWizard.BackButton).setEnabled(False)
        self._thread = threading.Thread(target=work, name="characterise", daemon=True)
        self._thread.start()

    def _on_progress(self, fraction: float, message: str) -> None:
        self.run_page.bar.setValue(int(fraction * 1000))
        self.run_page.status.setText(message)

    def _on_done(self, result: dict[str, Any] | None, error: str) -> None:
        import json

        if result is None:
            path = self.out_dir / "characterisation.json"
            result = json.loads(path.read_text()) if path.exists() else None
        self.result, self.error = result, error
        if result is not None and not error and self.plan_page.save_calibration.isChecked():
            self._save_calibration()
        page = self.run_page
        page.finished_run = True
        page.status.setText("Finished" if not error else f"Stopped: {error}")
        for b in (page.pause, page.resume, page.abort):
            b.setEnabled(False)
        page.completeChanged.emit()

    def _save_calibration(self) -> None:
        """The CLI's --save-calibration: calibration.json into the logbook, active."""
        import json

        sensor = self.setup.sensor_id() or ""
        try:
            cal = json.loads((self.out_dir / "calibration.json").read_text())
            self.saved_calibration = save_calibration(sensor, cal)
        except (UserError, OSError, ValueError) as exc:
            self.error = f"calibration not saved: {exc}"

    def _pause(self) -> None:
        self.control.pause()
        self.run_page.pause.setEnabled(False)
        self.run_page.resume.setEnabled(True)
        self.run_page.status.setText("Pausing after this taxel…")

    def _resume(self) -> None:
        self.control.resume()
        self.run_page.pause.setEnabled(True)
        self.run_page.resume.setEnabled(False)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()
