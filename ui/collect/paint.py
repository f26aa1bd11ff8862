"""Painting shared by the collection screens: the palette, fitted fonts, and the large
card of the prompted gesture (the participant screen's "NEXT GESTURE").

Sizes are in units ``u`` (1 unit = 1 px on a 1600x900 screen), so the same code draws
the full-screen participant monitor and the console's small mirror.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QRectF, Qt
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPainter, QPainterPath, QPen

BG = QColor("#1b1f2a")
SURROUND = QColor("#0e1016")
PANEL = QColor("#262c3b")
PANEL_DONE = QColor("#20242f")
TEXT = QColor("#f3f5f9")
MUTED = QColor("#aab2c3")
DIM = QColor("#5d6577")
ACCENT = QColor("#5b9bff")
ACTIVE = QColor("#ffb547")
GOOD = QColor("#46c98b")
WARN = QColor("#ff7a66")
PILOT = QColor("#ff8c1a")  # a rehearsal's frame and tag (the console's pilot banner too)



def _font(px: float, bold: bool = False) -> QFont:
    f = QFont()
    f.setPixelSize(max(6, int(px)))
    f.setBold(bold)
    return f


def _fit_font(text: str, rect: QRectF, px: float, bold: bool = False,
              wrap: bool = True, min_px: float = 7) -> QFont:
    """The largest font up to ``px`` in which ``text`` fits ``rect``."""
    flags = int(Qt.TextFlag.TextWordWrap) if wrap else 0
    while px > min_px:
        f = _font(px, bold)
        br = QFontMetricsF(f).boundingRect(rect, flags, text)
        if br.width() <= rect.width() + 0.5 and br.height() <= rect.height() + 0.5:
            return f
        px *= 0.92
    return _font(min_px, bold)



def paint_prompt(p: QPainter, r: QRectF, u: float, card: Any, how: str,
                 paint_image: Callable[[QRectF], None] | None = None) -> None:
    """The prompted gesture as one large card outlined in amber: "NEXT GESTURE", its key
    in a large badge, its name, ``how`` (how to start it), its definition, and its image
    at the right (drawn by ``paint_image(box)`` when there is one)."""
    p.setBrush(PANEL)
    p.setPen(QPen(ACTIVE, max(2.0, 6 * u)))
    p.drawRoundedRect(r, 22 * u, 22 * u)
    pad = 34 * u
    inner = r.adjusted(pad, pad * 0.8, -pad, -pad * 0.8)
    if paint_image is not None:
        side = min(inner.height(), inner.width() * 0.3)
        paint_image(QRectF(inner.right() - side, inner.center().y() - side / 2, side, side))
        inner.setRight(inner.right() - side - pad)
    label_h = 40 * u
    p.setPen(ACTIVE)
    p.setFont(_font(30 * u, bold=True))
    p.drawText(QRectF(inner.left(), inner.top(), inner.width(), label_h),
               Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, "NEXT GESTURE")
    top = inner.top() + label_h + 10 * u
    badge = min((inner.bottom() - top) * 0.5, 190 * u)
    b = QRectF(inner.left(), top, badge, badge)
    path = QPainterPath()
    path.addRoundedRect(b, 18 * u, 18 * u)
    p.fillPath(path, ACTIVE)
    p.setPen(QColor("#10131a"))
    key_txt = card.key.upper()
    p.setFont(_fit_font(key_txt, b.adjusted(6, 6, -6, -6), badge * 0.7, bold=True, wrap=False))
    p.drawText(b, Qt.AlignmentFlag.AlignCenter, key_txt)
    text_l = b.right() + pad
    name_r = QRectF(text_l, top, inner.right() - text_l, badge * 0.62)
    p.setPen(TEXT)
    p.setFont(_fit_font(card.name, name_r, 110 * u, bold=True))
    p.drawText(name_r, int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter
                           | Qt.TextFlag.TextWordWrap), card.name)
    how_r = QRectF(text_l, name_r.bottom(), name_r.width(), badge - name_r.height())
    p.setPen(MUTED)
    p.setFont(_fit_font(how, how_r, 34 * u))
    p.drawText(how_r, int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter
                          | Qt.TextFlag.TextWordWrap), how)
    if card.definition:
        d = QRectF(inner.left(), b.bottom() + 20 * u, inner.width(),
                   inner.bottom() - b.bottom() - 20 * u)
        if d.height() > 8:
            p.setPen(TEXT)
            p.setFont(_fit_font(card.definition, d, 42 * u))
            p.drawText(d, int(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop
                              | Qt.TextFlag.TextWordWrap), card.definition)
