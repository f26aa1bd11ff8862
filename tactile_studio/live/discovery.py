"""The device panel's "Scan": call a plugin's declared ``discover`` hook (see
``DevicePlugin.discover``) for serial ports or BLE peripherals, with the settings form's
values as its filters."""

from __future__ import annotations

import logging
from typing import Any

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import UserError


def discover_setting(cls: type[DevicePlugin] | None) -> str | None:
    """The setting a plugin can fill from a scan (it declares ``supports_discover`` and
    names a ``discover_setting`` of its schema), or None."""
    if cls is None or not getattr(cls, "supports_discover", False):
        return None
    name = cls.discover_setting
    return name if any(s.name == name for s in cls.settings_schema) else None


def discover_is_instant(cls: type[DevicePlugin]) -> bool:
    """True when ``discover`` waits for nothing (``discover_instant``, as for serial
    ports), so a panel may run it as soon as the plugin is chosen; a radio scan (BLE)
    runs only when asked."""
    return bool(getattr(cls, "discover_instant", False))


def discover_settings(cls: type[DevicePlugin], texts: dict[str, str]) -> dict[str, Any]:
    """The settings handed to ``cls.discover`` from the form's texts: every setting
    parsed, with its default where the text is empty or does not parse (the form shows
    that error itself, the scan still runs)."""
    out: dict[str, Any] = {}
    for setting in cls.settings_schema:
        text = texts.get(setting.name, "")
        try:
            out[setting.name] = setting.default if text == "" else setting.parse(text, cls.name)
        except UserError:
            out[setting.name] = setting.default
    return out


def run_discovery(cls: type[DevicePlugin],
                  texts: dict[str, str]) -> tuple[list[tuple[str, str]], str | None]:
    """Scan with the form's settings: ((value, label) choices, None) or ([], one-line
    error). Blocks (a BLE scan listens for seconds): call it from a worker thread."""
    try:
        found = cls.discover(discover_settings(cls, texts))
    except UserError as exc:
        return [], " ".join(str(exc).split())
    except Exception as exc:  # a plugin bug: full traceback in the log, one line shown
        logging.getLogger(__name__).error("device discovery failed", exc_info=exc)
        return [], f"{cls.name}: scan failed ({type(exc).__name__}: {exc})"
    return [(str(value), str(label)) for value, label in found], None
