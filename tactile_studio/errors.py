"""Error types the user can cause and fix.

A ``UserError`` is shown as one line (no traceback) and makes the CLI exit non-zero.
Anything else that escapes is a programming error and keeps its traceback.
"""

from __future__ import annotations

# The CLI's exit statuses (README, "Exit status"): one table for every command.
EXIT_OK = 0
EXIT_ERROR = 1        # bad input, a refused request, a file that cannot be read or written
EXIT_USAGE = 2        # the command line itself (argparse)
EXIT_INCOMPLETE = 3   # ended short of what was asked (device lost, disk full, frames lost);
#                       everything recorded so far is kept and readable
EXIT_CHECK_WARN = 4   # a check that ran to its end found something to look at (wellness WARN)
EXIT_CHECK_FAIL = 5   # a check that ran to its end failed (wellness FAIL, `check` violations)
EXIT_CANCELLED = 130  # Ctrl-C; finished work kept
EXIT_BROKEN_PIPE = 141
EXIT_TERMINATED = 143


class UserError(Exception):
    """Bad input from the user: a file, a setting, a device. Message is one line.

    ``exit_code`` is the CLI's exit status for it (see the EXIT_* table above)."""

    exit_code = EXIT_ERROR


class IncompleteError(UserError):
    """The user got less than they asked for (a device lost for good, a full disk, frames
    lost): the message says what was kept; the CLI exits with EXIT_INCOMPLETE."""

    exit_code = EXIT_INCOMPLETE


class CheckFailed(UserError):
    """A check ran to its end and its verdict is not a pass (wellness WARN/FAIL, session
    validation): the message is the verdict line; the exit status tells which."""

    def __init__(self, message: str, exit_code: int = EXIT_CHECK_FAIL) -> None:
        super().__init__(message)
        self.exit_code = exit_code


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

