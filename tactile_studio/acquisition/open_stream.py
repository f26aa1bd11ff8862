"""``open_stream``: the one place a device's stream (the acquisition engine) is made.

Every command, wizard and window that reads a device gets its stream here, so all of
them read it the same way (ring size, tare, reconnects) and hold it by the
:class:`~tactile_studio.devices.frame_stream.LiveStream` protocol, never by the engine's
class: only ``tactile_studio.acquisition`` (and ``devices`` itself) imports
``devices.engine`` (an import contract in pyproject.toml), and nothing but this module
calls its constructor (tests/test_open_stream.py).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.devices.registry import create_device

DEFAULT_CAPACITY = 1 << 16  # frames the ring holds (a few minutes at the usual rates)


def open_stream(device: DevicePlugin | str, settings: Mapping[str, Any] | None = None, *,
                capacity: int = DEFAULT_CAPACITY) -> LiveStream:
    """The stream of ``device`` (a plugin, or a plugin name made with ``settings``: a
    SettingsError at once when they are bad), not started: ``start()`` opens the device
    in the stream's thread, and a device that fails to open shows as state ``error``."""
    if isinstance(device, str):
        device = create_device(device, dict(settings or {}))
    elif settings:
        raise TypeError("settings go with a device's name, not with a device already made")
    return AcquisitionEngine(device, capacity=capacity)
