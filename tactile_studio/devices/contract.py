"""The public device-plugin contract. Built-in plugins use exactly this, as third parties do.

A plugin is a class registered under the entry-point group ``tactile_studio.devices``.
The acquisition engine drives it from its own thread::

    dev = Plugin(**settings)          # validates settings (SettingsError)
    dev.open()                        # DeviceNotFound if it is not there
    while running:
        batch = dev.read(max_frames)  # blocks up to ~0.1 s; may return an empty batch
    dev.close()

``read`` raises ``DeviceLost`` when the device goes away; if ``supports_reconnect`` the
engine then calls ``reopen()`` with backoff until it succeeds or the user stops.

Optional hooks (listed in ``OPTIONAL_HOOKS``) are declared by a capability flag on the
class and have a fixed signature; a plugin that does not set the flag does not have the
hook. :func:`tactile_studio.devices.check_plugin` checks both the required contract and
every declared hook. docs/plugins.md walks through a complete third-party plugin.
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from tactile_studio.errors import SettingsError, UserError
from tactile_studio.plugin_settings import Setting, validate_settings  # noqa: F401
from tactile_studio.sensor.layout import Layout, get_layout


def layout_setting(device: str, name: str) -> Layout:
    """The layout named by a device's ``layout`` setting, as a setting error if unknown."""
    try:
        return get_layout(name)
    except UserError as exc:
        raise SettingsError(f"device {device}: setting layout: {exc}") from None


@dataclass
class FrameBatch:
    """Frames read in one call.

    ``raw``: (n, n_channels) counts in the layout's dtype. ``device_time``: (n,) seconds
    on the device's clock, non-decreasing (or None: the engine uses ``host_time``).
    ``seq``: (n,) device sequence numbers (or None: no gap detection from the device).
    ``malformed``: bad input dropped while reading, counted by kind (e.g. {"short": 2,
    "non_numeric": 1}). ``host_time``: (n,) host wall-clock seconds (``time.time()``,
    Unix epoch) when each frame arrived, non-decreasing; give it when frames are received
    at different moments within one ``read`` (a serial line, a BLE notification), so the
    session file keeps the real arrival times. None: the engine stamps every frame of
    the batch with the moment it ingests the batch.
    """

    raw: np.ndarray
    device_time: np.ndarray | None = None
    seq: np.ndarray | None = None
    malformed: dict[str, int] = field(default_factory=dict)
    host_time: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.raw.shape[0])


@dataclass(frozen=True)
class OptionalHook:
    """An optional plugin hook: present when the class sets ``flag`` to True, and then
    defined (overriding the base) with exactly ``params`` after ``cls``/``self``."""

    name: str
    flag: str
    params: tuple[str, ...]
    kind: str = "classmethod"  # classmethod | method
    attributes: tuple[str, ...] = ()  # class attributes the hook needs, checked too


OPTIONAL_HOOKS: tuple[OptionalHook, ...] = (
    OptionalHook("discover", "supports_discover", ("settings",),
                 attributes=("discover_setting", "discover_instant")),
)


class DevicePlugin(abc.ABC):
    """Base class of every device plugin (simulated, replay, serial, BLE, third party)."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    settings_schema: ClassVar[tuple[Setting, ...]] = ()
    supports_reconnect: ClassVar[bool] = False

    # ---- optional hook: discover (a "Scan" list for one setting) ----------------------
    supports_discover: ClassVar[bool] = False
    discover_setting: ClassVar[str] = ""  # the setting a chosen value goes into
    discover_instant: ClassVar[bool] = False  # True: waits for nothing (lists ports)

    @classmethod
    def discover(cls, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """(value, label) choices for the ``discover_setting`` (serial ports, BLE
        addresses), for a device panel's drop-down; declared by ``supports_discover``.

        ``settings`` are the form's settings as ``validate_settings`` returns them
        (defaults filled in), so a scan can use filters such as a name prefix or a scan
        time. Unless ``discover_instant``, it may block for seconds: callers run it off
        the GUI thread. Raise a ``UserError`` (e.g. ``DeviceNotFound``) with one line
        when scanning is impossible.
        """
        raise NotImplementedError(f"device {cls.name}: no discover hook "
                                  "(supports_discover is False)")

    def __init__(self, **settings: Any) -> None:
        self.settings = self.validate_settings(settings)

    @classmethod
    def validate_settings(cls, settings: dict[str, Any]) -> dict[str, Any]:
        """Defaults filled in, every value parsed and range-checked, unknown keys refused."""
        return validate_settings(cls.settings_schema, settings, cls.name, "device")

    @property
    @abc.abstractmethod
    def layout(self) -> Layout:
        """The sensor layout this device delivers."""

    @property
    @abc.abstractmethod
    def nominal_rate_hz(self) -> float:
        """The rate the device is configured for (the engine measures the real one)."""

    @abc.abstractmethod
    def open(self) -> None:
        """Connect. Raise DeviceNotFound with a one-line message if impossible."""

    @abc.abstractmethod
    def read(self, max_frames: int) -> FrameBatch:
        """Block until at least one frame (or ~0.1 s) and return up to ``max_frames``."""

    @abc.abstractmethod
    def close(self) -> None:
        """Disconnect; must be safe to call twice or after a failed open."""

    def reopen(self) -> None:
        """Try once to reconnect after DeviceLost; raise DeviceError while it fails."""
        self.close()
        self.open()

    @property
    def finished(self) -> bool:
        """True when a finite source (a replayed file) has delivered everything."""
        return False

    @property
    def waits_for_reader(self) -> bool:
        """True when frames are made on demand (a file replayed or a simulation "as fast
        as possible"): the engine then reads no faster than a reader that may not lose
        frames takes them. A sensor streaming in real time cannot wait: False."""
        return False

    def sensor_id(self) -> str | None:
        """Optional hook: the attached sensor's identity (serial number, seed), if the
        device knows it; None lets the user pick or type one. Goes in the logbook."""
        return None

    def info(self) -> dict[str, Any]:
        """What goes into a session's metadata about the device."""
        return {"plugin": self.name, "settings": dict(self.settings),
                "layout": self.layout.name, "nominal_rate_hz": self.nominal_rate_hz}
