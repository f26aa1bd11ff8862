"""Where the GUI keeps its preferences, overridable so tests never touch the user's.

Set ``TACTILE_STUDIO_SETTINGS=/some/file.ini`` to use that INI file instead of the
platform's store for organisation "TactileStudio", application "Tactile Studio". Under
``TACTILE_STUDIO_TESTING=1`` (set by tests/conftest.py) without an explicit file, a
per-process file in the temp folder is used, so a test can never touch real settings.
"""

from __future__ import annotations

import json
import os
import tempfile
from importlib import resources
from typing import Any

from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QComboBox

ORGANISATION = "TactileStudio"
APPLICATION = "Tactile Studio"
SETTINGS_ENV = "TACTILE_STUDIO_SETTINGS"


def app_settings() -> QSettings:
    """The app's QSettings (an INI file at $TACTILE_STUDIO_SETTINGS when set)."""
    path = os.environ.get(SETTINGS_ENV)
    if not path and os.environ.get("TACTILE_STUDIO_TESTING"):
        path = os.path.join(tempfile.gettempdir(),
                            f"tactile-studio-test-settings-{os.getpid()}.ini")
    if path:
        return QSettings(path, QSettings.Format.IniFormat)
    return QSettings(ORGANISATION, APPLICATION)


def get_json(settings: QSettings, key: str, default: Any = None) -> Any:
    """A JSON value stored as text (QSettings types differ between backends)."""
    raw = settings.value(key)
    if raw is None or raw == "":
        return default
    try:
        return json.loads(str(raw))
    except ValueError:
        return default


def set_json(settings: QSettings, key: str, value: Any) -> None:
    settings.setValue(key, json.dumps(value))


def restore_text(settings: QSettings, key: str, combo: QComboBox) -> None:
    """Select the text saved at ``key`` (a name no longer offered keeps the current one)."""
    saved = settings.value(key)
    if saved and combo.findText(str(saved)) >= 0:
        combo.setCurrentText(str(saved))


def restore_data(settings: QSettings, key: str, combo: QComboBox, default: str) -> None:
    """Select the item whose data was saved at ``key`` (else ``default``'s, else the first)."""
    combo.setCurrentIndex(max(0, combo.findData(str(settings.value(key, default)))))


def style_sheet() -> str:
    """The app style sheet from tactile_studio.resources (empty if it is missing)."""
    try:
        return (resources.files("tactile_studio.resources") / "style.qss").read_text("utf-8")
    except (OSError, ModuleNotFoundError):
        return ""
