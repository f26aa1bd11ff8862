"""The console's experimenter verbs, participant keys and participant window: a mixin
of :class:`~tactile_studio.ui.collect.console.CollectConsole`.

Everything here forwards intent to the runner (``self.runner``) and presents the result
with ``self.tick()``; no collection logic lives in the widgets.
"""

from __future__ import annotations

from typing import Any

from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QMainWindow, QMessageBox

from tactile_studio.ui.collect.log import TextDialog

DISCARD_REASONS = ("wrong gesture", "started late", "interrupted", "sensor problem")


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

    def keep_flagged(self) -> None:
        """The banner's Keep: the flagged trial stays, its flag on record; a held
        session goes on (as Continue)."""
        if self.runner is None or not self.runner.snapshot().redo_prompt:
            return
        if self.runner.held:  # Continue keeps it (decision keep) and goes on
            self.runner.proceed()
        else:
            self.runner.keep_flagged()
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
        """Ask a reason to discard the selected trial (or the last one), and whether to
        collect its gesture again at the end of the block; the dialog says what
        discarding costs either way."""
        if self.runner is None:
            return None
        snap = self.runner.snapshot()
        index = self.log.selected_index()
        if index is None and snap.last_trial is not None:
            index = int(snap.last_trial["index"])
        trial = next((t for t in snap.trials if t["index"] == index), None)
        if trial is None:
            return None
        number, gesture, block = index + 1, trial["gesture"], int(trial["block"])
        if trial["status"] != "ok":
            self.statusBar().showMessage(f"Trial {number} is already {trial['status']}", 6000)
            return None
        where = "practice" if block < 0 else f"block {block + 1}"
        dlg = TextDialog("Discard trial", f"Discard trial {number} ({gesture}, {where})? It "
                         "stays in the file, marked discarded, and is left out of training "
                         "and of the summary. Reason:", DISCARD_REASONS, self)
        if self.runner.can_collect_again(index):
            dlg.add_choice(
                f"Collect {gesture} again at the end of {where}", True,
                f"One more trial ({self.protocol.trial_s:g} s) after the block's other "
                f"gestures; the new trial replaces this one.",
                f"{where.capitalize()} will have no usable {gesture} trial.")
        else:
            dlg.add_note(f"{where.capitalize()} is over, so {gesture} cannot be collected "
                         f"again: {where} keeps no usable {gesture} trial.")
        dlg.accepted.connect(lambda: self._discard(
            index, dlg.text(), dlg.choice is not None and dlg.choice.isChecked()))
        return self._open_dialog(dlg)

    def _discard(self, index: int, reason: str, again: bool = False) -> None:
        if self.runner is not None:
            self.runner.discard(index, reason, again=again)
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
        """A participant key from the participant screen or the focused mirror (the
        only two places where typing a letter starts a trial)."""
        if self.runner is None or len(text) != 1 or not text.isprintable() or text.isspace():
            return False  # Space, Ctrl+letter, arrows...: not a gesture key
        accepted = self.runner.key(text)
        self.tick()
        return bool(accepted)

    def _on_mirror_focus(self, focused: bool) -> None:
        """Say where the participant's keys go: the mirror, only once it is clicked."""
        self.mirror_hint.setText(
            "Keys typed now go to the session (click elsewhere to stop)" if focused else
            "Click the mirror to type the participant's keys on this keyboard")
        self.mirror_hint.setStyleSheet("color: #1f6feb; font-weight: 600;" if focused
                                       else "color: #606770;")

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

