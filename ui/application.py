"""The one QApplication, made with our names: a small module at the bottom of ui, so any
window (the main window, the collection console, a wizard) can start the app without
importing the main window's launcher (which imports them)."""

from __future__ import annotations

import sys

from PySide6.QtWidgets import QApplication

from tactile_studio.ui.settings import APPLICATION, ORGANISATION


def ensure_app(argv: list[str] | None = None) -> QApplication:
    """The running QApplication, created (with our names) if there is none."""
    app = QApplication.instance()
    if app is None:
        # The device, recorder and GUI threads share the GIL: hand it over every 1 ms
        # (not 5 ms) so the display timer is not starved by a 1 kHz device thread.
        sys.setswitchinterval(0.001)
        app = QApplication(argv if argv is not None else sys.argv[:1])
        app.setOrganizationName(ORGANISATION)
        app.setApplicationName(APPLICATION)
    return app  # type: ignore[return-value]
