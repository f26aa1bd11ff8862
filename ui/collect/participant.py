"""The participant screen: what the person touching the sensor sees on the second monitor.

Everything is painted relative to the widget's size, so the same widget works full
screen on a participant monitor and as the scaled mirror in the experimenter console.
It only draws a :class:`ParticipantView` (built from the runner's snapshot by
``view``) and forwards key presses; it holds no protocol logic. A gesture's
image (from the protocol file) sits at the right of its card, scaled to fit with its
aspect kept; an image that cannot be read is left out (logged once), never an error
mid-session.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

from PySide6.QtCore import QRectF, Qt, QVariantAnimation, Signal
from PySide6.QtGui import (
    QColor,
    QFontMetricsF,
    QImage,
    QKeyEvent,
    QPainter,
    QPen,
    QPixmap,
)
from PySide6.QtWidgets import QWidget

from tactile_studio.ui.collect.paint import (
    ACCENT,
    ACTIVE,
    BG,
    DIM,
    GOOD,
    MUTED,
    PANEL,
    PILOT,
    SURROUND,
    TEXT,
    WARN,
    _fit_font,
    _font,
    paint_prompt,
)
from tactile_studio.ui.collect.participant_cards import Card, CardPainting

log = logging.getLogger(__name__)



@dataclass
class ParticipantView:
    """What the participant screen draws; ``mode`` picks the layout.

    Modes: setup, free_play, block_start, waiting, recording, trial_end, review, break,
    paused, finished, aborted.
    """

    mode: str = "setup"
    title: str = ""
    subtitle: str = ""
    block_label: str = ""          # "Block 3 of 52", "Practice"; "" hides the header
    done_in_block: int = 0
    n_in_block: int = 0
    cards: list[Card] = field(default_factory=list)
    countdown_s: float | None = None        # seconds left (trial, break, free play)
    countdown_total_s: float | None = None
    hint: str = ""                          # e.g. a refused key
    footer: str = ""
    prompt: Card | None = None              # the prompted gesture, drawn large (waiting)
    pilot: bool = False                     # a rehearsal: framed and tagged PILOT




class ParticipantScreen(CardPainting, QWidget):
    """Large-type participant display; ``keyPressed`` carries the typed text."""

    keyPressed = Signal(str)
    focusChanged = Signal(bool)  # the mirror shows whether the keyboard is the session's

    def __init__(self, parent: QWidget | None = None, mirror: bool = False) -> None:
        super().__init__(parent)
        self.mirror = mirror
        # a mirror keeps the participant monitor's shape (letterboxed), so it shows the
        # same layout the participant sees; None fills the widget
        self.aspect: float | None = 16 / 9 if mirror else None
        self.view = ParticipantView()
        self._sources: dict[str, QImage | None] = {}    # path -> image (None: unreadable)
        self._scaled: dict[tuple[str, int, int], QPixmap] = {}
        self._flash = 0.0
        self._anim = QVariantAnimation(self)
        self._anim.setStartValue(1.0)
        self._anim.setEndValue(0.0)
        self._anim.setDuration(450)
        self._anim.valueChanged.connect(self._set_flash)
        # the mirror takes keys only once clicked (or tabbed to): the console's explicit
        # place for typing the participant's keys; elsewhere in the console letters are text
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.setMinimumSize(240, 150)
        self.setWindowTitle("Tactile Studio — participant")
        self.setAutoFillBackground(False)

    # ---- public -------------------------------------------------------------------
    def show_view(self, view: ParticipantView) -> None:
        """Draw ``view`` (cheap; called by the console's timer)."""
        if view != self.view:
            self.view = view
            self.update()

    def flash(self) -> None:
        """The visual beep: a bright overlay fading out."""
        self._anim.stop()
        self._anim.start()

    @property
    def flash_level(self) -> float:
        return self._flash

    def toggle_full_screen(self) -> None:
        if self.isFullScreen():
            self.showNormal()
        else:
            self.showFullScreen()

    def _set_flash(self, value: float) -> None:
        self._flash = float(value)
        self.update()

    # ---- input --------------------------------------------------------------------
    def keyPressEvent(self, event: QKeyEvent) -> None:  # noqa: N802 (Qt)
        if event.key() == Qt.Key.Key_F11 and not self.mirror:
            self.toggle_full_screen()
            return
        if event.key() == Qt.Key.Key_Escape and self.isFullScreen():
            self.showNormal()
            return
        text = event.text()
        if event.key() == Qt.Key.Key_Space:
            text = " "
        if text and not event.isAutoRepeat():
            self.keyPressed.emit(text)
            return
        super().keyPressEvent(event)

    def focusInEvent(self, event: object) -> None:  # noqa: N802 (Qt)
        super().focusInEvent(event)
        self.focusChanged.emit(True)
        self.update()

    def focusOutEvent(self, event: object) -> None:  # noqa: N802 (Qt)
        super().focusOutEvent(event)
        self.focusChanged.emit(False)
        self.update()

    # ---- painting -----------------------------------------------------------------
    def paintEvent(self, event: object) -> None:  # noqa: N802 (Qt)
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        p.setRenderHint(QPainter.RenderHint.TextAntialiasing)
        w, h = float(self.width()), float(self.height())
        if self.aspect:
            p.fillRect(self.rect(), SURROUND)
            if w / h > self.aspect:
                w = h * self.aspect
            else:
                h = w / self.aspect
            p.translate((self.width() - w) / 2, (self.height() - h) / 2)
        p.fillRect(QRectF(0, 0, w, h), BG)
        u = min(w / 1600.0, h / 900.0)  # 1 unit = 1 px on a 1600x900 screen
        v = self.view
        pad = 36 * u
        header_h = self._paint_header(p, QRectF(pad, pad * 0.6, w - 2 * pad, 64 * u), u)
        tag_h = 44 * u if v.pilot else 0.0  # the pilot tag's room at the bottom
        body = QRectF(pad, pad * 0.6 + header_h + 18 * u, w - 2 * pad,
                      h - (pad * 0.6 + header_h + 18 * u) - pad * 0.7 - tag_h)
        hint_h = 0.0
        if v.hint or v.footer:
            one_line = QFontMetricsF(_font(30 * u, bold=True)).horizontalAdvance(v.hint or v.footer)
            hint_h = (56 if one_line < w - 2 * pad - 80 * u else 92) * u
        if hint_h:
            self._paint_hint(p, QRectF(body.left(), body.bottom() - hint_h, body.width(),
                                       hint_h), u)
            body.setBottom(body.bottom() - hint_h - 10 * u)
        if v.mode == "waiting" and v.prompt is not None:
            prompt_h = body.height() * 0.6
            self._paint_prompt(p, QRectF(body.left(), body.top(), body.width(), prompt_h), u)
            strip = QRectF(body.left(), body.top() + prompt_h + 18 * u, body.width(),
                           body.height() - prompt_h - 18 * u)
            self._paint_cards(p, strip, u, compact=True)
        elif v.mode in ("waiting", "recording", "trial_end", "review", "block_start") and v.cards:
            stage_h = body.height() * (0.36 if v.mode in ("recording", "trial_end") else 0.22)
            if v.mode == "waiting" and any(self._readable(c) for c in v.cards):
                stage_h = body.height() * 0.16  # cards with images need the room for text
            self._paint_stage(p, QRectF(body.left(), body.top(), body.width(), stage_h), u)
            grid = QRectF(body.left(), body.top() + stage_h + 16 * u, body.width(),
                          body.height() - stage_h - 16 * u)
            self._paint_cards(p, grid, u, compact=v.mode != "waiting")
        else:
            self._paint_stage(p, body, u, big=True)
        if v.pilot:
            self._paint_pilot(p, w, h, u)
        if self._flash > 0:
            p.fillRect(QRectF(0, 0, w, h), QColor(255, 255, 255, int(200 * self._flash)))
        if self.mirror and self.hasFocus():  # keys typed now go to the session
            p.setPen(QPen(ACCENT, 4))
            p.setBrush(Qt.BrushStyle.NoBrush)
            p.drawRect(QRectF(2, 2, w - 4, h - 4))
        p.end()

    def _paint_pilot(self, p: QPainter, w: float, h: float, u: float) -> None:
        """A rehearsal is never taken for a session: an orange frame and a tag on the
        bottom edge, as PsychoPy's pilot mode marks its window."""
        edge = max(3.0, 8 * u)
        p.setPen(QPen(PILOT, edge))
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.drawRect(QRectF(edge / 2, edge / 2, w - edge, h - edge))
        text = "PILOT \u2013 rehearsal, not a participant's session"
        p.setFont(_font(22 * u, bold=True))
        tw = QFontMetricsF(p.font()).horizontalAdvance(text) + 36 * u
        tag = QRectF((w - tw) / 2, h - edge - 40 * u, tw, 40 * u)
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(PILOT)
        p.drawRoundedRect(tag, 8 * u, 8 * u)
        p.setPen(QColor("#1b1f2a"))
        p.drawText(tag, Qt.AlignmentFlag.AlignCenter, text)

    def _paint_header(self, p: QPainter, r: QRectF, u: float) -> float:
        v = self.view
        if not v.block_label:
            return 0.0
        p.setPen(TEXT)
        p.setFont(_font(34 * u, bold=True))
        p.drawText(r, Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, v.block_label)
        if v.n_in_block:
            # one dot per gesture of the block, filled when done
            d, gap = 20 * u, 12 * u
            total = v.n_in_block * d + (v.n_in_block - 1) * gap
            p.setFont(_font(26 * u))
            txt = f"{v.done_in_block} of {v.n_in_block} done"
            tw = QFontMetricsF(p.font()).horizontalAdvance(txt)
            x0 = r.right() - total - tw - 24 * u
            p.setPen(MUTED)
            p.drawText(QRectF(r.right() - tw, r.top(), tw, r.height()),
                       Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter, txt)
            cy = r.center().y()
            for i in range(v.n_in_block):
                x = x0 + i * (d + gap)
                dot = QRectF(x, cy - d / 2, d, d)
                if i < v.done_in_block:
                    p.setPen(Qt.PenStyle.NoPen)
                    p.setBrush(GOOD)
                else:
                    p.setPen(QPen(DIM, max(1.0, 2.5 * u)))
                    p.setBrush(Qt.BrushStyle.NoBrush)
                p.drawEllipse(dot)
        return r.height()

    def _paint_stage(self, p: QPainter, r: QRectF, u: float, big: bool = False) -> None:
        v = self.view
        p.setPen(Qt.PenStyle.NoPen)
        p.setBrush(PANEL)
        p.drawRoundedRect(r, 22 * u, 22 * u)
        inner = r.adjusted(36 * u, 20 * u, -36 * u, -20 * u)
        text_r = QRectF(inner)
        if v.countdown_s is not None:
            side = min(inner.height() * (0.66 if big else 1.0), inner.width() * 0.35)
            if big:
                dial = QRectF(inner.center().x() - side / 2, inner.bottom() - side - 12 * u,
                              side, side)
                text_r = QRectF(inner.left(), inner.top(), inner.width(),
                                inner.height() - side - 16 * u)
            else:
                dial = QRectF(inner.right() - side, inner.center().y() - side / 2, side, side)
                text_r = QRectF(inner.left(), inner.top(), inner.width() - side - 30 * u,
                                inner.height())
            self._paint_dial(p, dial, u)
        title_color = ACTIVE if v.mode in ("recording",) else TEXT
        if v.mode == "trial_end":
            title_color = GOOD
        align = Qt.AlignmentFlag.AlignHCenter if big else Qt.AlignmentFlag.AlignLeft
        sub_h = text_r.height() * 0.40 if v.subtitle else 0.0
        title_r = QRectF(text_r.left(), text_r.top(), text_r.width(), text_r.height() - sub_h)
        p.setPen(title_color)
        p.setFont(_fit_font(v.title, title_r, (110 if big else 70) * u, bold=True))
        valign = Qt.AlignmentFlag.AlignBottom if v.subtitle else Qt.AlignmentFlag.AlignVCenter
        p.drawText(title_r, int(align | valign | Qt.TextFlag.TextWordWrap),
                   v.title)
        if v.subtitle:
            sub_r = QRectF(text_r.left(), title_r.bottom() + 6 * u, text_r.width(), sub_h - 6 * u)
            p.setPen(MUTED)
            p.setFont(_fit_font(v.subtitle, sub_r, (40 if big else 32) * u))
            p.drawText(sub_r, int(align | Qt.AlignmentFlag.AlignTop | Qt.TextFlag.TextWordWrap),
                       v.subtitle)

    def _paint_prompt(self, p: QPainter, r: QRectF, u: float) -> None:
        card = self.view.prompt
        assert card is not None
        image = (lambda box: self._paint_image(p, box, card)) if self._readable(card) else None
        paint_prompt(p, r, u, card, self.view.subtitle, image)

    def _paint_dial(self, p: QPainter, r: QRectF, u: float) -> None:
        v = self.view
        left = max(0.0, v.countdown_s or 0.0)
        total = v.countdown_total_s or 0.0
        frac = min(1.0, left / total) if total > 0 else 0.0
        width = max(3.0, r.width() * 0.075)
        ring = r.adjusted(width / 2, width / 2, -width / 2, -width / 2)
        p.setBrush(Qt.BrushStyle.NoBrush)
        p.setPen(QPen(DIM, width, Qt.PenStyle.SolidLine, Qt.PenCapStyle.FlatCap))
        p.drawEllipse(ring)
        color = ACTIVE if v.mode == "recording" else ACCENT
        if v.mode == "trial_end":
            color = GOOD
        if frac > 0:
            p.setPen(QPen(color, width, Qt.PenStyle.SolidLine, Qt.PenCapStyle.RoundCap))
            p.drawArc(ring, 90 * 16, -int(360 * 16 * frac))  # clockwise from 12
        if left >= 60:
            txt = f"{int(left) // 60}:{int(left) % 60:02d}"
        elif total >= 5:
            txt = f"{math.ceil(left - 1e-9):d}"
        else:
            txt = f"{left:.1f}"
        p.setPen(TEXT)
        m = width * 1.6
        p.setFont(_fit_font(txt, ring.adjusted(m, m, -m, -m), r.height() * 0.32,
                            bold=True, wrap=False))
        p.drawText(ring, Qt.AlignmentFlag.AlignCenter, txt)

    def _paint_hint(self, p: QPainter, r: QRectF, u: float) -> None:
        v = self.view
        if v.hint:
            p.setPen(Qt.PenStyle.NoPen)
            p.setBrush(QColor(WARN.red(), WARN.green(), WARN.blue(), 40))
            p.drawRoundedRect(r, 14 * u, 14 * u)
            p.setPen(WARN)
            text, bold, px = v.hint, True, 30 * u
        else:
            p.setPen(MUTED)
            text, bold, px = v.footer, False, 28 * u
        inner = r.adjusted(32 * u, 6 * u, -32 * u, -6 * u)
        p.setFont(_fit_font(text, inner, px, bold=bold))
        p.drawText(inner, int(Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap), text)
