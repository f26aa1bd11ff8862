"""The participant screen's gesture cards: the grid of the block's gestures, each with
its key badge, name, definition and (when it can be read) its image at the right.

A mixin of :class:`~tactile_studio.ui.collect.participant.ParticipantScreen` (it uses the
screen's image caches ``_sources`` / ``_scaled``), plus the :class:`Card` data it draws.
Sizes are in units ``u`` as in :mod:`tactile_studio.ui.collect.paint`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

from PySide6.QtCore import QRectF, QSize, Qt
from PySide6.QtGui import (
    QColor,
    QImage,
    QImageReader,
    QPainter,
    QPainterPath,
    QPen,
    QPixmap,
)

from tactile_studio.ui.collect.paint import (
    ACCENT,
    ACTIVE,
    DIM,
    GOOD,
    MUTED,
    PANEL,
    PANEL_DONE,
    TEXT,
    _fit_font,
    _font,
)

log = logging.getLogger("tactile_studio.ui.collect.participant")


@dataclass
class Card:
    """One gesture of the block as shown to the participant."""

    key: str
    name: str
    definition: str = ""
    done: bool = False
    active: bool = False
    image: str | None = None  # file path; drawn at the card's right when it can be read
    note: str = ""            # "next" / "upcoming" under the name of a compact card


def _grid(n: int, w: float, h: float, aspect: float = 2.1) -> tuple[int, int]:
    """Columns and rows that make ``n`` cards of about ``aspect`` as large as possible."""
    best, best_size = (1, n), -1.0
    for cols in range(1, n + 1):
        rows = math.ceil(n / cols)
        cw, ch = w / cols, h / rows
        size = min(cw, ch * aspect)
        if size > best_size + 1e-6:
            best, best_size = (cols, rows), size
    return best


class CardPainting:
    """Painting of the gesture cards (mixin of the participant screen)."""

    _sources: dict[str, QImage | None]
    _scaled: dict[tuple[str, int, int], QPixmap]

    def _paint_cards(self, p: QPainter, r: QRectF, u: float, compact: bool = False) -> None:
        """The block's gestures; ``compact`` (during a trial) leaves out the definitions."""
        cards = self.view.cards
        if compact:
            cards = [replace(c, definition="") for c in cards]
        cols, rows = _grid(len(cards), r.width(), r.height())
        gap = 18 * u
        cw = (r.width() - gap * (cols - 1)) / cols
        ch = (r.height() - gap * (rows - 1)) / rows
        ch = min(ch, cw / 1.4)
        rects = []
        for i in range(len(cards)):
            row, col = divmod(i, cols)
            rects.append(QRectF(r.left() + col * (cw + gap), r.top() + row * (ch + gap), cw, ch))
        # one definition font for all cards (the largest in which every one fits), so
        # the cards read as one set
        def_px = min(30 * u, ch * 0.16)
        for card, cr in zip(cards, rects):
            if card.definition and not card.done:
                f = _fit_font(card.definition, self._definition_rect(cr, card, u), def_px)
                def_px = min(def_px, float(f.pixelSize()))
        for card, cr in zip(cards, rects):
            self._paint_card(p, cr, card, u, def_px)

    @staticmethod
    def _badge_side(r: QRectF, u: float) -> float:
        return min(r.height() * 0.32, 84 * u)

    def _image_rect(self, r: QRectF, c: Card, u: float) -> QRectF | None:
        """Where the card's image goes (a square at the right), None without one."""
        if not self._readable(c):
            return None
        pad = 18 * u
        side = min(r.height() - 2 * pad, r.width() * 0.23)
        if side < 16:
            return None
        return QRectF(r.right() - pad - side, r.center().y() - side / 2, side, side)

    def _text_right(self, r: QRectF, c: Card, u: float) -> float:
        img = self._image_rect(r, c, u)
        return r.right() - 18 * u if img is None else img.left() - 16 * u

    def _definition_rect(self, r: QRectF, c: Card, u: float) -> QRectF:
        pad = 18 * u
        top = r.top() + pad + self._badge_side(r, u) + pad * 0.7
        return QRectF(r.left() + pad, top, self._text_right(r, c, u) - r.left() - pad,
                      r.bottom() - pad * 0.8 - top)

    # ---- images -----------------------------------------------------------------------
    def _readable(self, c: Card) -> bool:
        return bool(c.image) and self._source(c.image or "") is not None

    def _source(self, path: str) -> QImage | None:
        if path not in self._sources:
            image = QImage(path)
            if image.isNull():
                log.warning("participant screen: cannot read gesture image %s", path)
            self._sources[path] = None if image.isNull() else image
        return self._sources[path]

    def _pixmap(self, path: str, box: QRectF) -> QPixmap | None:
        """``path`` scaled to fit ``box`` (aspect kept, device pixels), cached per size."""
        source = self._source(path)
        if source is None:
            return None
        dpr = self.devicePixelRatioF()
        key = (path, round(box.width() * dpr), round(box.height() * dpr))
        pm = self._scaled.get(key)
        if pm is None:
            if len(self._scaled) > 64:  # resized many times: start over
                self._scaled.clear()
            size = source.size().scaled(QSize(key[1], key[2]), Qt.AspectRatioMode.KeepAspectRatio)
            if path.lower().endswith(".svg"):  # vector: render at the size, not upscale
                reader = QImageReader(path)
                reader.setScaledSize(size)
                image = reader.read()
            else:
                image = source.scaled(size, Qt.AspectRatioMode.KeepAspectRatio,
                                      Qt.TransformationMode.SmoothTransformation)
            pm = QPixmap.fromImage(image)
            pm.setDevicePixelRatio(dpr)
            self._scaled[key] = pm
        return pm

    def _paint_image(self, p: QPainter, box: QRectF, c: Card) -> None:
        pm = self._pixmap(c.image or "", box)
        if pm is None:
            return
        dpr = pm.devicePixelRatio()
        w, h = pm.width() / dpr, pm.height() / dpr
        p.save()
        if c.done:
            p.setOpacity(0.3)
        p.drawPixmap(QRectF(box.center().x() - w / 2, box.center().y() - h / 2, w, h), pm,
                     QRectF(pm.rect()))
        p.restore()

    def _paint_card(self, p: QPainter, r: QRectF, c: Card, u: float, def_px: float) -> None:
        radius = 16 * u
        p.setBrush(PANEL_DONE if c.done else PANEL)
        if c.active:
            p.setPen(QPen(ACTIVE, max(2.0, 5 * u)))
        else:
            p.setPen(Qt.PenStyle.NoPen)
        p.drawRoundedRect(r, radius, radius)
        pad = 18 * u
        badge = self._badge_side(r, u)
        b = QRectF(r.left() + pad, r.top() + pad, badge, badge)
        path = QPainterPath()
        path.addRoundedRect(b, 12 * u, 12 * u)
        key_bg = GOOD if c.done else (ACTIVE if c.active else ACCENT)
        p.fillPath(path, key_bg if not c.done else QColor(GOOD.red(), GOOD.green(),
                                                           GOOD.blue(), 70))
        p.setPen(QColor("#10131a") if not c.done else GOOD)
        key_txt = "\u2713" if c.done else c.key.upper()
        p.setFont(_fit_font(key_txt, b.adjusted(4, 4, -4, -4), badge * 0.62, bold=True,
                            wrap=False))
        p.drawText(b, Qt.AlignmentFlag.AlignCenter, key_txt)
        img = self._image_rect(r, c, u)
        if img is not None:
            self._paint_image(p, img, c)
        name_r = QRectF(b.right() + pad, r.top() + pad,
                        self._text_right(r, c, u) - b.right() - pad, badge)
        p.setPen(DIM if c.done else TEXT)
        p.setFont(_fit_font(c.name, name_r, badge * 0.5, bold=True))
        p.drawText(name_r, int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter
                               | Qt.TextFlag.TextWordWrap), c.name)
        if c.done:
            p.setFont(_font(min(def_px, badge * 0.34)))
            p.drawText(QRectF(name_r.left(), name_r.bottom() + 2, name_r.width(), def_px * 2),
                       Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop,
                       f"key {c.key.upper()}  \u00b7  done")
            return
        if c.note and not c.definition:
            p.setPen(ACTIVE if c.active else MUTED)
            note = f"key {c.key.upper()}  \u00b7  {c.note}"
            note_r = QRectF(name_r.left(), name_r.bottom() + 2, name_r.width(), def_px * 2)
            p.setFont(_fit_font(note, note_r, min(def_px, badge * 0.34), bold=c.active,
                                wrap=False))
            p.drawText(note_r, Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop, note)
        if c.definition:
            d = self._definition_rect(r, c, u)
            if d.height() > 6:
                p.setPen(MUTED)
                p.setFont(_font(def_px))
                p.drawText(d, int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop
                                  | Qt.TextFlag.TextWordWrap), c.definition)
