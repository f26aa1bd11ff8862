"""Two runs side by side: the sentence, the difference matrix, per-participant bars."""

from __future__ import annotations

from typing import Any

import numpy as np
from PySide6.QtCore import QRect, QSize, Qt
from PySide6.QtGui import QColor, QFont, QFontMetrics, QPainter, QPaintEvent
from PySide6.QtWidgets import QLabel, QSplitter, QVBoxLayout, QWidget

from tactile_studio.ui.research.matrix_widget import MatrixWidget

A_COLOUR, B_COLOUR = QColor(150, 150, 150), QColor(40, 110, 200)


class PairedBars(QWidget):
    """Accuracy of run A and run B for each participant, side by side."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.result: dict[str, Any] | None = None
        self.setMinimumHeight(200)

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt name
        return QSize(500, 260)

    def set_result(self, r: dict[str, Any]) -> None:
        self.result = r
        self.update()

    def paintEvent(self, event: QPaintEvent) -> None:  # noqa: N802 - Qt name
        p = QPainter(self)
        p.fillRect(self.rect(), QColor("white"))
        r = self.result
        if not r:
            p.end()
            return
        font = QFont(self.font())
        font.setPointSize(9)
        p.setFont(font)
        fm = QFontMetrics(font)
        parts = list(r["per_participant"])
        left, top = fm.horizontalAdvance("100%") + 10, 2 * fm.height() + 12
        bottom = self.height() - 2 * fm.height() - 8
        width = self.width() - left - 10
        h = bottom - top
        p.setPen(QColor(200, 200, 200))
        for frac in (0.0, 0.5, 1.0):
            y = bottom - int(frac * h)
            p.drawLine(left, y, left + width, y)
            p.setPen(QColor("black"))
            p.drawText(QRect(0, y - fm.height() // 2, left - 4, fm.height()),
                       Qt.AlignmentFlag.AlignRight, f"{int(100 * frac)}%")
            p.setPen(QColor(200, 200, 200))
        slot = width / max(len(parts), 1)
        bar = max(min(slot * 0.35, 30), 2)
        for k, name in enumerate(parts):
            v = r["per_participant"][name]
            x = left + k * slot + slot / 2
            for off, acc, colour in ((-bar, v["accuracy_a"], A_COLOUR),
                                     (0, v["accuracy_b"], B_COLOUR)):
                bh = int(acc * h)
                p.fillRect(QRect(int(x + off), bottom - bh, int(bar), bh), colour)
                if bar >= fm.horizontalAdvance("100") + 2:
                    p.setPen(QColor("black"))
                    p.drawText(QRect(int(x + off) - 4, bottom - bh - fm.height(), int(bar) + 8,
                                     fm.height()), Qt.AlignmentFlag.AlignCenter,
                               f"{100 * acc:.0f}")
            p.setPen(QColor("black"))
            p.drawText(QRect(int(x - slot / 2), bottom + 2, int(slot), fm.height()),
                       Qt.AlignmentFlag.AlignCenter,
                       fm.elidedText(name, Qt.TextElideMode.ElideRight, int(slot)))
        y = self.height() - fm.height() - 2
        x = left
        for name, colour in ((r["name_a"], A_COLOUR), (r["name_b"], B_COLOUR)):
            p.fillRect(QRect(x, y + 2, 12, fm.height() - 4), colour)
            p.drawText(x + 16, y + fm.ascent(), name)
            x += 16 + fm.horizontalAdvance(name) + 20
        p.drawText(QRect(left, 2, width, fm.height()), Qt.AlignmentFlag.AlignLeft,
                   "accuracy per participant")
        p.end()


def shots_text(r: dict[str, Any]) -> str:
    """The few-shot comparison, one line per K (the matrix and bars below are the
    smallest K's); "" when neither run is a few-shot run."""
    shots = r.get("shots") or []
    if not shots:
        return ""
    lines = [f"Few-shot curve (K labelled performances per gesture of the test person; "
             f"below: K = {shots[0]['k']}):"]
    for s in shots:
        lines.append(f"K = {s['k']}: {r['name_a']} {100 * s['accuracy_a']:.1f}%, "
                     f"{r['name_b']} {100 * s['accuracy_b']:.1f}% — {s['sentence']}")
    return "\n".join(lines)


class CompareView(QWidget):
    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.result: dict[str, Any] | None = None
        self.sentence = QLabel("Select two runs in the Runs tab and press Compare.")
        self.sentence.setWordWrap(True)
        f = self.sentence.font()
        f.setPointSize(f.pointSize() + 1)
        self.sentence.setFont(f)
        self.sentence.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.details = QLabel("")
        self.details.setWordWrap(True)
        # two few-shot runs (train --shots): the comparison at every K both have
        self.shots = QLabel("")
        self.shots.setWordWrap(True)
        self.shots.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.shots.hide()
        self.matrix = MatrixWidget()
        self.matrix.tooltip = self._tooltip
        self.bars = PairedBars()
        split = QSplitter()
        split.addWidget(self.matrix)
        split.addWidget(self.bars)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        lay = QVBoxLayout(self)
        lay.addWidget(self.sentence)
        lay.addWidget(self.details)
        lay.addWidget(self.shots)
        lay.addWidget(split, 1)

    def set_result(self, r: dict[str, Any]) -> None:
        self.result = r
        self.sentence.setText(r["sentence"])
        self.details.setText(
            f"A = {r['name_a']} ({r['run_a']}): {100 * r['accuracy_a']:.1f}%   ·   "
            f"B = {r['name_b']} ({r['run_b']}): {100 * r['accuracy_b']:.1f}%   ·   differ in: "
            + ("; ".join(r["config_difference"]) or "the same settings"))
        self.shots.setText(shots_text(r))
        self.shots.setVisible(bool(r.get("shots")))
        diff = np.asarray(r["difference_matrix"])
        texts = [[f"{100 * v:+.0f}" if abs(v) >= 0.005 else "" for v in row] for row in diff]
        scale = max(float(np.abs(diff).max()), 0.05)
        better = -diff  # colour by improvement: more on the diagonal, less off it
        np.fill_diagonal(better, np.diag(diff))
        self.matrix.set_matrix(r["labels"], better, texts, None, True, scale,
                               f"row % of B ({r['name_b']}) minus A ({r['name_a']}), points "
                               f"(green: B better, red: B worse)")
        self.bars.set_result(r)

    def _tooltip(self, row: int, col: int) -> str:
        r = self.result or {}
        labels = r.get("labels", [])
        v = r["difference_matrix"][row][col]
        return (f"true {labels[row]} → predicted {labels[col]}: {100 * v:+.1f} points "
                f"({r['name_b']} minus {r['name_a']})")
