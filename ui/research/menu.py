"""The main window's entry to the research workspace (kept here so main_window.py only
calls one function)."""

from __future__ import annotations

from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QMainWindow, QMenu


def add_research_menu(window: QMainWindow, menu: QMenu) -> QAction:
    """Adds "Research workspace…" (Ctrl+Shift+W); the window is kept on ``window``."""
    action = QAction("Research &workspace…", window)
    action.setShortcut(QKeySequence("Ctrl+Shift+W"))

    def open_workspace() -> None:
        from tactile_studio.ui.research.window import ResearchWindow

        if getattr(window, "research_window", None) is None:
            window.research_window = ResearchWindow()
        window.research_window.show()
        window.research_window.raise_()

    action.triggered.connect(open_workspace)
    menu.addAction(action)
    return action
