"""Where the app keeps its files: one place, platform-appropriate (platformdirs).

Linux labs get XDG folders, Windows ``%LOCALAPPDATA%``, macOS ``~/Library``. Each folder
can be redirected with an environment variable, which tests use so they never touch the
user's real folders:

- ``TACTILE_STUDIO_DATA_DIR``: the sensor logbook and other durable app data;
- ``TACTILE_STUDIO_CACHE_DIR``: rebuildable caches (decoded datasets);
- ``TACTILE_STUDIO_CONFIG_DIR``: configuration files.
"""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs

from tactile_studio.errors import UserError

APP_NAME = "tactile-studio"
APP_AUTHOR = "TactileStudio"


def make_out_dir(out: str | os.PathLike) -> Path:
    """Create an output folder (and parents) like any export tool would; a folder that
    cannot be made is a one-line error naming it."""
    try:
        Path(out).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{out}: cannot create output folder ({exc.strerror})") from None
    return Path(out)


def text_path(path: str | os.PathLike) -> str:
    """``path`` as text every UTF-8 reader accepts (the SQLite logbook, JSON read by other
    tools): bytes of a file name that are not UTF-8, which Python keeps as lone surrogates
    (``os.fsdecode``), become backslash escapes (``caf\\xff.h5``) instead of ending the
    command in a UnicodeEncodeError."""
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def _folder(env: str, default: str) -> Path:
    value = os.environ.get(env)
    return Path(value).expanduser() if value else Path(default)


def data_dir() -> Path:
    """Durable app data (the sensor logbook). Not created here."""
    return _folder("TACTILE_STUDIO_DATA_DIR", platformdirs.user_data_dir(APP_NAME, APP_AUTHOR))


def cache_dir() -> Path:
    """Caches that can be deleted and rebuilt at any time. Not created here."""
    return _folder("TACTILE_STUDIO_CACHE_DIR",
                   platformdirs.user_cache_dir(APP_NAME, APP_AUTHOR))


def config_dir() -> Path:
    """Configuration files. Not created here."""
    return _folder("TACTILE_STUDIO_CONFIG_DIR",
                   platformdirs.user_config_dir(APP_NAME, APP_AUTHOR))
