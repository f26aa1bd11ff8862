"""The session player: any .h5 in the heatmap with shear arrows, a timeline of trials,
play at any speed, step, jump to a trial, loop it, and a run's prediction over time."""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.playback import PlayClock, SessionPlayback, flag_filters, session_history
from tactile_studio.playback.chart import ChartWindow
from tactile_studio.storage.format.session_check import check_file, verdict_text
from tactile_studio.ui.heatmap import HeatmapView, strip_colors
from tactile_studio.ui.research.timeline import Timeline
from tactile_studio.ui.stripchart import StripChart

SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
CHECKED = "clocks, trials, events, metadata and counters agree"
VALID_STYLE = "color: #1b7a1b; font-weight: bold"
INVALID_STYLE = "color: #b00000; font-weight: bold"


class SessionPlayer(QWidget):
    error = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.pb: SessionPlayback | None = None
        self.clock: PlayClock | None = None
        self.window = ChartWindow()  # the strip chart's stretch of the session
        self.run_path: str | None = None
        self.heatmap = HeatmapView()
        self.strip = StripChart()
        self.strip.setMinimumHeight(170)
        self.strip.setMaximumHeight(220)
        self.heatmap.setMinimumHeight(320)
        self.taxels: list[tuple[int, int]] = []
        self.timeline = Timeline()
        self.play_button = QPushButton("Play")
        self.back_button, self.next_button = QPushButton("◀ frame"), QPushButton("frame ▶")
        self.speed = QComboBox()
        self.speed.addItems([f"{s:g}×" for s in SPEEDS])
        self.speed.setCurrentIndex(SPEEDS.index(1.0))
        self.trial_box = QComboBox()
        self.trial_box.setMinimumContentsLength(22)
        # which trials the list offers: all, the flagged ones, or one flag's
        self.flag_filter = QComboBox()
        self.flag_filter.setToolTip("list only the flagged trials (quality flags and the "
                                    "model's check), or those of one flag")
        self.loop = QCheckBox("Loop trial")
        self.position = QLabel("no session")
        self.prediction = QLabel("")
        # the file's validity (tactile-studio check), said before anyone trusts what plays
        self.validity = QLabel("")
        self.validity.setWordWrap(True)
        self.check_button = QPushButton("Check file")
        self.check_button.setToolTip("check the file again (as tactile-studio check): "
                                     + CHECKED)
        self.check_button.setEnabled(False)
        # every violation, one a line, folded away until asked for (the map keeps its room)
        self.show_problems = QPushButton("Show problems")
        self.show_problems.setCheckable(True)
        self.show_problems.hide()
        self.problems = QListWidget()
        self.problems.setMaximumHeight(76)  # four lines, then it scrolls
        self.problems.hide()
        head = QHBoxLayout()
        head.addWidget(self.validity, 1)
        head.addWidget(self.show_problems)
        head.addWidget(self.check_button)
        bar = QHBoxLayout()
        for w in (self.play_button, self.back_button, self.next_button, QLabel("Speed"),
                  self.speed, QLabel("Trial"), self.flag_filter, self.trial_box, self.loop):
            bar.addWidget(w)
        bar.addStretch(1)
        bar.addWidget(self.position)
        lay = QVBoxLayout(self)
        lay.addLayout(head)
        lay.addWidget(self.problems)
        lay.addWidget(self.heatmap, 1)
        lay.addWidget(self.strip)
        lay.addLayout(bar)
        lay.addWidget(self.timeline)
        lay.addWidget(self.prediction)
        self.timer = QTimer(self)
        self.timer.setInterval(30)
        self._last = time.perf_counter()
        self.timer.timeout.connect(self._tick)
        self.check_button.clicked.connect(self.check)
        self.show_problems.toggled.connect(self._fold_problems)
        self.play_button.clicked.connect(self.toggle_play)
        self.back_button.clicked.connect(lambda: self.step(-1))
        self.next_button.clicked.connect(lambda: self.step(1))
        self.speed.currentIndexChanged.connect(self._speed_changed)
        self.trial_box.activated.connect(self._trial_chosen)
        self.flag_filter.activated.connect(lambda _k: self._list_trials(jump=True))
        self.loop.toggled.connect(self._loop_changed)
        self.timeline.seekRequested.connect(self.seek)
        self.heatmap.virtualChanged.connect(lambda _on: self.show_frame())
        self.heatmap.cellClicked.connect(self.toggle_taxel)
        self.strip.quantityChanged.connect(lambda _q: self.show_frame())
        self.strip.clearRequested.connect(lambda: self.set_taxels([]))
        self.pred_frames: np.ndarray | None = None
        self.pred_probs: np.ndarray | None = None
        self.pred_labels: list[str] = []

    # --- loading -----------------------------------------------------------------------
    def open_session(self, path: str) -> bool:
        try:
            pb = SessionPlayback(path)
        except (UserError, OSError) as exc:
            self.error.emit(f"{path}: {exc}" if str(path) not in str(exc) else str(exc))
            return False
        if self.pb is not None:
            self.pb.close()
        self.pb, self.clock = pb, PlayClock(pb)
        self.window = ChartWindow(self.strip.seconds, pb.duration)
        self.heatmap.set_layout(pb.layout)
        self.timeline.set_playback(pb)
        self.flag_filter.clear()
        for text, flag in flag_filters(pb.trials):
            self.flag_filter.addItem(text, flag)
        self._list_trials()
        # chart the two most-loaded taxels of the session to start with
        peak = np.abs(pb.frame(int(np.argmax(np.abs(pb.raw - pb.raw[0]).sum(axis=1))))[0])
        order = np.argsort(-peak.ravel())[:2]
        self.taxels = [(int(i // peak.shape[1]), int(i % peak.shape[1])) for i in order]
        self.pred_frames = self.pred_probs = None
        self.prediction.setText("")
        self.seek(0)
        self.check()
        return True

    def set_flag_filter(self, flag: str | None) -> None:
        """List only the trials ``flag`` keeps (None: all; ``ANY_FLAG``: any flagged) and
        go to the first of them."""
        self.flag_filter.setCurrentIndex(max(0, self.flag_filter.findData(flag)))
        self._list_trials(jump=True)

    def _list_trials(self, jump: bool = False) -> None:
        """The trial list under the flag filter; a flagged trial says why."""
        if self.pb is None:
            return
        flag = self.flag_filter.currentData()
        self.trial_box.clear()
        for t in self.pb.trials:
            if t.shows(flag):
                why = f" — {t.reason}" if t.reason else ""
                self.trial_box.addItem(f"{t.number}: {t.gesture} ({t.status}){why}", t.index)
                self.trial_box.setItemData(self.trial_box.count() - 1, t.reason or None,
                                           Qt.ItemDataRole.ToolTipRole)
        if jump and self.trial_box.count():
            self.jump_to_trial(int(self.trial_box.itemData(0)))

    def listed_trials(self) -> list[int]:
        """The trial indices the list offers now."""
        return [int(self.trial_box.itemData(k)) for k in range(self.trial_box.count())]

    def check(self) -> list[str] | None:
        """Check the open file (``session_check``, what ``tactile-studio check`` runs) and
        show the verdict; the violations, or None when the file cannot be read now. It
        reads the journal and the time columns only, far less than opening the file."""
        self.check_button.setEnabled(self.pb is not None)
        if self.pb is None:
            return None
        try:
            violations = check_file(self.pb.path).violations
        except (UserError, OSError) as exc:
            self._show_verdict(f"cannot check the file: {exc}", [], INVALID_STYLE)
            return None
        if violations:
            self._show_verdict("⚠ " + verdict_text(violations), violations, INVALID_STYLE)
        else:
            self._show_verdict(f"✓ valid session: passes check ({CHECKED})", [], VALID_STYLE)
        return violations

    def _show_verdict(self, text: str, violations: list[str], style: str) -> None:
        self.validity.setText(text)
        self.validity.setStyleSheet(style)
        self.validity.setToolTip("\n".join(violations) or text)
        self.problems.clear()
        self.problems.addItems(violations)
        self.show_problems.setVisible(bool(violations))
        if not violations:
            self.show_problems.setChecked(False)
        self._fold_problems(self.show_problems.isChecked())

    def _fold_problems(self, shown: bool) -> None:
        self.problems.setVisible(shown and self.problems.count() > 0)
        self.show_problems.setText("Hide problems" if shown else "Show problems")

    def set_predictions(self, frames: np.ndarray, probs: np.ndarray, labels: list[str]) -> None:
        self.pred_frames, self.pred_probs, self.pred_labels = frames, probs, labels
        self.timeline.set_predictions(frames, probs, labels)
        self.show_frame()

    def load_run_predictions(self, run: str) -> bool:
        """The run's prediction over this session's time (see learn/timeline.py)."""
        from tactile_studio.playback.predictions import predictions_over_time

        if self.pb is None:
            return False
        try:
            frames, probs, labels = predictions_over_time(run, self.pb)
        except UserError as exc:
            self.error.emit(str(exc))
            return False
        self.run_path = run
        self.set_predictions(frames, probs, labels)
        return True

    def toggle_taxel(self, row: int, col: int) -> None:
        """A click on the map adds or removes a taxel from the strip chart (physical grid)."""
        if self.heatmap.virtual:
            row, col = row // 2, col // 2
        cell = (row, col)
        self.set_taxels([t for t in self.taxels if t != cell] if cell in self.taxels
                        else [*self.taxels, cell])

    def set_taxels(self, taxels: list[tuple[int, int]]) -> None:
        self.taxels = list(taxels)
        self.show_frame()

    # --- playing -----------------------------------------------------------------------
    def seek(self, frame: int) -> None:
        if self.clock is not None:
            self.clock.seek(frame)
            self.show_frame()

    def step(self, n: int) -> None:
        if self.clock is not None:
            self.clock.playing = False
            self.play_button.setText("Play")
            self.clock.step(n)
            self.show_frame()

    def jump_to_trial(self, index: int) -> None:
        """The cursor to the trial's start, the trial centred in the strip chart (with
        what came before and after it)."""
        if self.pb is None or self.clock is None:
            return
        span = self.pb.trial(index)
        self.window.centre_on(self.pb.time_of(span.start), self.pb.time_of(span.end - 1))
        if self.loop.isChecked():
            self.clock.loop_trial(span)
        self.seek(span.start)

    def _trial_chosen(self, k: int) -> None:
        self.jump_to_trial(int(self.trial_box.itemData(k)))

    def _loop_changed(self, on: bool) -> None:
        if self.clock is None or self.pb is None:
            return
        span = self.pb.trial_at(self.clock.frame) if on else None
        if on and span is None and self.trial_box.count():
            span = self.pb.trial(int(self.trial_box.currentData()))
        self.clock.loop_trial(span)
        self.show_frame()

    def _speed_changed(self, k: int) -> None:
        if self.clock is not None:
            self.clock.speed = SPEEDS[k]

    def toggle_play(self) -> None:
        if self.clock is None:
            return
        self.clock.playing = not self.clock.playing
        self.play_button.setText("Pause" if self.clock.playing else "Play")
        self._last = time.perf_counter()
        self.timer.start() if self.clock.playing else self.timer.stop()

    def _tick(self) -> None:
        if self.clock is None:
            return
        now = time.perf_counter()
        self.clock.advance(now - self._last)
        self._last = now
        self.show_frame()
        if not self.clock.playing:
            self.timer.stop()
            self.play_button.setText("Play")

    def show_frame(self) -> None:
        if self.pb is None or self.clock is None:
            return
        f = self.clock.frame
        normal, sx, sy, units = self.pb.frame(f, self.heatmap.virtual)
        self.heatmap.set_frame(normal, sx, sy, units)
        self.timeline.set_cursor(f)
        near = self.pb.trial_near(f)  # the trial box and the chart follow the cursor
        self._show_chart(f, near)
        self.heatmap.set_marked_cells(self.taxels, strip_colors(len(self.taxels)))
        t = self.pb.trial_at(f)
        where = f"trial {t.number} {t.gesture}" if t else "between trials"
        k = self.trial_box.findData(near.index) if near is not None else -1
        if k >= 0 and k != self.trial_box.currentIndex():
            self.trial_box.setCurrentIndex(k)
        self.position.setText(f"{self.pb.time_of(f):7.2f} s · frame {f}/{self.pb.n_frames - 1}"
                              f" · {where}")
        if self.pred_frames is not None and self.pred_probs is not None:
            k = int(np.searchsorted(self.pred_frames, f, side="right")) - 1
            if k < 0:
                self.prediction.setText("prediction: waiting for the first full window")
            else:
                order = np.argsort(-self.pred_probs[k])[:3]
                self.prediction.setText("prediction: " + ",  ".join(
                    f"{self.pred_labels[i]} {100 * self.pred_probs[k, i]:.0f}%" for i in order))

    def _show_chart(self, f: int, near) -> None:  # noqa: ANN001 - a TrialSpan or None
        """The strip chart's stretch around the cursor (playback.chart.ChartWindow), the
        trials in it shaded (``near``, the trial box's, darker) and the cursor line."""
        assert self.pb is not None
        pb, now = self.pb, self.pb.time_of(f)
        t0, t1 = self.window.follow(now)
        self.strip.set_window(t0, t1, now)
        self.strip.set_spans([(pb.time_of(s.start), pb.time_of(s.end - 1),
                               f"{s.number}: {s.gesture}", s is near) for s in pb.trials
                              if pb.time_of(s.end - 1) >= t0 and pb.time_of(s.start) <= t1])
        self.strip.set_history(session_history(pb, f, self.taxels, self.strip.quantity(),
                                               window=(t0, t1)))

    def current_frame(self) -> int:
        return self.clock.frame if self.clock else 0
