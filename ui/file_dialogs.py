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


def start_folder(kind: str) -> str:
    """The folder a dialog of ``kind`` opens in: where the last one was left, else home."""
    saved = str(app_settings().value(PREFIX + kind, "") or "")
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
                  filters: str) -> str:
    """Where to save (suggesting ``name`` in the remembered folder; "" when cancelled)."""
    path, _ = QFileDialog.getSaveFileName(parent, title, str(Path(start_folder(kind)) / name),
                                          filters)
    if path:
        remember(kind, Path(path).parent)
    return path


def ask_folder(parent: QWidget | None, title: str, kind: str) -> str:
    """A folder ("" when cancelled); the next dialog starts in its parent, beside it, where
    the sibling folders (the next participant's, the next sweep's) are."""
    folder = QFileDialog.getExistingDirectory(parent, title, start_folder(kind))
    if folder:
        remember(kind, Path(folder).parent)
    return folder


def ask_open_files(parent: QWidget | None, title: str, kind: str, filters: str) -> list[str]:
    """Files to open ([] when cancelled); their folder is where the next dialog starts."""
    paths, _ = QFileDialog.getOpenFileNames(parent, title, start_folder(kind), filters)
    if paths:
        remember(kind, Path(paths[0]).parent)
    return list(paths)
