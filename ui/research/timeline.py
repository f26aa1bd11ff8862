"""The player's timeline: trials coloured by gesture (status shown), events as ticks,
the cursor, and under it a run's top prediction with its probability over time.
Click or drag to scrub."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QRect, QSize, Qt, Signal
from PySide6.QtGui import QBrush, QColor, QFont, QFontMetrics, QMouseEvent, QPainter, QPaintEvent
from PySide6.QtWidgets import QToolTip, QWidget

from tactile_studio.playback import SessionPlayback
from tactile_studio.storage.trials import TrialStatus

PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39"]


def gesture_colour(names: list[str], name: str) -> QColor:
    return QColor(PALETTE[names.index(name) % len(PALETTE)] if name in names else "#aaaaaa")


class Timeline(QWidget):
    seekRequested = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.pb: SessionPlayback | None = None
        self.cursor = 0
        self.names: list[str] = []
        self.pred_frames: np.ndarray | None = None
        self.pred_probs: np.ndarray | None = None
        self.pred_labels: list[str] = []
        self.setMouseTracking(True)
        self.setMinimumHeight(130)

    def sizeHint(self) -> QSize:  # noqa: N802 - Qt name
        return QSize(800, 140)

    def set_playback(self, pb: SessionPlayback | None) -> None:
        self.pb, self.cursor = pb, 0
        self.names = sorted({*(pb.gestures if pb else [])})
        self.pred_frames = self.pred_probs = None
        self.update()

    def set_predictions(self, frames: np.ndarray, probs: np.ndarray, labels: list[str]) -> None:
        self.pred_frames, self.pred_probs, self.pred_labels = frames, probs, labels
        self.names = sorted({*self.names, *labels})
        self.update()

    def set_cursor(self, frame: int) -> None:
        self.cursor = frame
        self.update()

    def _x(self, frame: float) -> float:
        n = self.pb.n_frames if self.pb else 1
        return 4 + (self.width() - 8) * frame / max(n - 1, 1)

    def frame_at_x(self, x: float) -> int:
        n = self.pb.n_frames if self.pb else 1
        return int(np.clip(round((x - 4) / max(self.width() - 8, 1) * (n - 1)), 0, n - 1))

    def mousePressEvent(self, e: QMouseEvent) -> None:  # noqa: N802 - Qt name
        if self.pb is not None:
            self.seekRequested.emit(self.frame_at_x(e.position().x()))

    def mouseMoveEvent(self, e: QMouseEvent) -> None:  # noqa: N802 - Qt name
        if self.pb is None:
            return
        frame = self.frame_at_x(e.position().x())
        if e.buttons() & Qt.MouseButton.LeftButton:
            self.seekRequested.emit(frame)
        t = self.pb.trial_at(frame)
        tip = f"{self.pb.time_of(frame):.2f} s (frame {frame})"
        if t is not None:
            tip += f"\ntrial {t.index}: {t.gesture} ({t.status}{', flagged' if t.flags else ''})"
        QToolTip.showText(e.globalPosition().toPoint(), tip, self)

    def paintEvent(self, event: QPaintEvent) -> None:  # noqa: N802 - Qt name
        p = QPainter(self)
        p.fillRect(self.rect(), QColor("white"))
        pb = self.pb
        if pb is None:
            p.end()
            return
        font = QFont(self.font())
        font.setPointSize(8)
        p.setFont(font)
        fm = QFontMetrics(font)
        h = self.height()
        lane = (6, 6 + 34)             # trials
        pred = (lane[1] + fm.height() + 8, h - fm.height() - 6)  # predictions
        p.setPen(QColor(180, 180, 180))
        p.drawRect(QRect(4, lane[0], self.width() - 8, lane[1] - lane[0]))
        for t in pb.trials:
            x0, x1 = self._x(t.start), self._x(t.end)
            colour = gesture_colour(self.names, t.gesture)
            r = QRect(int(x0), lane[0] + 1, max(int(x1 - x0), 1), lane[1] - lane[0] - 1)
            if t.status != TrialStatus.OK:
                colour.setAlpha(90)
                p.fillRect(r, QBrush(colour, Qt.BrushStyle.BDiagPattern))
            else:
                p.fillRect(r, colour)
            if t.flags:
                p.fillRect(QRect(r.x(), r.y(), r.width(), 4), QColor("#e0a000"))
            label = fm.elidedText(t.gesture, Qt.TextElideMode.ElideRight, r.width() - 2)
            p.setPen(QColor("white") if t.status == TrialStatus.OK else QColor("black"))
            p.drawText(r, Qt.AlignmentFlag.AlignCenter, label)
        p.setPen(QColor("#c00000"))
        for ev in pb.events:
            x = int(self._x(ev.frame))
            p.drawLine(x, 0, x, lane[1] + 4)
        if self.pred_frames is not None and self.pred_probs is not None and len(self.pred_frames):
            top = self.pred_probs.argmax(axis=1)
            span = pred[1] - pred[0]
            for k in range(len(self.pred_frames)):
                x0 = self._x(self.pred_frames[k - 1] if k else self.pred_frames[0])
                x1 = self._x(self.pred_frames[k])
                ph = int(span * float(self.pred_probs[k, top[k]]))
                p.fillRect(QRect(int(x0), pred[1] - ph, max(int(x1 - x0), 1), ph),
                           gesture_colour(self.names, self.pred_labels[top[k]]))
            p.setPen(QColor(120, 120, 120))
            p.drawText(QRect(6, lane[1] + 4, self.width(), fm.height()), Qt.AlignmentFlag.AlignLeft,
                       "prediction (height = probability)")
        p.setPen(QColor(60, 60, 60))
        p.drawText(QRect(4, h - fm.height() - 2, 200, fm.height()), Qt.AlignmentFlag.AlignLeft,
                   "0 s")
        p.drawText(QRect(self.width() - 204, h - fm.height() - 2, 200, fm.height()),
                   Qt.AlignmentFlag.AlignRight, f"{pb.duration:.1f} s")
        x = int(self._x(self.cursor))
        p.setPen(QColor("black"))
        p.drawLine(x, 0, x, h)
        p.end()
