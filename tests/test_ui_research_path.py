"""The researcher's first day: the live-inference dock beside a usable device panel, the
train panel's run folder, the main window's import entry. Real windows (pytest-qt,
offscreen) at their default sizes.
"""

from __future__ import annotations

import pytest

from tactile_studio.ui.main_window import DEVICE_PANEL_MIN_WIDTH, MainWindow
from tactile_studio.ui.research.menu import live_inference_dock
from tactile_studio.ui.settings import SETTINGS_ENV


@pytest.fixture(autouse=True)
def isolated(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def fully_shown(widget) -> bool:
    """Wide enough for its own text (not cut off) and inside its window."""
    return widget.isVisible() and widget.width() >= widget.minimumSizeHint().width() \
        and widget.visibleRegion().boundingRect().width() >= widget.width() - 1


def test_the_live_inference_dock_leaves_the_device_panel_usable(qtbot):
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False,
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    assert w.size().width() == 1280  # the default window size
    dock = live_inference_dock(w)
    dock.show()
    qtbot.waitUntil(lambda: dock.isVisible() and dock.width() > 100, timeout=2000)
    assert w.device_dock.width() >= DEVICE_PANEL_MIN_WIDTH and not w.device_panel_squeezed()
    p = w.panel
    for button in (p.connect_button, p.disconnect_button, p.record_button, p.tare_button):
        assert fully_shown(button), button.text()
    assert fully_shown(dock.widget().load_button)
    w.shutdown()


def test_a_squeezed_layout_is_not_saved(qtbot, tmp_path):
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w.save_settings()  # a good layout
    dock = live_inference_dock(w)
    dock.show()
    w.resize(760, 800)  # a window too narrow for the map, the dock and the panel
    qtbot.waitUntil(lambda: w.width() <= 800 and w.device_panel_squeezed(), timeout=3000)
    w.shutdown()  # saves, but not the squeezed layout
    again = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False)
    qtbot.addWidget(again)
    again.resize(1280, 800)
    again.show()
    qtbot.waitExposed(again)
    qtbot.waitUntil(lambda: again.device_dock.width() >= DEVICE_PANEL_MIN_WIDTH, timeout=3000)
    assert not again.device_panel_squeezed()
    again.shutdown()
