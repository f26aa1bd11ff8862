"""The research workspace says which session files hold the session invariants
(``tactile-studio check``): the Session player's badge and list, the Sessions tab's
problem column. Real recordings, a deliberately inconsistent real HDF5 file, real widgets."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.sensor.layout import get_layout
from tactile_studio.storage.format.session_compress import wait_for_compression
from tactile_studio.storage.format.session_writer import SessionWriter
from tactile_studio.ui.research.sessions_view import CHECKING, COLUMNS
from tactile_studio.ui.research.window import ResearchWindow

SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())

# what check says of the inconsistent file, in its order
BAD_VIOLATIONS = ("device_time goes back at row 30",
                  "trial 1: rows 34..60 end past the 50 frames",
                  "session_end at frame 20 is before trial 1 ends (row 60)")


def _recording(path: Path, capsys) -> Path:
    assert main(["record", "--seconds", "0.3", "--set", "speed=10", "--out", str(path)]) == 0
    capsys.readouterr()
    wait_for_compression(path)
    return path


def _inconsistent(path: Path) -> Path:
    """A session whose clock goes back, a trial ends past the frames and session_end
    comes before the last trial ends: readable, playable, and wrong."""
    layout = get_layout("shearsense-6x6")
    n = 50
    dev = np.arange(n) / 43.0
    dev[30:] -= 0.5
    host = 1e9 + np.arange(n) / 43.0
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name},
                       {"source": "collect", "participant": "P09"}) as w:
        w.append_frames(np.zeros((n, layout.n_channels), np.uint16), dev, host)
        w.add_event("session_end", frame=20)
        for index, (a, b) in enumerate(((2, 12), (34, 60))):
            w.add_trial({"index": index, "block": 0, "gesture": "Poke", "start_sample": a,
                         "end_sample": b, "start_time": a / 43, "end_time": b / 43,
                         "status": "ok"})
    return path


@pytest.fixture
def window(qtbot):
    w = ResearchWindow()
    qtbot.addWidget(w)
    w.resize(1400, 820)
    w.show()
    return w


@pytest.mark.damaged_files
def test_player_says_whether_the_file_is_valid(window, tmp_path, capsys):
    good = _recording(tmp_path / "good.h5", capsys)
    bad = _inconsistent(tmp_path / "bad.h5")
    player = window.player
    assert not player.check_button.isEnabled()  # nothing open, nothing to check
    assert window.open_session(str(good))
    assert player.validity.text().startswith("✓ valid session: passes check")
    assert player.problems.isHidden() and player.show_problems.isHidden()
    assert player.check_button.isEnabled()
    window.player.grab().save(str(SHOTS / "research_player_valid.png"))

    assert window.open_session(str(bad))  # it still plays: the user sees it, flagged
    text = player.validity.text()
    assert text.startswith("⚠ fails check: 3 problems: " + BAD_VIOLATIONS[0]), text
    assert player.problems.isHidden()  # folded until asked for: the map keeps its room
    window.player.grab().save(str(SHOTS / "research_player_invalid.png"))
    player.show_problems.click()
    assert not player.problems.isHidden() and player.show_problems.text() == "Hide problems"
    listed = [player.problems.item(i).text() for i in range(player.problems.count())]
    assert len(listed) == 3
    for expected, line in zip(BAD_VIOLATIONS, listed):
        assert line.startswith(expected), (expected, line)
    assert player.validity.toolTip() == "\n".join(listed)
    window.player.grab().save(str(SHOTS / "research_player_problems.png"))

    # "Check file" runs the check again and says the same of the same file
    player.validity.setText("")
    player.problems.clear()
    player.check_button.click()
    assert player.validity.text() == text and player.problems.count() == 3
    # back to the valid one: the list goes
    assert window.open_session(str(good))
    assert player.problems.isHidden() and player.show_problems.isHidden()
    assert player.validity.text().startswith("✓")


@pytest.mark.damaged_files
def test_sessions_tab_flags_the_file_that_fails_check(window, tmp_path, capsys, qtbot):
    """The tab lists the files at once and checks them on a background job: the rows are
    there saying "checking…" before any result (results reach the table only through the
    event loop, which has not run yet), then each result fills its cell."""
    folder = tmp_path / "study"
    folder.mkdir()
    _recording(folder / "good.h5", capsys)
    _inconsistent(folder / "bad.h5")
    s = window.sessions
    s.set_folders([str(folder)])
    problem = COLUMNS.index("problem")
    assert not s.table.isColumnHidden(problem)
    by_name = {s.table.item(r, 0).text(): r for r in range(s.table.rowCount())}
    assert set(by_name) == {"good.h5", "bad.h5"}
    assert s.checking  # listed before checked: the tab never waits for check
    assert [s.table.item(r, problem).text() for r in by_name.values()] == [CHECKING] * 2
    assert s.table.item(by_name["good.h5"], COLUMNS.index("ok trials")).text() == "0"
    qtbot.waitUntil(lambda: not s.checking, timeout=30_000)
    bad_cell = s.table.item(by_name["bad.h5"], problem)
    assert bad_cell.text().startswith("fails check: 3 problems: " + BAD_VIOLATIONS[0])
    for expected in BAD_VIOLATIONS:  # every violation in the tooltip
        assert expected in bad_cell.toolTip()
    assert s.table.item(by_name["good.h5"], problem).text() == ""
    # readable, so still selectable for a run, but the selection says one fails
    assert len(s.selected_paths()) == 2
    assert "1 fails check" in s.summary.text()
    window.tabs.setCurrentWidget(s)
    window.grab().save(str(SHOTS / "research_sessions_check.png"))
    # a study that holds its invariants: no problem column once checked, nothing said
    (folder / "bad.h5").unlink()
    s.set_folders([str(folder)])
    qtbot.waitUntil(lambda: not s.checking, timeout=30_000)
    assert s.table.isColumnHidden(problem) and "fails check" not in s.summary.text()
