"""Error types the user can cause and fix.

A ``UserError`` is shown as one line (no traceback) and makes the CLI exit non-zero.
Anything else that escapes is a programming error and keeps its traceback.
"""

from __future__ import annotations


class UserError(Exception):
    """Bad input from the user: a file, a setting, a device. Message is one line."""


class SettingsError(UserError):
    """A device or job setting is unknown or has a bad value."""


class SessionFileError(UserError):
    """A session file is missing, corrupt, truncated or not a session."""


class DeviceError(UserError):
    """Base for device problems."""


class DeviceNotFound(DeviceError):
    """The device (port, address, file) does not exist or cannot be opened."""


class DeviceLost(DeviceError):
    """The device went away while streaming; the engine may try to reconnect."""


class BadData(DeviceError):
    """The device sent data that cannot be decoded at all (not just one bad line)."""


class Cancelled(Exception):
    """A long job stopped because its cancel flag was set; partial results are kept."""
