"""The live main window: heatmap in the middle, device panel and strip chart in docks.

A fast poll timer looks for a new frame every few milliseconds and a
:class:`PaintPacer` draws it at once, or when a display period (1/display_hz) has passed
since the last paint — never one repaint per sample, so a 1 kHz device costs the GUI no
more than a 60 Hz one, and a 43 Hz frame waits milliseconds, not a display period.
Between a paint and the next one the pacer allows, polling pauses (one timer instead of
several wake-ups of the GUI thread). The strip chart is redrawn with a new frame (at most
every STRIP_INTERVAL_S), so the chart and the map are painted in one repaint pass.
Device-to-paint latency is measured when the heatmap has actually painted.
"""

from __future__ import annotations

import math
import time
from typing import Any

from PySide6.QtCore import QByteArray, QEventLoop, Qt, QTimer
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence, QShowEvent
from PySide6.QtWidgets import QDockWidget, QMainWindow, QScrollArea, QWidget

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.devices.registry import DEFAULT_DEVICE
from tactile_studio.errors import UserError
from tactile_studio.live import (
    LatencyMeter,
    LiveFrame,
    LiveView,
    RateMeter,
    parse_taxel_name,
)
from tactile_studio.live.meters import PaintPacer
from tactile_studio.ui.device_panel import DevicePanel
from tactile_studio.ui.heatmap import COLOR_SCHEMES, HeatmapView, strip_colors
from tactile_studio.ui.settings import app_settings, get_json, set_json, style_sheet
from tactile_studio.ui.status import LiveStatusBar
from tactile_studio.ui.stripchart import StripChart

DEFAULT_STRIP_TAXELS = [(2, 2), (3, 3)]
MAX_STRIP_TAXELS = 10
STRIP_INTERVAL_S = 0.04  # the strip chart redraws at most 25 times a second
POLL_MS = 4  # how often the display looks for a new frame (a look costs microseconds)


