"""A panel's remembered choices, declared once: each entry is a settings key with how to
read its widget and how to set it back, so loading (on open) and saving (on start) walk
the same list. A widget moved or renamed in a panel cannot lose a user's saved choice
without its entry changing too, and a test can round-trip every key of a panel.

Each kind keeps the storage form the keys always had (text, or JSON text for numbers
and lists), so the choices saved by earlier versions load unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QCheckBox, QComboBox, QLineEdit, QSpinBox

from tactile_studio.ui.settings import get_json, restore_data, restore_text, set_json


@dataclass(frozen=True)
class Bound:
    """One remembered choice: ``read`` gives the widget's value, ``save``/``load`` move it
    to and from the settings under ``key`` (the full key)."""

    key: str
    read: Callable[[], Any]
    save: Callable[[QSettings, str], None]
    load: Callable[[QSettings, str], None]
    formerly: str | None = None  # the full key it was saved under before a rename


class BoundSettings:
    """The declared choices of one panel under ``prefix`` (e.g. ``research/train/``)."""

    def __init__(self, prefix: str) -> None:
        self.prefix = prefix
        self.entries: list[Bound] = []

    def add(self, key: str, read: Callable[[], Any], save: Callable[[QSettings, str], None],
            load: Callable[[QSettings, str], None]) -> None:
        full = self.prefix + key
        if any(b.key == full for b in self.entries):
            raise ValueError(f"settings key {full!r} bound twice")
        self.entries.append(Bound(full, read, save, load))

    def renamed(self, key: str, formerly: str) -> None:
        """``key`` was saved as ``formerly`` by earlier versions (a rename): a choice saved
        under the old name is loaded, and moved to the new one, instead of being lost."""
        full = self.prefix + key
        at = next(i for i, b in enumerate(self.entries) if b.key == full)
        self.entries[at] = replace(self.entries[at], formerly=self.prefix + formerly)

    # --- kinds of widget ---------------------------------------------------------------
    def combo_text(self, key: str, combo: QComboBox) -> None:
        """The shown text (a name no longer offered keeps the current one)."""
        self.add(key, combo.currentText, lambda s, k: s.setValue(k, combo.currentText()),
                 lambda s, k: restore_text(s, k, combo))

    def combo_data(self, key: str, combo: QComboBox, default: str) -> None:
        """The item's data (else ``default``'s item)."""
        self.add(key, combo.currentData, lambda s, k: s.setValue(k, combo.currentData()),
                 lambda s, k: restore_data(s, k, combo, default))

    def spin(self, key: str, box: QSpinBox, default: int) -> None:
        """A whole number, stored as JSON text."""
        self.add(key, box.value, lambda s, k: set_json(s, k, box.value()),
                 lambda s, k: box.setValue(int(get_json(s, k, default))))

    def check(self, key: str, box: QCheckBox) -> None:
        """A checkbox, stored as JSON true/false (off by default)."""
        self.add(key, box.isChecked, lambda s, k: set_json(s, k, box.isChecked()),
                 lambda s, k: box.setChecked(bool(get_json(s, k, False))))

    def text(self, key: str, edit: QLineEdit) -> None:
        """A line of text, stored stripped."""
        self.add(key, lambda: edit.text().strip(),
                 lambda s, k: s.setValue(k, edit.text().strip()),
                 lambda s, k: edit.setText(str(s.value(k, "") or "")))

    def json(self, key: str, read: Callable[[], Any], write: Callable[[Any], None],
             default: Any) -> None:
        """Any JSON value through a getter and a setter (checked lists, a form's kwargs)."""
        self.add(key, read, lambda s, k: set_json(s, k, read()),
                 lambda s, k: write(get_json(s, k, default)))

    # --- use ---------------------------------------------------------------------------
    def load(self, settings: QSettings) -> None:
        for b in self.entries:
            if b.formerly and not settings.contains(b.key) and settings.contains(b.formerly):
                settings.setValue(b.key, settings.value(b.formerly))
                settings.remove(b.formerly)
            b.load(settings, b.key)

    def save(self, settings: QSettings) -> None:
        for b in self.entries:
            b.save(settings, b.key)

    def values(self) -> dict[str, Any]:
        """Every key with its widget's current value (what :meth:`save` would store)."""
        return {b.key: b.read() for b in self.entries}
