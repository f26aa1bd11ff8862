"""The console's amber banner for a flagged trial: its reason, **Redo** and **Keep**.

It keeps its room on the page while hidden (and a fixed height while shown), so the
heatmap, the buttons and the mirror do not move as flags come and go; the experimenter
looks at the participant, not at a page that jumps.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QFrame, QHBoxLayout, QLabel, QPushButton, QSizePolicy, QWidget

AMBER = "#ffe3b3"
AMBER_TEXT = "#6b4100"


class FlagBanner(QFrame):
    """"Trial 4 (Twist): looks like Wide Pinch (0.61) - redo?" with Redo and Keep."""

    redoRequested = Signal()
    keepRequested = Signal()

    def __init__(self, redo_key: str, keep_key: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setObjectName("flagBanner")
        self.setStyleSheet(
            f"#flagBanner {{ background: {AMBER}; border-radius: 6px; }}"
            f"#flagBanner QLabel {{ color: {AMBER_TEXT}; font-weight: 600; }}")
        self.label = QLabel()
        self.label.setWordWrap(True)
        self.label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.label.setTextFormat(Qt.TextFormat.PlainText)
        self.redo = QPushButton(f"Redo ({redo_key})")
        self.redo.setToolTip("Collect this gesture again in this block; the flagged trial "
                             "is marked redone")
        self.keep = QPushButton(f"Keep ({keep_key})")
        self.keep.setToolTip("Keep the trial; its flag and your decision stay on record")
        for b in (self.redo, self.keep):
            b.setFocusPolicy(Qt.FocusPolicy.NoFocus)  # letters and Space are the runner's
        self.redo.clicked.connect(self.redoRequested)
        self.keep.clicked.connect(self.keepRequested)
        row = QHBoxLayout(self)
        row.setContentsMargins(8, 4, 8, 4)
        row.addWidget(self.label, 1)
        row.addWidget(self.redo)
        row.addWidget(self.keep)
        # two lines of text or the buttons, whichever is taller: the same height always
        lines = 2 * self.label.fontMetrics().lineSpacing()
        self.setFixedHeight(max(lines, self.redo.sizeHint().height()) + 8 + 6)
        policy = self.sizePolicy()
        policy.setRetainSizeWhenHidden(True)
        self.setSizePolicy(policy)
        self.hide()

    def text(self) -> str:
        return self.label.text()

    def say(self, text: str) -> None:
        """Show ``text`` (hide on ""); the page's layout does not change either way."""
        if text != self.label.text():
            self.label.setText(text)
            self.label.setToolTip(text)
        self.setVisible(bool(text))
