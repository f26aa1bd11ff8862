"""The main window's entry to the research workspace (kept here so main_window.py only
calls one function)."""

from __future__ import annotations

from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QMainWindow, QMenu

from tactile_studio.ui.file_dialogs import SESSION_KIND, ask_open_file


def add_research_menu(window: QMainWindow, menu: QMenu, file_menu: QMenu | None = None
                      ) -> QAction:
    """Adds "Research workspace…" (Ctrl+Shift+W) to ``menu`` and "Open session…" (plays a
    recorded session in the workspace's player) to ``file_menu``; the workspace window
    is kept on ``window.research_window``."""
    action = QAction("Research &workspace…", window)
    action.setShortcut(QKeySequence("Ctrl+Shift+W"))

    def workspace():
        from tactile_studio.ui.research.window import ResearchWindow

        if getattr(window, "research_window", None) is None:
            window.research_window = ResearchWindow()
        window.research_window.show()
        window.research_window.raise_()
        return window.research_window

    action.triggered.connect(workspace)
    menu.addAction(action)
    live = QAction("&Live inference…", window)
    live.triggered.connect(lambda: live_inference_dock(window).show())
    menu.addAction(live)
    if file_menu is not None:
        play = QAction("&Open session…", window)
        play.setShortcut(QKeySequence.StandardKey.Open)

        def open_session() -> None:
            path = ask_open_file(window, "Open session", SESSION_KIND, "Sessions (*.h5)")
            if path:
                workspace().open_session(path)

        play.triggered.connect(open_session)
        file_menu.insertAction(file_menu.actions()[0] if file_menu.actions() else None, play)
        # where the README sends people with old recordings: the main window's File menu
        old = QAction("&Import old recordings (ShearSense CSV)…", window)
        old.triggered.connect(lambda: workspace().open_import())
        actions = file_menu.actions()
        file_menu.insertAction(actions[1] if len(actions) > 1 else None, old)
        window.import_action = old
    return action


def live_inference_dock(window: QMainWindow):
    """The main window's live-inference dock (made once, kept on ``window.live_dock``)."""
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QDockWidget

    from tactile_studio.ui.research.live_panel import LiveInferencePanel

    if getattr(window, "live_dock", None) is None:
        c = window.acquisition
        panel = LiveInferencePanel(lambda: c.engine, lambda: c.recorder is not None)
        dock = QDockWidget("Live inference", window)
        dock.setObjectName("live_inference")
        dock.setWidget(panel)
        window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
        # the new dock takes its room from the map, never from the device panel (which
        # it squeezed to a sliver: values truncated, Disconnect and Record cut off)
        device = getattr(window, "device_dock", None)
        if device is not None:
            keep = max(device.width(), device.widget().sizeHint().width(), 280)
            window.resizeDocks([device, dock], [keep, 260], Qt.Orientation.Horizontal)
        window.live_dock = dock
        window.destroyed.connect(panel.stop)
    return window.live_dock
