"""The live screen's session: the main window's :class:`AcquisitionSession`.

The verbs (connect, tare, record, stream to LSL) and the auto-stop live in
:mod:`tactile_studio.live.session`; this name is what the main window, the device panel
and the wizards are handed.
"""

from __future__ import annotations

from tactile_studio.live.session import AcquisitionSession


class LiveController(AcquisitionSession):
    """The main window's acquisition session (one device at a time, reconnectable)."""

    compress_in_background = True  # stopping a recording must not freeze the window


__all__ = ["LiveController"]
