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

from tactile_studio.output_faults import as_user_error

APP_NAME = "tactile-studio"
APP_AUTHOR = "TactileStudio"


def make_out_dir(out: str | os.PathLike) -> Path:
    """The one rule for an output folder that does not exist, in every command and the
    collection console: it is made (with its parents), as any export tool does. The
    commands' last line names what they wrote there, and the console says beforehand
    that the folder will be made, so a mistyped folder shows. A folder that cannot be
    made is the house's one fault line naming it."""
    path = Path(out)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a file in the way, no permission...
        error = as_user_error(exc)
        if error is None:
            raise
        raise error from None
    return path


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
