"""The console's experimenter verbs, participant keys and participant window: a mixin
of :class:`~tactile_studio.ui.collect.console.CollectConsole`.

Everything here forwards intent to the runner (``self.runner``) and presents the result
with ``self.tick()``; no collection logic lives in the widgets.
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtGui import QGuiApplication, QKeyEvent
from PySide6.QtWidgets import (
    QAbstractSpinBox,
    QComboBox,
    QLineEdit,
    QMainWindow,
    QMessageBox,
    QTextEdit,
    QWidget,
)

from tactile_studio.ui.collect.log import TextDialog

DISCARD_REASONS = ("wrong gesture", "started late", "interrupted", "sensor problem")
_TEXT_INPUTS = (QLineEdit, QTextEdit, QAbstractSpinBox, QComboBox)


class ConsoleActions(QMainWindow):
    """The experimenter's buttons, the participant's keys and the participant window.

    Uses the console's ``runner``, ``log``, ``stack``, ``participant``, ``mirror``,
    ``live`` and ``tick()``.
    """

    runner: Any
    _dialog: TextDialog | None

    # ---- experimenter actions (forwarded to the runner) ---------------------------------
    def primary_action(self) -> None:
        if self.runner is None:
            return
        if self.runner.snapshot().state == "setup":
            self.runner.start()
        else:
            self.runner.proceed()
        self.tick()

    def redo_last(self) -> None:
        if self.runner is not None:
            self.runner.redo_last()
            self.tick()

    def toggle_pause(self) -> None:
        if self.runner is None:
            return
        if self.runner.snapshot().state == "paused":
            self.runner.resume()
        else:
            self.runner.pause()
        self.tick()

    def skip_to_break(self) -> None:
        if self.runner is not None:
            self.runner.skip_to_break()
            self.tick()

    def ask_discard(self) -> TextDialog | None:
        """Ask a reason to discard the selected trial (or the last one)."""
        if self.runner is None:
            return None
        snap = self.runner.snapshot()
        index = self.log.selected_index()
        if index is None and snap.last_trial is not None:
            index = int(snap.last_trial["index"])
        if index is None:
            return None
        gesture = next((t["gesture"] for t in snap.trials if t["index"] == index), "?")
        dlg = TextDialog("Discard trial", f"Discard trial {index} ({gesture}). Reason:",
                         DISCARD_REASONS, self)
        dlg.accepted.connect(lambda: self._discard(index, dlg.text()))
        return self._open_dialog(dlg)

    def _discard(self, index: int, reason: str) -> None:
        if self.runner is not None:
            self.runner.discard(index, reason)
            self.tick()

    def ask_note(self) -> TextDialog | None:
        if self.runner is None:
            return None
        dlg = TextDialog("Session note", "Note (saved in the session file):", (), self)
        dlg.accepted.connect(lambda: self.runner is not None and self.runner.add_note(dlg.text()))
        return self._open_dialog(dlg)

    def _open_dialog(self, dlg: TextDialog) -> TextDialog:
        self._dialog = dlg
        dlg.finished.connect(dlg.deleteLater)
        dlg.open()
        dlg.edit.setFocus()
        return dlg

    @property
    def dialog(self) -> TextDialog | None:
        """The open discard/note dialog, if any (tests type into it)."""
        try:
            return self._dialog if self._dialog is not None and self._dialog.isVisible() else None
        except RuntimeError:  # already deleted
            return None

    def end_session(self) -> None:
        if self.runner is None:
            return
        answer = QMessageBox.question(
            self, "End session", "End the session now? Finished trials stay in the file.")
        if answer == QMessageBox.StandardButton.Yes:
            self.runner.abort()
            self.tick()

    # ---- keys ---------------------------------------------------------------------------
    def forward_key(self, text: str) -> bool:
        """A participant key from either window goes to the runner."""
        if self.runner is None or not text.strip():
            return False
        accepted = self.runner.key(text)
        self.tick()
        return bool(accepted)

    def eventFilter(self, obj: QObject, event: QEvent) -> bool:  # noqa: N802 (Qt)
        """Plain printable keys typed anywhere in the console go to the runner, unless
        the experimenter is typing into a text field or a dialog."""
        if event.type() != QEvent.Type.KeyPress or self.runner is None:
            return False
        if not isinstance(obj, QWidget) or obj.window() is not self:
            return False
        if self.stack.currentIndex() != 1 or isinstance(obj, _TEXT_INPUTS):
            return False
        assert isinstance(event, QKeyEvent)
        mods = event.modifiers() & ~Qt.KeyboardModifier.ShiftModifier \
            & ~Qt.KeyboardModifier.KeypadModifier
        text = event.text()
        if mods or len(text) != 1 or not text.isprintable() or text.isspace():
            return False
        if not event.isAutoRepeat():
            self.forward_key(text)
        return True

    # ---- participant window and beep flash ----------------------------------------------
    def show_participant_screen(self) -> None:
        """Show the participant screen, full screen on a second monitor if there is one."""
        screens = QGuiApplication.screens()
        if len(screens) > 1:
            other = next((s for s in screens if s is not self.screen()), screens[-1])
            self.participant.setScreen(other)
            self.participant.move(other.geometry().topLeft())
            self.participant.showFullScreen()
            size = other.geometry().size()
        else:
            self.participant.resize(1280, 720)
            self.participant.show()
            size = self.participant.size()
        self.mirror.aspect = size.width() / max(1, size.height())
        self.mirror.update()
        self.participant.raise_()

    def _flash(self) -> None:
        self.participant.flash()
        self.mirror.flash()

    def _on_virtual(self, on: bool) -> None:
        self.live.virtual = on