class MainWindow(QMainWindow):
    """Tactile Studio's live view.

    ``device``/``settings`` preselect a plugin (settings as ``--set`` text); with
    ``connect`` it connects at once. Without ``device`` the last used device and its
    settings are restored (not connected). ``persist=False`` neither reads nor writes
    QSettings (snapshots, benchmarks).
    """

    def __init__(self, device: str | None = None, settings: dict[str, Any] | None = None,
                 connect: bool = False, persist: bool = True, display_hz: float = 60.0,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("MainWindow")
        self.setWindowTitle("Tactile Studio")
        self.setStyleSheet(style_sheet())
        self.persist = persist
        # stopping a recording must not freeze the window: compressed on a worker thread
        self.acquisition = LiveAcquisition(compress_in_background=True)
        self.live = LiveView()
        self.fps = RateMeter(1.0)
        self.latency = LatencyMeter(keep=600)
        self.pacer = PaintPacer(display_hz)
        self._paced = QTimer(self)  # a frame that came too soon after the last paint
        self._paced.setTimerType(Qt.TimerType.PreciseTimer)
        self._paced.setSingleShot(True)
        self._paced.timeout.connect(self.tick)
        self._polling = False  # True while the poll timer runs (from set-up to shutdown)
        self._shown: LiveFrame | None = None
        self._held = False  # a picture being taken: the shown frame stays (hold_frame)
        self._painted_index = -1
        self._hover = (-1, -1)
        self._tick_count = 0
        self._strip_drawn = 0.0
        self.strip_taxels: list[tuple[int, int]] = list(DEFAULT_STRIP_TAXELS)

        self.heatmap = HeatmapView()
        self.setCentralWidget(self.heatmap)
        self.panel = DevicePanel(self.acquisition)
        self.strip = StripChart(seconds=self.live.history_s)
        self.status = LiveStatusBar()
        self.setStatusBar(self.status)
        self.status.follow(self.acquisition)  # a device gone silent while recording
        self.device_dock = self._dock("Device", "deviceDock", self._scrolled(self.panel),
                                      Qt.DockWidgetArea.LeftDockWidgetArea)
        self.strip_dock = self._dock("Strip chart", "stripDock", self.strip,
                                     Qt.DockWidgetArea.BottomDockWidgetArea)
        self.setCorner(Qt.Corner.BottomLeftCorner, Qt.DockWidgetArea.LeftDockWidgetArea)
        self._build_menu()
        self.resize(1280, 800)
        self.resizeDocks([self.device_dock], [300], Qt.Orientation.Horizontal)
        self.resizeDocks([self.strip_dock], [230], Qt.Orientation.Vertical)

        self.heatmap.virtualChanged.connect(self.set_virtual)
        self.heatmap.cellHovered.connect(self._on_hover)
        self.heatmap.cellClicked.connect(self._on_click)
        self.heatmap.painted.connect(self._on_painted)
        self.panel.engineChanged.connect(self._on_engine_changed)
        self.panel.deviceChosen.connect(self._on_device_chosen)
        self.strip.clearRequested.connect(lambda: self.set_strip_taxels([]))
        self.strip.quantityChanged.connect(lambda _q: self._draw_strip(time.monotonic()))

        if persist:
            self.restore_settings(device)
        if device is not None or not persist:
            name = device or DEFAULT_DEVICE
            saved = self._saved_device_values(name) if persist else {}
            self.panel.set_device(name, {**saved, **(settings or {})})
        self._mark_strip_taxels()

        self.paint_timer = QTimer(self)  # polls for new frames
        self.paint_timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.paint_timer.setInterval(POLL_MS)
        self.paint_timer.timeout.connect(self.tick)
        self._polling = True
        self.paint_timer.start()
        self.status_timer = QTimer(self)
        self.status_timer.setInterval(250)
        self.status_timer.timeout.connect(self.refresh_status)
        self.status_timer.start()
        self.refresh_status()
        if connect:
            self.panel.connect_device()

    # ---- construction helpers ------------------------------------------------------
    def _dock(self, title: str, name: str, widget: QWidget,
              area: Qt.DockWidgetArea) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        dock.setWidget(widget)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QDockWidget.DockWidgetFeature.DockWidgetFloatable
                         | QDockWidget.DockWidgetFeature.DockWidgetClosable)
        self.addDockWidget(area, dock)
        return dock

    @staticmethod
    def _scrolled(widget: QWidget) -> QScrollArea:
        area = QScrollArea()
        area.setWidget(widget)
        area.setWidgetResizable(True)
        area.setFrameShape(QScrollArea.Shape.NoFrame)
        return area

    def _build_menu(self) -> None:
        file_menu = self.menuBar().addMenu("&File")
        record = QAction("&Record…", self)
        record.setShortcut(QKeySequence("Ctrl+R"))
        record.triggered.connect(self.panel.toggle_recording)
        file_menu.addAction(record)
        tare = QAction("&Tare", self)
        tare.setShortcut(QKeySequence("Ctrl+T"))
        tare.triggered.connect(self.panel.tare)
        file_menu.addAction(tare)
        # collection sessions (ui/collect/app.py): the console shares the live engine
        from tactile_studio.ui.collect.app import add_collection_menu
        add_collection_menu(self, file_menu,
                            lambda: (self.acquisition.engine, self.acquisition.device_name))
        from tactile_studio.ui.remote_control import add_remote_control  # off by default
        self.remote_control = add_remote_control(self, file_menu)
        file_menu.addSeparator()
        quit_action = QAction("&Quit", self)
        quit_action.setShortcut(QKeySequence.StandardKey.Quit)
        quit_action.triggered.connect(self.close)
        file_menu.addAction(quit_action)
        self._build_sensor_menu()
        view_menu = self.menuBar().addMenu("&View")
        virtual = QAction("&Virtual 11×11 grid", self, checkable=True)
        virtual.setShortcut(QKeySequence("Ctrl+G"))
        virtual.toggled.connect(self.set_virtual)
        self.heatmap.virtualChanged.connect(virtual.setChecked)
        self.virtual_action = virtual
        view_menu.addAction(virtual)
        view_menu.addSeparator()
        view_menu.addAction(self.device_dock.toggleViewAction())
        view_menu.addAction(self.strip_dock.toggleViewAction())
        from tactile_studio.ui.research.menu import add_research_menu  # ui/research/
        add_research_menu(self, view_menu, file_menu)

    def _build_sensor_menu(self) -> None:
        menu = self.menuBar().addMenu("&Sensors")
        for text, slot in (("Sensors and history…", self.open_sensors),
                           ("Wellness check…", lambda: self.open_health("wellness")),
                           ("Calibrate…", lambda: self.open_health("calibration")),
                           ("Characterise taxels (stage + load cell)…",
                            self.open_characterisation)):
            action = QAction(text, self)
            action.triggered.connect(slot)
            menu.addAction(action)

    def open_sensors(self) -> QWidget:
        from tactile_studio.ui.sensors_window import SensorsWindow
        self._sensors = SensorsWindow()
        self._sensors.show()
        return self._sensors

    def open_health(self, kind: str) -> QWidget:
        """A wizard on its own connection to the panel's device (the live one is
        disconnected first: a serial port has one owner)."""
        from tactile_studio.ui.calibration_wizard import CalibrationWizard
        from tactile_studio.ui.wellness_wizard import WellnessWizard
        was_live = self._lend_device()
        cls = WellnessWizard if kind == "wellness" else CalibrationWizard
        self._wizard = cls(self.panel.device_name() or DEFAULT_DEVICE, self.panel.values(),
                           parent=self)
        self._return_device_after(self._wizard, was_live)
        self._wizard.show()
        return self._wizard

    def _lend_device(self) -> bool:
        """Disconnect the live view for a wizard (a serial port has one owner); True if
        it was live, so the wizard's end connects it again."""
        if self.acquisition.engine is not None and self.acquisition.engine.running:
            self.panel.disconnect_device()
            self.heatmap.set_readout_text(
                "Disconnected while a wizard uses the device; it reconnects when the "
                "wizard closes.")
            return True
        return False

    def _return_device_after(self, wizard: QWidget, was_live: bool) -> None:
        """When ``wizard`` closes, leave the live view as the wizard found it."""
        def back(*_: object) -> None:
            if was_live and not (self.acquisition.engine and self.acquisition.engine.running):
                self.panel.connect_device()
            self._update_readout()
        wizard.finished.connect(back)

    def open_characterisation(self) -> QWidget:
        """The characterisation wizard; it opens its own device, stage and load cell (the
        live device is disconnected first, as for the health wizards)."""
        from tactile_studio.ui.characterise_wizard import CharacteriseWizard
        sensor = self.panel.sensor_box.currentText().strip()
        if not sensor and self.acquisition.engine is not None:
            sensor = self.acquisition.engine.sensor_id() or ""
        was_live = self._lend_device()
        self._wizard = CharacteriseWizard(sensor_id=sensor)
        self._return_device_after(self._wizard, was_live)
        self._wizard.resize(1000, 760)
        self._wizard.show()
        return self._wizard

    # ---- display loop --------------------------------------------------------------
    def tick(self) -> None:
        """Draw the newest frame if there is one we have not drawn (poll timer)."""
        self._tick_count += 1
        if self._held:
            return
        now = time.monotonic()
        wait = self.pacer.delay(now)
        if wait > 0:  # too soon after the last paint: look again then, decode nothing now
            self._poll_after(wait)
        else:
            if self._polling and not self.paint_timer.isActive():
                self.paint_timer.start()
            frame = self.live.latest()
            if frame is None:
                if self._shown is not None:
                    self._shown = None
                    self.heatmap.clear()
                    self._draw_strip(now)
                return
            if frame is not self._shown:
                self.pacer.painted(now)
                self._poll_after(self.pacer.delay(now))
                self._shown = frame
                self.heatmap.set_frame(frame.normal, frame.shear_x, frame.shear_y,
                                       frame.units)
                self._update_readout()
                # with a new frame only, so the chart is painted in the heatmap's repaint
                # pass rather than in one of its own
                if now - self._strip_drawn >= STRIP_INTERVAL_S:
                    self._draw_strip(now)

    def hold_frame(self, frame: LiveFrame) -> None:
        """Paint ``frame`` and keep it shown: a snapshot pictures this touch, and any paint
        before the grab would draw a newer frame (a gap after the touch, under load)."""
        self._held = True
        self._shown = frame
        self.heatmap.set_frame(frame.normal, frame.shear_x, frame.shear_y, frame.units)
        self._update_readout()

    def _poll_after(self, wait: float) -> None:
        """No polling until the pacer allows the next paint: one timer then, and polling
        again from there (each poll wakes the GUI thread, ~75 us even when it finds
        nothing; a 43 Hz frame cannot be painted sooner anyway)."""
        if wait > 0 and self._polling:
            self.paint_timer.stop()
            if not self._paced.isActive():
                self._paced.start(max(1, math.ceil(wait * 1000)))

    def _draw_strip(self, now: float) -> None:
        if self.strip_dock.isVisible():
            self._strip_drawn = now
            self.strip.set_history(self.live.history(self.strip_taxels,
                                                     self.strip.quantity()))

    def _on_painted(self) -> None:
        frame = self._shown
        if frame is not None and frame.index != self._painted_index:
            self._painted_index = frame.index
            self.fps.tick()
            self.latency.record(frame.host_time)

    def display_fps(self) -> float:
        return self.fps.rate()

    def refresh_status(self) -> None:
        self.acquisition.poll()  # the session stops a recording whose stream ended
        st = self.acquisition.status()
        self.panel.refresh(st)
        med = self.latency.percentile(50, last=60)
        self.status.update_status(st, self.display_fps(), None if med is None else med * 1e3)

    # ---- user intent -----------------------------------------------------------------
    def set_virtual(self, on: bool) -> None:
        """Show the physical (False) or virtual (True) grid."""
        if self.heatmap.virtual != on:
            self.heatmap.set_virtual(on)
        self.live.virtual = on
        self.virtual_action.setChecked(on)
        self._shown = None
        self.tick()

    def hover_taxel(self, name: str) -> None:
        """Show the readout of a named taxel ("C3") as if the pointer rested on it."""
        lay = self.live.layout
        if lay is None:
            raise UserError("connect a device first")
        row, col = parse_taxel_name(lay, name)
        if self.live.virtual:
            row, col = 2 * row, 2 * col
        self.heatmap.hover_cell(row, col)

    def _on_hover(self, row: int, col: int) -> None:
        self._hover = (row, col)
        self._update_readout()

    def _update_readout(self) -> None:
        row, col = self._hover
        if row < 0 or self.live.layout is None:
            frame = self._shown
            hint = "Hover over a taxel for its readout; click it to chart it."
            if self.live.layout is None:  # not a stale "Taking the baseline..."
                hint = "Not connected: choose a device and Connect."
            elif frame is not None and frame.provisional_baseline:
                hint = "Taking the baseline: keep hands off the sensor…"
            self.heatmap.set_readout_text(hint)
            return
        readout = self.live.readout(row, col)
        self.heatmap.set_readout_text(readout.text() if readout else "")

    def _on_click(self, row: int, col: int) -> None:
        if self.live.layout is None:
            return
        taxel = self.live.nearest_taxel(row, col)
        taxels = list(self.strip_taxels)
        if taxel in taxels:
            taxels.remove(taxel)
        elif len(taxels) < MAX_STRIP_TAXELS:
            taxels.append(taxel)
        self.set_strip_taxels(taxels)

    def set_strip_taxels(self, taxels: list[tuple[int, int]]) -> None:
        """Chart these physical (row, col) taxels."""
        self.strip_taxels = [(int(r), int(c)) for r, c in taxels]
        self._mark_strip_taxels()
        self._draw_strip(time.monotonic())  # now, even if no new frame comes

    def _mark_strip_taxels(self) -> None:
        self.heatmap.set_marked_cells(self.strip_taxels, strip_colors(len(self.strip_taxels)))

    def _on_device_chosen(self, *_: object) -> None:
        """Fill the form with what was last used for the newly chosen device."""
        name = self.panel.device_name()
        if self.persist and name:
            self.panel.set_device(name, self._saved_device_values(name))

    def _on_engine_changed(self) -> None:
        engine = self.acquisition.engine
        self.live.attach(engine if engine is not None and engine.running else None)
        lay = self.live.layout
        self.heatmap.set_layout(lay)
        if lay is not None:
            self.strip_taxels = [(r, c) for r, c in self.strip_taxels
                                 if r < lay.rows and c < lay.cols]
            self._mark_strip_taxels()
        self._shown = None
        self._painted_index = -1
        self._update_readout()
        self.latency.clear()
        if self.persist and self.acquisition.device_name:
            self.save_device_settings()
        self.refresh_status()

    # ---- persistence ---------------------------------------------------------------
    def _saved_device_values(self, name: str) -> dict[str, Any]:
        values = get_json(app_settings(), f"device/values/{name}", {})
        return values if isinstance(values, dict) else {}

    def save_device_settings(self) -> None:
        s = app_settings()
        name = self.panel.device_name()
        if name and self.panel.is_valid():  # never save values that cannot connect
            s.setValue("device/name", name)
            set_json(s, f"device/values/{name}", self.panel.values())

    def save_settings(self) -> None:
        """Window geometry, dock layout, view options, device and its settings."""
        if not self.persist:
            return
        s = app_settings()
        s.setValue("window/geometry", self.saveGeometry())
        if not self.device_panel_squeezed():  # a squeezed layout is not one to come back to
            s.setValue("window/state", self.saveState())
        set_json(s, "view/virtual", self.heatmap.virtual)
        set_json(s, "view/fixed_max", self.heatmap.fixed_max)
        set_json(s, "view/arrow_scale", self.heatmap.arrow_scale)
        set_json(s, "view/colors", self.heatmap.color_scheme)
        set_json(s, "strip/taxels", self.strip_taxels)
        set_json(s, "strip/quantity", self.strip.quantity())
        self.save_device_settings()
        s.sync()

    def device_panel_squeezed(self) -> bool:
        """True when the docked device panel is narrower than its form needs (values
        truncated, Disconnect and Record cut off)."""
        dock = self.device_dock
        if dock.isHidden() or dock.isFloating():  # (isHidden: also while the window closes)
            return False
        return dock.width() < min(DEVICE_PANEL_MIN_WIDTH, dock.widget().sizeHint().width())

    def unsqueeze_device_panel(self) -> None:
        """Give the device panel its width back (from the map, never from a dock)."""
        if self.device_panel_squeezed():
            self.resizeDocks([self.device_dock], [300], Qt.Orientation.Horizontal)

    def restore_settings(self, device: str | None = None) -> None:
        s = app_settings()
        geometry = s.value("window/geometry")
        if isinstance(geometry, QByteArray | bytes):
            self.restoreGeometry(geometry)
        state = s.value("window/state")
        if isinstance(state, QByteArray | bytes):
            self.restoreState(state)
        self.set_virtual(bool(get_json(s, "view/virtual", False)))
        fixed = get_json(s, "view/fixed_max", self.heatmap.fixed_max)
        self.heatmap.set_range(float(fixed) if fixed is not None else None)
        self.heatmap.set_arrow_scale(float(get_json(s, "view/arrow_scale",
                                                    self.heatmap.arrow_scale)))
        scheme = get_json(s, "view/colors", self.heatmap.color_scheme)
        if scheme in COLOR_SCHEMES:
            self.heatmap.set_color_scheme(scheme)
        taxels = get_json(s, "strip/taxels", None)
        if isinstance(taxels, list):
            self.strip_taxels = [(int(r), int(c)) for r, c in taxels][:MAX_STRIP_TAXELS]
        self.strip.set_quantity(str(get_json(s, "strip/quantity", "normal")))
        if device is None:
            name = str(s.value("device/name", "") or DEFAULT_DEVICE)
            if not self.panel.set_device(name, self._saved_device_values(name)):
                self.panel.set_device(DEFAULT_DEVICE, self._saved_device_values(DEFAULT_DEVICE))

    def showEvent(self, event: QShowEvent) -> None:  # noqa: N802 - Qt name
        """Once laid out, a restored layout that squeezes the device panel is undone (a
        dock layout restored before the first show can come up squeezed)."""
        super().showEvent(event)
        QTimer.singleShot(0, self.unsqueeze_device_panel)

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 - Qt name
        self.shutdown()
        super().closeEvent(event)

    def shutdown(self) -> None:
        """Save preferences, finish any recording and stop the device (idempotent)."""
        self._polling = False
        self.paint_timer.stop()
        self._paced.stop()
        self.status_timer.stop()
        if self.persist:
            self.save_settings()
        self.remote_control.close()
        self.acquisition.disconnect()  # finishes a recording first (the stop order)


DEVICE_PANEL_MIN_WIDTH = 260  # below this the device form is cut off


def wait_for(seconds: float) -> None:
    """Run the Qt event loop for ``seconds`` (snapshots and benchmarks)."""
    loop = QEventLoop()
    QTimer.singleShot(max(0, round(seconds * 1000)), loop.quit)
    loop.exec()
