"""The experimenter console of a collection session.

Setup page (protocol, participant, folder, device, or "Resume session...") then the
session page: the live heatmap with shear arrows, a mirror of the participant screen,
session progress and ETA, the trial log with quality flags, and the experimenter's
buttons. One QTimer drives ``runner.tick()`` and every repaint (never one repaint per
sample). Widgets only present ``runner.snapshot()`` and forward intent to the runner;
opening, resuming and closing the session file is the core's ``open_collection`` /
``resume_collection`` / ``close``, and the device, engine, recorder and LSL outlet belong
to the :class:`~tactile_studio.acquisition.live_acquisition.LiveAcquisition` the console is handed
(it never builds an engine or a recorder itself).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSettings, Qt, QTimer
from PySide6.QtGui import QCloseEvent, QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QCheckBox,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QSplitter,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.acquisition.events import (
    AcquisitionEvent,
    Health,
    RecordingStarted,
    RecordingStopped,
)
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import UserError
from tactile_studio.health.gate import admit, wellness_status
from tactile_studio.live import LiveView
from tactile_studio.live.meters import PaintPacer
from tactile_studio.protocol.background_check import WAIT_S, BackgroundCheck
from tactile_studio.protocol.collect import (
    CollectionSettings,
    OtherSensorRefused,
    can_perform,
    open_collection,
    resume_collection,
)
from tactile_studio.protocol.flag_summary import block_summary
from tactile_studio.protocol.snapshot import RunnerSnapshot
from tactile_studio.protocol.trial_check import TrialChecker
from tactile_studio.protocol.virtual import VirtualParticipant
from tactile_studio.ui.collect.beep import QtBeeper
from tactile_studio.ui.collect.console_actions import ConsoleActions
from tactile_studio.ui.collect.flag_banner import FlagBanner
from tactile_studio.ui.collect.log import TextDialog, TrialLog
from tactile_studio.ui.collect.paint import PILOT
from tactile_studio.ui.collect.participant import ParticipantScreen
from tactile_studio.ui.collect.setup import CollectSetup, SetupChoice
from tactile_studio.ui.collect.view import participant_view, progress_text, state_label
from tactile_studio.ui.heatmap import HeatmapView
from tactile_studio.ui.settings import app_settings

log = logging.getLogger(__name__)
TICK_MS = 15
DISPLAY_HZ = 1000.0 / (2 * TICK_MS)  # heatmap paints at most ~33 Hz (the main window: 60)
ELLIPSIS = "\u2026"
REDO_KEY, KEEP_KEY = "Ctrl+Z", "Ctrl+K"  # a flagged trial: Redo (as "Redo last"), Keep


def _banner(name: str, style: str) -> QLabel:
    """A coloured line that shows only when it has something to say."""
    label = QLabel()
    label.setObjectName(name)
    label.setStyleSheet(style)
    label.hide()
    return label


class CollectConsole(ConsoleActions):
    """Runs one collection session over ``acquisition`` (a new LiveAcquisition if not
    given); ``engine`` is a live engine it may share (the setup's "live device")."""

    def __init__(self, engine: LiveStream | None = None, live_device: str | None = None,
                 settings: QSettings | None = None, beeper: QtBeeper | None = None,
                 clock: Any = None, parent: QWidget | None = None,
                 acquisition: LiveAcquisition | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Tactile Studio \u2014 collection session")
        self.shared_engine = engine
        self.live_device = live_device
        self.acquisition = acquisition if acquisition is not None else LiveAcquisition()
        self.session: Any = None          # the core's collect session (cs)
        self.runner: Any = None
        self.protocol: Any = None
        self.clock = clock
        self.beeper = beeper or QtBeeper(self)
        self.live = LiveView()
        self._ticks = 0
        self.pacer = PaintPacer(DISPLAY_HZ)  # the main window's pacing, at the console's rate
        self._closed_session_path: str | None = None
        self._dialog: TextDialog | None = None
        self.wellness_text = ""  # the sensor's last check, shown beside the file name
        self.virtual: VirtualParticipant | None = None  # performs in a pilot on the simulator
        self.pilot = False  # the open (or last) session is a rehearsal
        self._shown: Any = None  # the LiveFrame last drawn (LiveView caches per frame)

        self.setup = CollectSetup(settings if settings is not None else app_settings(),
                                  live_device=live_device if engine is not None else None)
        self.setup.startRequested.connect(self.start_session)
        self.setup.resumeRequested.connect(self.resume_from)
        self.setup.otherSensorRequested.connect(self.ask_other_sensor_note)
        self.participant = ParticipantScreen()
        self.participant.keyPressed.connect(self.forward_key)
        self.beeper.flash.connect(self._flash)
        self.beeper.played.connect(self._on_beep)
        self.setup.testSoundRequested.connect(self.test_sound)

        self.stack = QStackedWidget()
        self.stack.addWidget(self.setup)
        self.stack.addWidget(self._build_session_page())
        self.setCentralWidget(self.stack)
        self.resize(1500, 900)

        self.timer = QTimer(self)
        self.timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.timer.setInterval(TICK_MS)
        self.timer.timeout.connect(self.tick)
        self.acquisition.add_listener(self._on_acquisition_event)

    # ---- layout -----------------------------------------------------------------------
    def _build_session_page(self) -> QWidget:
        """The live map, its status lines and the buttons on the left; the participant
        screen's mirror above the trial log on the right."""
        mirror_box = self._build_mirror_box()
        self._build_status_lines()
        grid = self._build_buttons()
        log_box = self._build_log_box()
        left = QWidget()
        lv = QVBoxLayout(left)
        lv.setContentsMargins(0, 0, 0, 0)
        lv.addWidget(self.pilot_banner)
        lv.addWidget(self.heatmap, 1)
        for line in (self.state, self.progress, self.progress_label, self.file_label,
                     self.touches_label, self.fault_banner, self.health_banner,
                     self.redo_banner, self.sound_notice, self.hint_label):
            lv.addWidget(line)
        lv.addLayout(grid)
        lv.addWidget(self._build_lsl_toggle())
        right = QSplitter(Qt.Orientation.Vertical)
        right.addWidget(mirror_box)
        right.addWidget(log_box)
        right.setSizes([540, 320])

        page = self.page_splitter = QSplitter(Qt.Orientation.Horizontal)
        page.addWidget(left)
        page.addWidget(right)
        page.setSizes([560, 900])
        outer = QWidget()
        h = QHBoxLayout(outer)
        h.setContentsMargins(6, 6, 6, 6)
        h.addWidget(page)
        return outer

    def _build_mirror_box(self) -> QGroupBox:
        """The live map (made first) and the participant screen's mirror in its box."""
        self.heatmap = HeatmapView()
        self.heatmap.virtualChanged.connect(self._on_virtual)
        self.mirror = ParticipantScreen(mirror=True)
        self.mirror.keyPressed.connect(self.forward_key)
        self.mirror_hint = QLabel()
        self.mirror_hint.setStyleSheet("color: #606770;")
        self.mirror.focusChanged.connect(self._on_mirror_focus)
        self._on_mirror_focus(False)
        mirror_box = QGroupBox("Participant screen (mirror)")
        mb = QVBoxLayout(mirror_box)
        mb.setContentsMargins(6, 6, 6, 6)
        mb.addWidget(self.mirror, 1)  # the box's room goes to the mirror, not around it
        mb.addWidget(self.mirror_hint)
        return mirror_box

    def _build_status_lines(self) -> None:
        """The lines under the map: the banners, state, progress, file and hint."""
        # a rehearsal is said at the top of the page, in the participant screen's colour
        self.pilot_banner = _banner("pilot", f"background: {PILOT.name()}; color: #1b1f2a; "
                                    "border-radius: 6px; padding: 8px;font-weight: 700;")
        self.state = QLabel()
        self.state.setStyleSheet("font-size: 17px; font-weight: 600;")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.progress.setTextVisible(False)
        self.progress_label = QLabel()
        self.file_label = QLabel()
        self.file_label.setStyleSheet("color: #606770;")
        self.file_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.touches_label = QLabel()  # who makes the touches (a simulator never by itself)
        self.touches_label.setStyleSheet("color: #606770;")
        # a flagged trial: its reason, Redo and Keep (keeps its room while hidden)
        self.redo_banner = FlagBanner(REDO_KEY, KEEP_KEY)
        self.redo_banner.redoRequested.connect(self.redo_last)
        self.redo_banner.keepRequested.connect(self.keep_flagged)
        # the recording ended short (write failed, device lost, frames lost): its one line
        self.fault_banner = _banner("recordingFault", "background: #c62828; color: white; "
                                    "border-radius: 6px; padding: 8px;font-weight: 600;")
        # the device went silent while recording (or came back): the recording goes on
        self.health_banner = _banner("streamHealth", "background: #ffe082; color: #4e3b00; "
                                     "border-radius: 6px; padding: 8px;font-weight: 600;")
        # said once: no speaker, the screen flashes instead
        self.sound_notice = _banner("", "background: #fdecea; color: #8a1c12; "
                                    "border-radius: 6px; padding: 6px;")
        self.hint_label = QLabel()
        self.hint_label.setStyleSheet("color: #c0392b;")
        # lines that grow with what they say wrap in the pane's width instead of
        # widening it (the state line pushed the splitter as the prompts changed)
        for label in (self.pilot_banner, self.state, self.progress_label, self.file_label,
                      self.touches_label, self.fault_banner,
                      self.health_banner, self.sound_notice, self.hint_label):
            label.setWordWrap(True)
            label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        # a refusal or "Please redo it" comes and goes with every trial: its two lines
        # stay reserved, so the page does not move under the experimenter's eyes
        self.hint_label.setFixedHeight(2 * self.hint_label.fontMetrics().lineSpacing())
        self.hint_label.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        hint_policy = self.hint_label.sizePolicy()
        hint_policy.setRetainSizeWhenHidden(True)
        self.hint_label.setSizePolicy(hint_policy)

    def _build_buttons(self) -> QGridLayout:
        """The experimenter's buttons in two columns, each with its window shortcut."""
        b = self.buttons = {}
        self.shortcuts: dict[str, QShortcut] = {}
        for name, text, key, slot in (
                ("primary", "Start", "Ctrl+Return", self.primary_action),
                ("redo", "Redo last", REDO_KEY, self.redo_last),
                ("discard", "Discard\u2026", "Ctrl+D", self.ask_discard),
                ("pause", "Pause", "Ctrl+P", self.toggle_pause),
                ("break", "Skip to break", "Ctrl+B", self.skip_to_break),
                ("note", "Note\u2026", "Ctrl+N", self.ask_note),
                ("screen", "Participant screen", "Ctrl+F", self.show_participant_screen),
                ("end", "End session", "", self.end_session)):
            btn = QPushButton(text)
            btn.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # letters and Space are the runner's
            if key:  # a window shortcut, not the button's: setText() would replace that
                self._shortcut(key, btn)
                btn.setToolTip(f"{text.rstrip(ELLIPSIS)} ({key})")
            btn.clicked.connect(slot)
            b[name] = btn
        b["primary"].setStyleSheet("font-weight: 600; padding: 6px 18px;")
        grid = QGridLayout()
        for i, name in enumerate(("primary", "redo", "discard", "pause", "break", "note",
                                  "screen", "end")):
            grid.addWidget(b[name], i // 2, i % 2)
        self._shortcut(KEEP_KEY, self.redo_banner.keep)
        return grid

    def _build_log_box(self) -> QGroupBox:
        """The trial log; at a block's end, a line per gesture with flagged performances."""
        self.log = TrialLog()
        log_box = QGroupBox("Trials")
        lb = QVBoxLayout(log_box)
        lb.setContentsMargins(6, 6, 6, 6)
        lb.addWidget(self.log, 1)
        self.block_summary = _banner("blockSummary", "background: #fff4e0; color: #4e3b00; "
                                     "border-radius: 4px; padding: 4px;")
        self.block_summary.setWordWrap(True)
        self.block_summary.setTextFormat(Qt.TextFormat.PlainText)
        lb.addWidget(self.block_summary)
        self._summary_key: tuple = ()
        return log_box

    def _shortcut(self, key: str, button: QPushButton) -> QShortcut:
        """``key`` clicks ``button`` whenever it is enabled, whatever its label says
        (Start/Continue, Pause/Resume): a button's own shortcut dies with setText()."""
        sc = QShortcut(QKeySequence(key), self)
        sc.setContext(Qt.ShortcutContext.WindowShortcut)
        sc.activated.connect(lambda: button.isEnabled() and button.isVisible()
                             and self.stack.currentIndex() == 1 and button.click())
        self.shortcuts[key] = sc
        return sc

    # ---- opening and closing sessions ---------------------------------------------------
    @property
    def engine(self) -> LiveStream | None:
        """The engine of the open (or last) session."""
        return self.acquisition.engine

    def _engine_for(self, device: str | None, dev_settings: dict[str, Any]) -> LiveStream:
        """Step 1 of the session's start order: the device, opened but not started."""
        if device is None:
            if self.shared_engine is None:
                raise UserError("no live device: choose a device")
            return self.acquisition.share(self.shared_engine, self.live_device)
        return self.acquisition.open(device, dev_settings)

    def start_session(self, choice: SetupChoice, override_note: str | None = None) -> bool:
        """Open a new session from the setup choices; False (message shown) on a user error.

        A protocol requiring a wellness check asks for an override note first when the
        sensor's last check failed, is stale or missing (``self.dialog``)."""
        try:
            status = wellness_status(self._sensor_id(choice), choice.protocol.wellness_required,
                                     choice.protocol.wellness_max_age_h)
        except UserError as exc:
            self.setup.show_error(str(exc))
            return False
        self.wellness_text = status.text()
        if not status.ok and not (override_note or "").strip():
            self.setup.show_error(f"{status.text()}. {status.problem}.")
            dlg = TextDialog("Wellness check needed",
                             f"{status.problem}.\nStart anyway? Override note:", (), self)
            dlg.accepted.connect(lambda: dlg.text().strip()
                                 and self.start_session(choice, dlg.text()))
            self._open_dialog(dlg)
            return False
        health = admit(status, override_note)
        return self._open(lambda: open_collection(CollectionSettings(
            choice.protocol, participant=choice.participant, out_dir=choice.out_dir,
            seed=choice.seed, condition=choice.condition, hold_flagged=choice.hold_flagged,
            auto_continue=choice.auto_continue, wellness=health, pilot=choice.pilot,
            trial_check=self._off_gui(choice.qc.checker(choice.participant)),
            personalise_check=choice.qc.personalise),
            self.acquisition, beeper=self.beeper, clock=self.clock),
            choice.device, choice.device_settings)

    @staticmethod
    def _off_gui(checker: TrialChecker | None) -> BackgroundCheck | None:
        """The model scores each trial on a worker thread, not in the timer's tick: the
        heatmap and the buttons stay live while it thinks (its verdict joins the trial
        at the first tick after)."""
        return None if checker is None else BackgroundCheck(checker)

    def _sensor_id(self, choice: SetupChoice) -> str | None:
        """The sensor of the chosen device (the shared live one when none is chosen)."""
        if choice.device is None:
            return self.shared_engine.sensor_id() if self.shared_engine is not None else None
        return create_device(choice.device, choice.device_settings).sensor_id()

    def resume_from(self, path: str | Path, allow_other_sensor: str | None = None) -> bool:
        """Continue a killed or closed session file at its next trial, on the device the
        form shows; on another sensor than the file's only with ``allow_other_sensor``
        (the note kept in the session, as ``collect --allow-other-sensor``)."""
        self.setup.keep_resume_file(str(path))
        hold, auto = self.setup.run_options()
        try:
            device, dev_settings = self.setup.device_choice()
        except UserError as exc:
            self.setup.show_error(str(exc))
            return False
        return self._open(lambda: resume_collection(
            Path(path), self.acquisition, beeper=self.beeper, clock=self.clock,
            hold_flagged=hold, auto_continue=auto,
            allow_other_sensor=allow_other_sensor,
            protocol_at_hand=self.setup.current_protocol(),
            trial_check=self._off_gui(
                self.setup.qc.choice().checker(self.setup.resume_participant()))),
            device, dev_settings)

    def ask_other_sensor_note(self, path: str) -> TextDialog:
        """"Resume on this other sensor…": why, then the resume on the form's device."""
        why = self.setup.other_sensor_why or "the device is not the file's"
        dlg = TextDialog("Resume on another sensor",
                         f"{why[:1].upper()}{why[1:]}.\nThe session goes on with this "
                         "device's frames after the file's. Why? (kept in the session)",
                         (), self)
        dlg.accepted.connect(lambda: self.resume_from(path, dlg.text()))
        return self._open_dialog(dlg)

    def _open(self, make: Any, device: str | None, dev_settings: dict[str, Any]) -> bool:
        self.close_session()
        try:  # the session's start order: device, recorder (the file), LSL, then start
            self._engine_for(device, dev_settings)
            self.session = make()
        except OtherSensorRefused as exc:  # offered: resume on it, saying why
            self.setup.show_error(f"{exc.path.name}: {exc.why}.")
            self.setup.offer_other_sensor(exc.why)
            self.acquisition.disconnect()
            return False
        except UserError as exc:
            self.setup.show_error(str(exc))
            self.acquisition.disconnect()
            return False
        self.runner = self.session.runner
        self.protocol = self.runner.protocol
        self._start_pilot()
        self._sync_lsl()
        self.acquisition.start()
        self.live.attach(self.engine)
        self.live.virtual = self.heatmap.virtual
        self.heatmap.set_layout(self.engine.layout)
        self.touches_label.setText(self.session.touches)
        path = Path(self.session.path)  # the name, then its folder: wraps between them
        self.file_label.setText(f"File: {path.name}   in {path.parent}"
                                + (f"   ·   {self.wellness_text}" if self.wellness_text else ""))
        self._closed_session_path = None
        if not self.beeper.has_audio:
            self._say_no_sound()
        self.stack.setCurrentIndex(1)
        self.timer.start()
        self.tick()
        return True

    def _start_pilot(self) -> None:
        """A pilot says so (banner, title, the participant screen's frame); on the
        simulated sensor a virtual participant performs what the screen prompts, in real
        time, while the experimenter runs the session as with a person."""
        pilot = self.pilot = bool(self.session.pilot)
        self.virtual = None
        if pilot and can_perform(self.engine):
            self.virtual = VirtualParticipant(self.runner, self.engine.device,
                                              self.session.participant, self.session.seed,
                                              plan_ahead=False)
            self.virtual.prepare()
        who = ("a virtual participant performs what the screen prompts"
               if self.virtual is not None else "you perform the gestures yourself")
        self.pilot_banner.setText(
            f"PILOT \u2013 a rehearsal: {who}. The file is marked pilot "
            f"({self.session.path.name}); datasets, train and info's study leave it out.")
        self.pilot_banner.setVisible(pilot)
        self.setWindowTitle("Tactile Studio \u2014 collection session"
                            + (" \u2014 PILOT" if pilot else ""))

    def close_session(self) -> str | None:
        """Stop the timer and close the file cleanly (finished trials are kept)."""
        self.timer.stop()
        self._stop_lsl()
        path = None
        if self.virtual is not None:  # the simulator is itself again (its own style)
            device = self.virtual.device
            device.set_style(int(device.settings.get("style_seed", 0) or 0))
            self.virtual = None
        if self.session is not None:
            path = str(self.session.path)
            self.runner.take_verdict(wait_s=WAIT_S)  # a verdict on its way joins its trial
            self.session.close()
            if isinstance(self.runner.trial_check, BackgroundCheck):
                self.runner.trial_check.close()
            self.session = None
        self.acquisition.disconnect()  # stops the engine only if it is the session's own
        return path

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 (Qt)
        """Closing mid-session is safe: the file is consistent and can be resumed."""
        self.close_session()
        self.participant.close()
        super().closeEvent(event)

    # ---- the beep -------------------------------------------------------------------------
    def _say_no_sound(self) -> None:
        reason = self.beeper.fallback_reason or "audio output failed"
        self.sound_notice.setText(f"No sound ({reason}): the participant screen flashes "
                                  "white at the end of each trial instead of beeping.")
        self.sound_notice.show()

    def _on_beep(self, request: Any) -> None:
        if request.via == "fallback" and self.sound_notice.isHidden():
            self._say_no_sound()

    def test_sound(self) -> str:
        """The setup's "Test sound": the session's beep now, and what the lab will get."""
        p = self.setup.current_protocol()
        hz, length = (p.beep_hz, p.beep_s) if p is not None else (880.0, 0.2)
        req = self.beeper.beep(hz, length)
        text = (f"Beep played ({hz:g} Hz, {length:g} s). Did you hear it?" if req.via == "audio"
                else f"No sound ({self.beeper.fallback_reason}): the participant screen will "
                     "flash instead of beeping.")
        self.setup.show_sound(text, ok=req.via == "audio")
        return text

    # ---- Lab Streaming Layer (the core streams; this only forwards the toggle) -----------
    def _build_lsl_toggle(self) -> QWidget:
        self._lsl_detach: Any = None
        self.lsl_toggle = QCheckBox("Stream to LSL")
        self.lsl_toggle.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # keys are the runner's
        self.lsl_toggle.setToolTip("Publish the frames and the session's markers (trials, "
                                   "beeps, keys, redo, breaks) on the Lab Streaming Layer")
        self.lsl_toggle.toggled.connect(self._sync_lsl)
        return self.lsl_toggle

    def set_lsl(self, on: bool) -> bool:
        """Switch streaming on or off; False if it could not start (message shown)."""
        self.lsl_toggle.setChecked(on)
        self._sync_lsl()
        return self.lsl_toggle.isChecked() == on

    @property
    def _lsl(self) -> Any:
        """The session's LSL streamer while this console streams (None otherwise)."""
        return self.acquisition.lsl if self._lsl_detach is not None else None

    def _sync_lsl(self, *_: object) -> None:
        want = self.lsl_toggle.isChecked() and self.runner is not None
        acq = self.acquisition
        if not want or (acq.lsl is not None and acq.lsl.engine is not self.engine):
            self._stop_lsl()
        if want and self._lsl_detach is None:
            try:
                acq.set_lsl(True)
            except UserError as exc:
                self.statusBar().showMessage(str(exc))
                self.lsl_toggle.blockSignals(True)
                self.lsl_toggle.setChecked(False)
                self.lsl_toggle.blockSignals(False)
                return
            self._lsl_detach = acq.lsl.attach_runner(self.runner)

    def _stop_lsl(self) -> None:
        detach, self._lsl_detach = self._lsl_detach, None
        if detach is not None:
            detach()
        self.acquisition.set_lsl(False)

    # ---- the timer ----------------------------------------------------------------------
    def _on_acquisition_event(self, event: AcquisitionEvent) -> None:
        """How the recording ended (acquisition/outcome.py): a banner when it is incomplete;
        a device silent while recording, or back (acquisition/stream_health.py): another."""
        match event:
            case RecordingStarted():
                self.fault_banner.hide()
                self.health_banner.hide()
            case Health():  # the all-clear stays: the file has a gap there
                self.health_banner.setText(("\u26a0 " if event.silent else "") + event.message)
                self.health_banner.show()
            case RecordingStopped(message=message) if message:
                self.fault_banner.setText(f"\u26a0 {message}")
                self.fault_banner.show()

    def tick(self) -> None:
        """Advance the runner and present its snapshot (called every TICK_MS)."""
        if self.runner is None:
            return
        cut_off = self.session.end_if_cut_off() if self.session is not None else None
        if cut_off is not None:  # the file cannot be written, or the device ended: the
            # session ends here, and closing it says how the recording ended (outcome)
            self.fault_banner.setText(f"\u26a0 {cut_off}; the session ended, its completed "
                                      f"trials are kept in {self.session.path}")
            self.fault_banner.show()
        self.acquisition.check_health()  # a silent device is said (health_banner)
        self.runner.tick()
        if self.virtual is not None and self.runner.state != "setup":
            self.virtual.step()  # the experimenter starts the session, as with a person
        snap = self.runner.snapshot()
        self._ticks += 1
        view = participant_view(snap, self.protocol)
        view.pilot = self.pilot  # until the next session: the Finished screen too
        self.participant.show_view(view)
        self.mirror.show_view(view)
        self._present(snap)
        now = time.monotonic()
        if self.pacer.delay(now) <= 0:  # else too soon: the next tick looks again
            frame = self.live.latest()
            if frame is not None and frame is not self._shown:
                self.pacer.painted(now)
                self._shown = frame
                self.heatmap.set_frame(frame.normal, frame.shear_x, frame.shear_y, frame.units)
        if snap.state in ("finished", "aborted") and self.session is not None:
            self._closed_session_path = self.close_session()
            self.file_label.setText(f"Saved: {self._closed_session_path}")

    def _present(self, snap: Any) -> None:
        self.state.setText(state_label(snap))
        self.progress.setValue(int(round(1000 * (snap.progress or 0.0))))
        self.progress_label.setText(progress_text(snap))
        self.redo_banner.say(snap.redo_prompt)
        self.hint_label.setText(snap.hint)
        self.hint_label.setVisible(bool(snap.hint))
        self.log.set_trials(snap.trials)
        self._show_block_summary(snap)
        live = snap.state not in ("finished", "aborted")
        b = self.buttons
        if snap.state == "setup":
            b["primary"].setText("Start")
            b["primary"].setEnabled(True)
        else:
            b["primary"].setText("Continue")
            b["primary"].setEnabled(bool(snap.can_continue))
        b["redo"].setEnabled(live and snap.last_trial is not None)
        b["discard"].setEnabled(bool(snap.trials))
        b["pause"].setText("Resume" if snap.state == "paused" else "Pause")
        b["pause"].setEnabled(live and snap.state != "setup")
        b["break"].setEnabled(live and snap.state not in ("setup", "break", "free_play"))
        b["end"].setEnabled(live)

    def _show_block_summary(self, snap: RunnerSnapshot) -> None:
        """After each block (a break, the next block, the end): per gesture, how many of
        its performances so far were flagged and why; rebuilt only when that changes."""
        done = snap.block if (not snap.remaining or snap.state in ("finished", "aborted")) \
            else snap.block - 1
        key = (done, self.log.signature)
        if key == self._summary_key:
            return
        self._summary_key = key
        lines = block_summary(snap.trials, done) if done >= 0 else []
        title = f"After block {done + 1}: "
        self.block_summary.setText(
            (title + ("\n".join(lines) if len(lines) < 2 else "\n" + "\n".join(lines)))
            if lines else (f"{title}no flagged trials" if done >= 0 else ""))
        self.block_summary.setVisible(done >= 0)
