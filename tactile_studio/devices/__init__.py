"""Device plugins: the public contract, the registry, and the acquisition engine."""

from tactile_studio.devices.conformance import PluginCheckError, check_plugin
from tactile_studio.devices.contract import OPTIONAL_HOOKS, DevicePlugin, FrameBatch, Setting
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.devices.frame_stream import FrameStream, RecordableStream
from tactile_studio.devices.registry import (
    DEFAULT_DEVICE,
    available_plugins,
    create_device,
    parse_set_options,
    plugin_class,
    register_device,
    unregister_device,
)
from tactile_studio.devices.ring import FrameChunk, RingBuffer

__all__ = [
    "DEFAULT_DEVICE", "OPTIONAL_HOOKS", "AcquisitionEngine", "DevicePlugin", "FrameBatch",
    "FrameChunk", "FrameStream", "PluginCheckError", "RecordableStream", "RingBuffer", "Setting",
    "available_plugins",
    "check_plugin", "create_device", "parse_set_options", "plugin_class", "register_device",
    "unregister_device",
]
