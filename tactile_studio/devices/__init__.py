"""Device plugins: the public contract, the registry, and the acquisition engine."""

from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.devices.registry import (
    DEFAULT_DEVICE,
    available_plugins,
    create_device,
    parse_set_options,
    plugin_class,
)
from tactile_studio.devices.ring import FrameChunk, RingBuffer

__all__ = [
    "DEFAULT_DEVICE", "AcquisitionEngine", "DevicePlugin", "FrameBatch", "FrameChunk",
    "RingBuffer", "Setting", "available_plugins", "create_device", "parse_set_options",
    "plugin_class",
]
