"""Windows that write files: a place that cannot be written is one line, never a traceback.

The GUI's side of ``tactile_studio.output_faults`` (which the CLI's ``main()`` uses):
an action that writes catches ``OSError`` and ``UserError`` and hands them to
:func:`fault_text` (for its own status line) or :func:`show_write_fault` (a message
box); anything that is not a fault of the place is re-raised by the caller. Images are
encoded in memory and written with Python (:func:`write_image`), because Qt's own
``save()`` only answers False and the user would never learn why.
"""

from __future__ import annotations

import os
from pathlib import Path

from PySide6.QtCore import QBuffer, QByteArray, QIODevice, Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import QMessageBox, QWidget

from tactile_studio.errors import UserError
from tactile_studio.output_faults import fault_line


def fault_text(exc: BaseException) -> str | None:
    """The one line for a write that failed because of the place or the user's input;
    None for a programming error (the caller re-raises it)."""
    if isinstance(exc, UserError):
        return " ".join(str(exc).split()) or type(exc).__name__
    return fault_line(exc)


def show_write_fault(parent: QWidget, title: str, exc: BaseException) -> QMessageBox | None:
    """Show ``exc`` as one line in a (non-blocking) message box over ``parent``; None
    when it is not a write fault (re-raise it)."""
    text = fault_text(exc)
    if text is None:
        return None
    box = QMessageBox(QMessageBox.Icon.Warning, title, text, QMessageBox.StandardButton.Ok,
                      parent)
    box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    box.open()
    return box


def encoded_image(image: QImage | QPixmap, fmt: str = "PNG") -> bytes:
    """``image`` encoded as ``fmt`` in memory (empty when Qt cannot encode that format)."""
    data = QByteArray()
    buffer = QBuffer(data)
    buffer.open(QIODevice.OpenModeFlag.WriteOnly)
    ok = image.save(buffer, fmt)
    buffer.close()
    return bytes(data.data()) if ok else b""


def write_image(image: QImage | QPixmap, path: str | os.PathLike) -> Path:
    """Write ``image`` to ``path`` in the format its suffix names (PNG without one); an
    unwritable place raises the real ``OSError`` (errno and file), an unknown format a
    ``UserError``."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").upper() or "PNG"
    data = encoded_image(image, fmt)
    if not data:
        raise UserError(f"{path}: cannot encode an image as {fmt} (use a .png name)")
    path.write_bytes(data)
    return path
