"""Finding device plugins: the ``tactile_studio.devices`` entry-point group plus
:func:`register_device` (one :class:`~tactile_studio.registry.Registry`, lazy and cached)."""

from __future__ import annotations

from typing import Any

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import SettingsError
from tactile_studio.registry import Registry, subclass_of

GROUP = "tactile_studio.devices"
DEFAULT_DEVICE = "simulated"

DEVICES: Registry[type[DevicePlugin]] = Registry(GROUP, "device", subclass_of(DevicePlugin))


def available_plugins() -> dict[str, type[DevicePlugin] | Exception]:
    """Every registered plugin by name; a plugin that fails to load maps to its error."""
    return dict(sorted(DEVICES.all().items()))


def register_device(cls: type[DevicePlugin], *, replace: bool = False) -> type[DevicePlugin]:
    """Make the plugin class ``cls`` available as ``cls.name`` in this process (a notebook,
    a script, a test), as an entry point would; returns ``cls``."""
    return DEVICES.register(cls.name, cls, replace=replace)


def unregister_device(name: str) -> None:
    """Forget a device registered with :func:`register_device`."""
    DEVICES.unregister(name)


def plugin_class(name: str) -> type[DevicePlugin]:
    """The plugin class called ``name``; a one-line UserError if unknown or broken."""
    return DEVICES.get(name)


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
