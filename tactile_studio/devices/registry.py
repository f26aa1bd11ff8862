"""Finding device plugins through the ``tactile_studio.devices`` entry-point group."""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import SettingsError, UserError

GROUP = "tactile_studio.devices"
DEFAULT_DEVICE = "simulated"


def available_plugins() -> dict[str, type[DevicePlugin] | Exception]:
    """Every registered plugin by name; a plugin that fails to load maps to its error."""
    found: dict[str, type[DevicePlugin] | Exception] = {}
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        try:
            cls = ep.load()
        except Exception as exc:  # a broken third-party plugin must not break the app
            found[ep.name] = exc
            continue
        if not (isinstance(cls, type) and issubclass(cls, DevicePlugin)):
            found[ep.name] = TypeError(f"{ep.value} is not a DevicePlugin subclass")
            continue
        found[ep.name] = cls
    return found


def plugin_class(name: str) -> type[DevicePlugin]:
    plugins = available_plugins()
    if name not in plugins:
        raise UserError(f"unknown device {name!r} (available: {', '.join(plugins) or 'none'})")
    cls = plugins[name]
    if isinstance(cls, Exception):
        raise UserError(f"device plugin {name!r} failed to load: {cls}")
    return cls


def parse_set_options(pairs: list[str] | None) -> dict[str, str]:
    """``["rate=100", "seed=3"]`` -> {"rate": "100", "seed": "3"}."""
    out: dict[str, str] = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            raise SettingsError(f"bad --set {pair!r}: expected key=value")
        out[key.strip()] = value.strip()
    return out


def create_device(name: str, settings: dict[str, Any] | None = None) -> DevicePlugin:
    """Instantiate a plugin with validated settings (SettingsError on bad values)."""
    return plugin_class(name)(**(settings or {}))
