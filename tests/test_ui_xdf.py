"""XDF in the research workspace, driven like a user: File > Import XDF recordings
imports a LabRecorder-like file (a pressure mat, an EDA band, a script's markers) into
the Sessions tab, and the session player shows the EDA in a lane of its own beside the
touch, with the markers named on the timeline. Screenshot: research_xdf_player.png
(TACTILE_STUDIO_SCREENSHOTS)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
from test_xdf import foreign_xdf

from tactile_studio.ui.research.window import ResearchWindow

SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


@pytest.fixture
def window(qtbot, tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    w = ResearchWindow()
    qtbot.addWidget(w)
    return w


def test_import_xdf_from_the_workspace_and_play_it_with_its_eda(window, qtbot, tmp_path):
    src = tmp_path / "sub-P07_ses-S2_task-touch_run-1.xdf"
    foreign_xdf(src)
    (tmp_path / "eda_only.xdf").write_bytes(b"XDF:")  # no streams at all
    dialog = window.open_import_xdf()
    out = tmp_path / "sessions"
    dialog.out.setText(str(out))
    dialog.add_files([str(tmp_path / "eda_only.xdf")])
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert "eda_only.xdf: no tactile stream (streams: none); name one with Tactile " \
           "stream and Its layout" in dialog.status.text()
    dialog.files.clear()
    dialog.add_files([str(src)])
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text().startswith(f"Imported 1 session(s) into {out}")
    assert window.tabs.currentWidget() is window.sessions
    assert window.sessions.folders == [str(out)] and len(window.sessions.rows) == 1
    dialog.grab().save(str(SHOTS / "research_import_xdf.png"))
    dialog.close()

    player = window.player
    assert player.open_session(str(out / "sub-P07_ses-S2_task-touch_run-1.h5"))
    (track,) = player.pb.aux
    assert (track.name, track.unit, track.label) == ("Shimmer-EDA", "uS", "gsr")
    assert 0 <= track.frames.min() and track.frames.max() <= player.pb.n_frames - 1
    assert [e.text for e in player.pb.events if e.kind == "marker"] == ["start", "stop"]
    assert player.timeline.minimumHeight() == 130 + 30
    window.tabs.setCurrentWidget(player)
    player.set_taxels([(3, 2), (3, 5)])
    player.seek(250)  # mid-stroke
    window.resize(1100, 700)
    window.show()
    qtbot.waitExposed(window)
    window.grab().save(str(SHOTS / "research_xdf_player.png"))
