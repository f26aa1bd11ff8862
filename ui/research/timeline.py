"""The player's timeline: trials coloured by gesture (status shown), events as ticks
(named in the tooltip: markers from scripts and other programs too), auxiliary signals
(EDA, ECG...) each in a lane of its own, the cursor, and under it a run's top
prediction with its probability over time. Click or drag to scrub."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRect, QSize, Qt, Signal
from PySide6.QtGui import (
    QBrush,
    QColor,
    QFont,
    QFontMetrics,
    QMouseEvent,
    QPainter,
    QPaintEvent,
    QPolygonF,
)
from PySide6.QtWidgets import QToolTip, QWidget

from tactile_studio.playback import AuxTrack, SessionPlayback
from tactile_studio.storage.format.trials import TrialStatus

AUX_LANE = 30  # px per auxiliary signal (EDA, ECG...) drawn under the trials
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
        self.setMinimumHeight(130 + AUX_LANE * len(pb.aux if pb else []))
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
            tip += f"\ntrial {t.number}: {t.gesture} ({t.status}{', flagged' if t.flags else ''})"
        near = 3 * (self.pb.n_frames - 1) / max(self.width() - 8, 1)  # 3 px either side
        for ev in [ev for ev in self.pb.events if abs(ev.frame - frame) <= near][:6]:
            tip += f"\n{ev.kind}: {ev.text}" if ev.text != ev.kind else f"\n{ev.kind}"
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
        aux0 = lane[1] + 6              # auxiliary signals, one lane each
        pred = (aux0 + AUX_LANE * len(pb.aux) + fm.height() + 8, h - fm.height() - 6)
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
        for k, track in enumerate(pb.aux):
            self._draw_aux(p, fm, track, aux0 + k * AUX_LANE, AUX_LANE - 4)
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
            caption = "prediction (height = probability):"
            y = pred[0] - fm.height() - 4
            p.drawText(QRect(6, y, self.width(), fm.height()), Qt.AlignmentFlag.AlignLeft,
                       caption)
            self._draw_legend(p, fm, 6 + fm.horizontalAdvance(caption) + 10, y)
        p.setPen(QColor(60, 60, 60))
        p.drawText(QRect(4, h - fm.height() - 2, 200, fm.height()), Qt.AlignmentFlag.AlignLeft,
                   "0 s")
        p.drawText(QRect(self.width() - 204, h - fm.height() - 2, 200, fm.height()),
                   Qt.AlignmentFlag.AlignRight, f"{pb.duration:.1f} s")
        x = int(self._x(self.cursor))
        p.setPen(QColor("black"))
        p.drawLine(x, 0, x, h)
        p.end()

    def legend_entries(self) -> list[tuple[str, QColor]]:
        """The gestures the prediction strip shows, each with its colour (the trials'
        colours: a prediction is right where its colour matches the trial above)."""
        if self.pred_probs is None or not len(self.pred_probs):
            return []
        shown = {self.pred_labels[i] for i in np.unique(self.pred_probs.argmax(axis=1))}
        return [(n, gesture_colour(self.names, n)) for n in self.names if n in shown]

    def _draw_legend(self, p: QPainter, fm: QFontMetrics, x: int, y: int) -> None:
        """A swatch and a name per predicted gesture, on the caption's line."""
        box = fm.height() - 4
        for name, colour in self.legend_entries():
            need = box + 4 + fm.horizontalAdvance(name) + 12
            if x + need > self.width() - 6:
                p.drawText(QRect(x, y, 20, fm.height()), Qt.AlignmentFlag.AlignLeft, "…")
                return
            p.fillRect(QRect(x, y + 2, box, box), colour)
            p.setPen(QColor(60, 60, 60))
            p.drawText(QRect(x + box + 4, y, need, fm.height()), Qt.AlignmentFlag.AlignLeft,
                       name)
            x += need

    def _draw_aux(self, p: QPainter, fm: QFontMetrics, track: AuxTrack, top: int,
                  height: int) -> None:
        """One auxiliary signal as a line scaled to its own range, named at the left."""
        p.setPen(QColor(225, 225, 225))
        p.drawRect(QRect(4, top, self.width() - 8, height))
        step = max(1, len(track.values) // 4000)  # enough points for any screen
        v, f = track.values[::step], track.frames[::step]
        lo, hi = float(np.min(v)), float(np.max(v))
        y = top + height - 2 - (v - lo) / ((hi - lo) or 1.0) * (height - 4)
        x = 4 + (self.width() - 8) * f / max((self.pb.n_frames if self.pb else 1) - 1, 1)
        p.setPen(QColor("#2a6f97"))
        p.drawPolyline(QPolygonF([QPointF(a, b) for a, b in zip(x.tolist(), y.tolist())]))
        unit = f" ({track.unit})" if track.unit else ""
        text = f"{track.name}{unit}: {lo:.3g} to {hi:.3g}"
        box = QRect(6, top + 1, fm.horizontalAdvance(text) + 4, fm.height())
        p.fillRect(box, QColor(255, 255, 255, 220))  # readable over the trace
        p.setPen(QColor(70, 70, 70))
        p.drawText(box.adjusted(2, 0, 0, 0), Qt.AlignmentFlag.AlignLeft, text)
