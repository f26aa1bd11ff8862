"""Draw the shear9 gesture pictograms (one PNG per gesture) with QPainter.

``QT_QPA_PLATFORM=offscreen .venv/bin/python tools/make_protocol_images.py
[OUT_DIR]`` (default: this folder) rewrites the nine PNGs that shear9.toml references.
Each is a top view of the sensor pad with a right hand (palm down, wrist at the bottom)
and the motion in amber, so the participant can tell the gestures apart at a glance.
Drawn procedurally so they can be regenerated and restyled without any download.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

from PySide6 import QtCore, QtGui

SIZE = 256
PAD = "#323a4d"
PAD_EDGE = "#4a5368"
GRID = "#414a5f"
SKIN_MOVED = "#8fa3c8"
HAND = "#eef1f6"
HAND_EDGE = "#141821"
MOTION = "#ffb547"
CONTACT = "#5b9bff"
FINGER_X = (-25.0, -8.5, 8.5, 25.0)       # index, middle, ring, little (right hand, palm down)
FINGER_LEN = (50.0, 56.0, 50.0, 38.0)


class Pose:
    """Where the hand is and which fingers are out; lengths are fractions of full."""

    def __init__(self, x: float = 128, y: float = 182, angle: float = 0.0,
                 fingers: tuple[float, float, float, float] = (1, 1, 1, 1),
                 thumb: float = 0.6, thumb_angle: float = -35.0, spread: float = 0.0,
                 scale: float = 1.0) -> None:
        self.x, self.y, self.angle = x, y, angle
        self.fingers, self.thumb, self.thumb_angle = fingers, thumb, thumb_angle
        self.spread, self.scale = spread, scale

    def transform(self) -> QtGui.QTransform:
        t = QtGui.QTransform()
        t.translate(self.x, self.y)
        t.rotate(self.angle)
        t.scale(self.scale, self.scale)
        return t

    def tip(self, i: int) -> tuple[float, float]:
        """Fingertip ``i`` (0 index .. 3 little; 4 thumb) in image coordinates."""
        if i == 4:
            a = math.radians(self.thumb_angle - 90)
            length = 14 + 40 * self.thumb
            x, y = -30 + math.cos(a) * length, 4 + math.sin(a) * length
        else:
            a = math.radians((i - 1.5) * self.spread - 90)
            length = 8 + (FINGER_LEN[i] - 8) * self.fingers[i]
            x = FINGER_X[i] + math.cos(a) * (length - 6)
            y = -33 + math.sin(a) * (length - 6)
        p = self.transform().map(QtCore.QPointF(x, y))
        return p.x(), p.y()


def _capsule(x0: float, y0: float, angle_deg: float, length: float,
             width: float) -> QtGui.QPainterPath:
    path = QtGui.QPainterPath()
    path.addRoundedRect(QtCore.QRectF(-width / 2, -length, width, length + width / 2),
                        width / 2, width / 2)
    t = QtGui.QTransform()
    t.translate(x0, y0)
    t.rotate(angle_deg)
    return t.map(path)


def hand_path(pose: Pose) -> QtGui.QPainterPath:
    path = QtGui.QPainterPath()
    path.addRoundedRect(QtCore.QRectF(-36, -38, 72, 74), 20, 20)       # palm
    arm = QtGui.QPainterPath()
    arm.addRoundedRect(QtCore.QRectF(-27, 20, 54, 120), 12, 12)        # wrist, forearm
    path = path.united(arm)
    for i, frac in enumerate(pose.fingers):
        length = 8 + (FINGER_LEN[i] - 8) * frac
        path = path.united(_capsule(FINGER_X[i], -30, (i - 1.5) * pose.spread, length,
                                    15.5 if i < 3 else 14.0))
    thumb = _capsule(-30, 4, pose.thumb_angle, 14 + 40 * pose.thumb, 17)
    path = path.united(thumb).simplified()
    return pose.transform().map(path)


class Canvas:
    """One pictogram: the pad, then hands and marks, clipped to the pad."""

    def __init__(self) -> None:
        self.image = QtGui.QImage(SIZE, SIZE, QtGui.QImage.Format.Format_ARGB32_Premultiplied)
        self.image.fill(QtCore.Qt.GlobalColor.transparent)
        self.p = QtGui.QPainter(self.image)
        self.p.setRenderHint(QtGui.QPainter.RenderHint.Antialiasing)
        self.pad = QtGui.QPainterPath()
        self.pad.addRoundedRect(QtCore.QRectF(6, 6, SIZE - 12, SIZE - 12), 30, 30)

    def pad_grid(self, warp: Callable[[float, float], tuple[float, float]] | None = None) -> None:
        """The pad with its taxel grid; ``warp`` moves grid points (skin dragged along)."""
        p = self.p
        p.fillPath(self.pad, QtGui.QColor(PAD))
        p.save()
        p.setClipPath(self.pad)
        plain = QtGui.QPen(QtGui.QColor(GRID), 2.0)
        moved = QtGui.QPen(QtGui.QColor(SKIN_MOVED), 2.5)
        for fixed in (20 + 24 * k for k in range(10)):
            for vertical in (False, True):
                prev = None
                for s in range(0, SIZE + 1, 4):
                    x, y = (fixed, s) if vertical else (s, fixed)
                    wx, wy = warp(x, y) if warp is not None else (x, y)
                    if prev is not None:
                        p.setPen(moved if abs(wx - x) + abs(wy - y) > 3 else plain)
                        p.drawLine(QtCore.QPointF(*prev), QtCore.QPointF(wx, wy))
                    prev = (wx, wy)
        p.restore()

    def hand(self, pose: Pose, alpha: float = 1.0) -> None:
        p = self.p
        p.save()
        p.setClipPath(self.pad)
        p.setOpacity(alpha)
        fill = QtGui.QColor(HAND)
        p.setBrush(fill)
        p.setPen(QtGui.QPen(QtGui.QColor(HAND_EDGE), 3.0))
        p.drawPath(hand_path(pose))
        p.restore()

    def glow(self, pose: Pose) -> None:
        """Soft contact shading under a hand resting flat on the pad."""
        p = self.p
        p.save()
        p.setClipPath(self.pad)
        path = hand_path(pose)
        for width, alpha in ((26, 40), (16, 70), (8, 110)):
            p.setPen(QtGui.QPen(QtGui.QColor(91, 155, 255, alpha), width,
                                QtCore.Qt.PenStyle.SolidLine, QtCore.Qt.PenCapStyle.RoundCap,
                                QtCore.Qt.PenJoinStyle.RoundJoin))
            p.setBrush(QtCore.Qt.BrushStyle.NoBrush)
            p.drawPath(path)
        p.restore()

    def _pen(self, color: str = MOTION, width: float = 7.0) -> QtGui.QPen:
        return QtGui.QPen(QtGui.QColor(color), width, QtCore.Qt.PenStyle.SolidLine,
                          QtCore.Qt.PenCapStyle.RoundCap, QtCore.Qt.PenJoinStyle.RoundJoin)

    def _head(self, x: float, y: float, angle: float, size: float = 16,
              color: str = MOTION) -> None:
        """A filled arrowhead at (x, y) pointing along ``angle`` (radians)."""
        pts = [QtCore.QPointF(x + math.cos(angle) * size * 0.55,
                              y + math.sin(angle) * size * 0.55)]
        for side in (-1, 1):
            a = angle + side * 2.5
            pts.append(QtCore.QPointF(x + math.cos(a) * size * 0.75, y + math.sin(a) * size * 0.75))
        self.p.setPen(QtGui.QPen(QtGui.QColor(HAND_EDGE), 2.0))
        self.p.setBrush(QtGui.QColor(color))
        self.p.drawPolygon(QtGui.QPolygonF(pts))

    def arrow(self, x0: float, y0: float, x1: float, y1: float, both: bool = False,
              width: float = 7.0) -> None:
        a = math.atan2(y1 - y0, x1 - x0)
        back = 9
        sx, sy = (x0 + math.cos(a) * back, y0 + math.sin(a) * back) if both else (x0, y0)
        self._outlined_line([(sx, sy), (x1 - math.cos(a) * back, y1 - math.sin(a) * back)],
                            width)
        self._head(x1, y1, a, size=width * 3.2)
        if both:
            self._head(x0, y0, a + math.pi, size=width * 3.2)

    def arc_arrow(self, cx: float, cy: float, rx: float, ry: float, start_deg: float,
                  span_deg: float, width: float = 7.0) -> None:
        """An elliptical arc with an arrowhead at its end (clockwise for negative span)."""
        n = 48
        pts = []
        for k in range(n + 1):
            t = math.radians(start_deg + span_deg * k / n)
            pts.append((cx + rx * math.cos(t), cy - ry * math.sin(t)))
        self._outlined_line(pts[:-3], width)
        (xa, ya), (xb, yb) = pts[-4], pts[-1]
        self._head(xb, yb, math.atan2(yb - ya, xb - xa), size=width * 3.2)

    def _outlined_line(self, pts: list[tuple[float, float]], width: float,
                       color: str = MOTION) -> None:
        poly = QtGui.QPolygonF([QtCore.QPointF(x, y) for x, y in pts])
        self.p.setBrush(QtCore.Qt.BrushStyle.NoBrush)
        self.p.setPen(self._pen(HAND_EDGE, width + 4))
        self.p.drawPolyline(poly)
        self.p.setPen(self._pen(color, width))
        self.p.drawPolyline(poly)

    def dashed(self, x0: float, y0: float, x1: float, y1: float) -> None:
        pen = QtGui.QPen(QtGui.QColor(SKIN_MOVED), 3.0, QtCore.Qt.PenStyle.DashLine,
                         QtCore.Qt.PenCapStyle.RoundCap)
        self.p.setPen(pen)
        self.p.drawLine(QtCore.QPointF(x0, y0), QtCore.QPointF(x1, y1))

    def rings(self, x: float, y: float, radii: tuple[float, ...] = (16, 27),
              color: str = MOTION) -> None:
        self.p.setBrush(QtCore.Qt.BrushStyle.NoBrush)
        for r in radii:
            self.p.setPen(self._pen(color, 4.5))
            self.p.drawEllipse(QtCore.QPointF(x, y), r, r)

    def dot(self, x: float, y: float, r: float = 7, color: str = CONTACT) -> None:
        self.p.setPen(QtGui.QPen(QtGui.QColor(HAND_EDGE), 2.0))
        self.p.setBrush(QtGui.QColor(color))
        self.p.drawEllipse(QtCore.QPointF(x, y), r, r)

    def squiggle(self, x: float, y: float, angle_deg: float, length: float = 26) -> None:
        a = math.radians(angle_deg)
        pts = []
        for k in range(13):
            s = length * k / 12
            off = 5 * math.sin(k * math.pi / 2)
            pts.append((x + math.cos(a) * s - math.sin(a) * off,
                        y + math.sin(a) * s + math.cos(a) * off))
        self._outlined_line(pts, 4.0)

    def strokes(self, lines: list[tuple[float, float, float, float]]) -> None:
        for x0, y0, x1, y1 in lines:
            self._outlined_line([(x0, y0), (x1, y1)], 5.0)

    def edge(self) -> None:
        self.p.setBrush(QtCore.Qt.BrushStyle.NoBrush)
        self.p.setPen(QtGui.QPen(QtGui.QColor(PAD_EDGE), 3.0))
        self.p.drawPath(self.pad)

    def save(self, path: Path) -> None:
        self.edge()
        self.p.end()
        if not self.image.save(str(path), "PNG"):
            raise OSError(f"{path}: could not write the PNG")


# ---- the nine gestures --------------------------------------------------------------------
def poke(c: Canvas) -> None:
    c.pad_grid()
    pose = Pose(x=138, y=196, fingers=(1, 0.12, 0.12, 0.12), thumb=0.15, thumb_angle=20)
    x, y = pose.tip(0)
    c.rings(x, y - 2)
    c.hand(pose)
    c.dot(x, y - 2)


def wide_pinch(c: Canvas) -> None:
    c.pad_grid()
    pose = Pose(x=164, y=194, angle=4, fingers=(1, 0.15, 0.15, 0.15), thumb=1.05,
                thumb_angle=-72)
    (ix, iy), (tx, ty) = pose.tip(0), pose.tip(4)
    length = math.hypot(ix - tx, iy - ty)
    ux, uy = (ix - tx) / length, (iy - ty) / length  # thumb -> index
    c.dashed(tx + ux * 12, ty + uy * 12, ix - ux * 12, iy - uy * 12)  # the skin squeezed
    c.hand(pose)
    for (x, y), sign in (((ix, iy), 1), ((tx, ty), -1)):  # from outside, pointing inwards
        c.arrow(x + sign * ux * 54, y + sign * uy * 54, x + sign * ux * 12, y + sign * uy * 12)
    c.dot(ix, iy)
    c.dot(tx, ty)


def heavy_pat(c: Canvas) -> None:
    c.pad_grid()
    pose = Pose(x=128, y=172, fingers=(1, 1, 1, 1), thumb=0.85, thumb_angle=-50,
                spread=2)
    c.hand(pose)
    c.strokes([(50, 112, 30, 100), (46, 140, 24, 140), (52, 168, 32, 180),
               (206, 112, 226, 100), (210, 140, 232, 140), (204, 168, 224, 180),
               (100, 50, 94, 28), (128, 44, 128, 22), (156, 50, 162, 28)])


def _centroid(pose: Pose) -> tuple[float, float]:
    tips = [pose.tip(i) for i in range(4)]
    return sum(x for x, _ in tips) / 4, sum(y for _, y in tips) / 4


def twist(c: Canvas) -> None:
    c.pad_grid()
    shape = {"fingers": (0.75, 0.8, 0.75, 0.6), "thumb": 0.5, "thumb_angle": -20.0}
    pose = Pose(x=122, y=196, angle=-14, **shape)
    cx, cy = _centroid(pose)
    ghost = Pose(x=122, y=196, angle=22, **shape)  # turned about the fingertips
    gx, gy = _centroid(ghost)
    ghost.x, ghost.y = ghost.x + cx - gx, ghost.y + cy - gy
    c.hand(ghost, 0.22)
    c.hand(pose)
    for i in range(4):
        c.dot(*pose.tip(i), 5.5)
    c.arc_arrow(cx, cy + 6, 64, 46, 200, -230)


def back_forth_rub(c: Canvas) -> None:
    c.pad_grid()
    for dx, alpha in ((-40, 0.2), (40, 0.2)):
        c.hand(Pose(x=128 + dx, y=186, fingers=(1, 1, 0.3, 0.2), thumb=0.3, thumb_angle=0),
               alpha)
    pose = Pose(x=128, y=186, fingers=(1, 1, 0.3, 0.2), thumb=0.3, thumb_angle=0)
    c.hand(pose)
    y = min(pose.tip(0)[1], pose.tip(1)[1]) - 24
    c.arrow(36, y, 220, y, both=True)


def isometric_rub(c: Canvas) -> None:
    pose = Pose(x=128, y=190, fingers=(1, 1, 0.3, 0.2), thumb=0.3, thumb_angle=0)
    (ax, ay), (bx, by) = pose.tip(0), pose.tip(1)
    fx, fy = (ax + bx) / 2, (ay + by) / 2

    def warp(x: float, y: float) -> tuple[float, float]:  # skin dragged with the fingers
        d2 = ((x - fx) / 60) ** 2 + ((y - fy) / 46) ** 2
        return x + 20 * math.exp(-d2), y

    c.pad_grid(warp)
    c.hand(pose)
    y = fy - 34
    c.arrow(fx - 30, y, fx + 30, y, both=True)


def circular_stroke(c: Canvas) -> None:
    c.pad_grid()
    pose = Pose(x=150, y=200, angle=-6, fingers=(1, 1, 0.3, 0.2), thumb=0.3, thumb_angle=0)
    (ax, ay), (bx, by) = pose.tip(0), pose.tip(1)
    fx, fy = (ax + bx) / 2, (ay + by) / 2
    c.arc_arrow(fx - 34, fy - 22, 50, 40, -30, 320)
    c.hand(pose)
    c.dot(ax, ay, 5.5)
    c.dot(bx, by, 5.5)


def constant_touch(c: Canvas) -> None:
    c.pad_grid()
    pose = Pose(x=128, y=172, fingers=(1, 1, 1, 1), thumb=0.85, thumb_angle=-50, spread=2)
    c.glow(pose)
    c.hand(pose)


def tickle(c: Canvas) -> None:
    c.pad_grid()
    pose = Pose(x=128, y=196, fingers=(0.7, 0.75, 0.7, 0.6), thumb=0.35, thumb_angle=-10,
                spread=9)
    c.hand(pose)
    for i, ang in zip(range(4), (-120, -100, -80, -60)):
        x, y = pose.tip(i)
        c.dot(x, y, 5)
        c.squiggle(x + math.cos(math.radians(ang)) * 12, y + math.sin(math.radians(ang)) * 12,
                   ang, 28)


IMAGES: dict[str, Callable[[Canvas], None]] = {
    "poke.png": poke, "wide-pinch.png": wide_pinch, "heavy-pat.png": heavy_pat,
    "twist.png": twist, "back-forth-rub.png": back_forth_rub,
    "isometric-rub.png": isometric_rub, "circular-stroke.png": circular_stroke,
    "constant-touch.png": constant_touch, "tickle.png": tickle,
}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else (Path(__file__).resolve().parents[1] / "resources"
                                      / "protocols" / "images")
    out.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    app = QtGui.QGuiApplication.instance() or QtGui.QGuiApplication([])  # noqa: F841 (painting)
    for name, draw in IMAGES.items():
        c = Canvas()
        draw(c)
        c.save(out / name)
        print(out / name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
