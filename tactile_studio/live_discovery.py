"""The device panel's "Scan": ask a plugin's ``discover`` hook for serial ports or BLE
peripherals, with arguments taken from the settings form."""

from __future__ import annotations

import inspect
import logging
from typing import Any

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import UserError


def discover_setting(cls: type[DevicePlugin] | None) -> str | None:
    """The setting a plugin can fill from a scan (duck-typed ``discover`` +
    ``discover_setting`` hooks, see docs/devices.md), or None."""
    name = getattr(cls, "discover_setting", None)
    if cls is None or not name or not callable(getattr(cls, "discover", None)):
        return None
    return name if any(s.name == name for s in cls.settings_schema) else None


def discover_is_instant(cls: type[DevicePlugin]) -> bool:
    """True when ``discover`` waits for nothing (its ``timeout`` defaults to 0, as for
    serial ports), so a panel may run it as soon as the plugin is chosen; a radio scan
    (BLE) runs only when asked."""
    timeout = inspect.signature(cls.discover).parameters.get("timeout")
    return timeout is None or timeout.default in (0, 0.0)


def discover_kwargs(cls: type[DevicePlugin], texts: dict[str, str]) -> dict[str, Any]:
    """Arguments for ``cls.discover`` from the settings form: parameters named like a
    setting take its value (``timeout`` takes ``scan_timeout``); a value that does not
    parse is left out, so the hook's default applies (the form shows the error)."""
    schema = {s.name: s for s in cls.settings_schema}
    out: dict[str, Any] = {}
    for param in inspect.signature(cls.discover).parameters:
        key = "scan_timeout" if param == "timeout" and "scan_timeout" in schema else param
        setting = schema.get(key)
        if setting is None or key == discover_setting(cls):
            continue
        text = texts.get(key, "")
        try:
            out[param] = setting.default if text == "" else setting.parse(text, cls.name)
        except UserError:
            continue
    return out


def run_discovery(cls: type[DevicePlugin],
                  texts: dict[str, str]) -> tuple[list[tuple[str, str]], str | None]:
    """Scan with the form's settings: ((value, label) choices, None) or ([], one-line
    error). Blocks (a BLE scan listens for seconds): call it from a worker thread."""
    try:
        found = cls.discover(**discover_kwargs(cls, texts))
    except UserError as exc:
        return [], " ".join(str(exc).split())
    except Exception as exc:  # a plugin bug: full traceback in the log, one line shown
        logging.getLogger(__name__).error("device discovery failed", exc_info=exc)
        return [], f"{cls.name}: scan failed ({type(exc).__name__}: {exc})"
    return [(str(value), str(label)) for value, label in found], None
