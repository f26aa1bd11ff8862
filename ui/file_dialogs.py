"""File dialogs that open where the user last was.

Each kind of choice (a session to open, a report to save, a folder of runs) remembers,
in the app's settings, the folder it was last left in, across runs of the app: a
researcher opening one session after another, or an engineer saving a report a day,
should not have to walk from their home folder each time. A remembered folder that no
longer exists falls back to the home folder.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QWidget

from tactile_studio.ui.settings import app_settings

PREFIX = "dialogs/"
SESSION_KIND = "session"  # the Open session dialogs of the main window and the workspace
# where a kind's folder was kept before its dialog moved here: read while the new key is
# unset, so an update does not make anyone walk from their home folder once more
FORMER_KEYS = {"record": "record/last_dir", "sweep": "research/sweep/last_dir",
               "live_run": "live/last_run_dir",
               "live_calibration": "live/last_calibration_dir"}


def start_folder(kind: str, prefer: str | Path | None = None) -> str:
    """The folder a dialog of ``kind`` opens in: ``prefer`` (a path the form already
    shows) or its folder when it exists, else where the last one was left, else home."""
    if prefer:
        for folder in (Path(prefer).expanduser(), Path(prefer).expanduser().parent):
            if str(folder) not in ("", ".") and folder.is_dir():
                return str(folder)
    settings = app_settings()
    saved = str(settings.value(PREFIX + kind, "") or "")
    if not saved and kind in FORMER_KEYS:
        saved = str(settings.value(FORMER_KEYS[kind], "") or "")
    return saved if saved and Path(saved).is_dir() else str(Path.home())


def remember(kind: str, folder: str | Path) -> None:
    app_settings().setValue(PREFIX + kind, str(folder))


def ask_open_file(parent: QWidget | None, title: str, kind: str, filters: str) -> str:
    """A file to open ("" when cancelled); its folder is where the next one starts."""
    path, _ = QFileDialog.getOpenFileName(parent, title, start_folder(kind), filters)
    if path:
        remember(kind, Path(path).parent)
    return path


def ask_save_file(parent: QWidget | None, title: str, kind: str, name: str,
                  filters: str, prefer: str | Path | None = None) -> str:
    """Where to save (suggesting ``name`` in the remembered folder; "" when cancelled)."""
    path, _ = QFileDialog.getSaveFileName(parent, title,
                                          str(Path(start_folder(kind, prefer)) / name), filters)
    if path:
        remember(kind, Path(path).parent)
    return path


def ask_folder(parent: QWidget | None, title: str, kind: str,
               prefer: str | Path | None = None) -> str:
    """A folder ("" when cancelled); the next dialog starts in its parent, beside it, where
    the sibling folders (the next participant's, the next sweep's) are."""
    folder = QFileDialog.getExistingDirectory(parent, title, start_folder(kind, prefer))
    if folder:
        remember(kind, Path(folder).parent)
    return folder


def ask_open_files(parent: QWidget | None, title: str, kind: str, filters: str) -> list[str]:
    """Files to open ([] when cancelled); their folder is where the next dialog starts."""
    paths, _ = QFileDialog.getOpenFileNames(parent, title, start_folder(kind), filters)
    if paths:
        remember(kind, Path(paths[0]).parent)
    return list(paths)
