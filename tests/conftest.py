"""Shared test setup: headless Qt, and no test touches the user's settings or cache."""

from __future__ import annotations

import os
import tempfile

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("TACTILE_STUDIO_TESTING", "1")
# the app's data, cache and config folders (tactile_studio.paths) live in one temporary
# folder per test run; tests that need their own set them with monkeypatch
_APPDIRS = tempfile.mkdtemp(prefix="tactile-studio-appdirs-")
for _name in ("DATA", "CACHE", "CONFIG"):
    os.environ.setdefault(f"TACTILE_STUDIO_{_name}_DIR", os.path.join(_APPDIRS, _name.lower()))
# Lab Streaming Layer: loopback only, a session ID of its own (read when liblsl loads);
# under pytest-xdist one per worker, so one worker's streams never answer another's resolve
_LSL_CFG = os.path.join(os.path.dirname(__file__), "lsl_api.cfg")
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER:
    _worker_cfg = os.path.join(_APPDIRS, "lsl_api.cfg")
    with open(_LSL_CFG) as src, open(_worker_cfg, "w") as dst:
        dst.write(src.read().replace("SessionID = tactile-studio-tests",
                                     f"SessionID = tactile-studio-tests-{_WORKER}"))
    _LSL_CFG = _worker_cfg
os.environ.setdefault("LSLAPICFG", _LSL_CFG)

# test files that start a local Ray instance: one worker runs them all, one after another
_RAY_FILES = {"test_sweep.py", "test_ui_research_sweep.py"}


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """Whole files per worker (module fixtures are built once), the Ray files together."""
    from xdist.scheduler import LoadFileScheduling

    class FilesRayTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "ray" if os.path.basename(path) in _RAY_FILES else path

    return FilesRayTogether(config, log)



@pytest.fixture
def wait_until():
    """The shared bounded wait (tests/waiting.py), for tests that prefer a fixture."""
    from waiting import wait_until as wait
    return wait


@pytest.fixture(autouse=True)
def no_recorder_left_running():
    """A test that starts a recorder stops it: one left running would write into its
    file while the interpreter tears down (a crash after the last test)."""
    from tactile_studio.storage.recorder import running_recorders
    before = set(map(id, running_recorders()))
    yield
    left = [r for r in running_recorders() if id(r) not in before]
    for r in left:
        r.stop()
    assert not left, f"recorder left running: {[str(r.path) for r in left]}"


@pytest.fixture(autouse=True)
def widgets_live_until_closed(monkeypatch):
    """Close the widgets a test registered with ``qtbot.addWidget`` at its end.

    pytest-qt holds them weakly: a window the test no longer references was destroyed at
    the test's last line without a closeEvent (a collection console's recording kept
    running). Here they are held until closed; one its parent already deleted is skipped.
    Set up after (so torn down before) the recorder check.
    """
    from pytestqt.qtbot import QtBot
    held = []

    def add_widget(self, widget, *, before_close_func=None):
        held.append((widget, before_close_func))

    monkeypatch.setattr(QtBot, "addWidget", add_widget)
    yield
    if not held:
        return
    import shiboken6
    from PySide6.QtWidgets import QApplication
    for widget, before_close in held:
        if shiboken6.isValid(widget):
            if before_close is not None:
                before_close(widget)
            widget.close()
            widget.deleteLater()
    held.clear()
    QApplication.processEvents()
