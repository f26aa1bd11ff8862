"""Importing old ShearSense CSVs from the research workspace, driven like a user: files,
a gesture map typed as on the command line, progress, the summary, the imported folder in
the Sessions tab, a bad map as one line, settings kept; and the background job's cancel
and error paths. Screenshot: research_import.png (TACTILE_STUDIO_SCREENSHOTS)."""

from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path

import pytest
from csv_fixtures import labelled_csv
from fault_helpers import file_size_limit

from tactile_studio.errors import UserError
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.ui.background_job import BackgroundJob
from tactile_studio.ui.research.window import ResearchWindow

SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


@pytest.fixture
def window(qtbot, tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    w = ResearchWindow()
    qtbot.addWidget(w)
    return w


def test_import_from_the_workspace_names_gestures_and_lists_the_sessions(window, qtbot,
                                                                         tmp_path):
    src = tmp_path / "old"
    src.mkdir()
    csvs = [str(labelled_csv(src, n, i, keys)) for i, (n, keys) in enumerate(
        [("P01_FLAT.csv", "rpz"), ("P1_PILLOW.csv", "rpz"), ("P02_FLAT.csv", "rp")])]
    dialog = window.open_import()
    assert not dialog.start() and "Add CSV files" in dialog.status.text()
    dialog.add_files(csvs + csvs[:1])  # a file added twice is listed once
    assert dialog.files.count() == 3
    out = tmp_path / "sessions"
    dialog.out.setText(str(out))

    dialog.gestures.setText("cost15")  # a typo: one line, nothing written
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text() == ("--gestures: 'cost15' is not key=Name,..., a .toml file "
                                    "or a shipped protocol (cost14, haart7, shear9)")
    assert not out.exists() and dialog.import_button.isEnabled()

    dialog.gestures.setText("cost14")
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text().startswith(f"Imported 3 session(s) into {out}")
    assert dialog.progress.value() == 1000
    summary = dialog.summary.toPlainText()
    assert "gesture keys (from protocol cost14): g=grab, h=hit" in summary
    assert "participants: P01, P02, P1 -> P01" in summary
    assert "key 'z' (code 122) has no gesture name" in summary
    with SessionFile(out / "P1_PILLOW.h5") as s:
        assert [t.gesture for t in s.trials] == ["rub", "pat", "z"]
        assert s.metadata["participant"] == "P01" and s.metadata["condition"] == "PILLOW"
    # the imported folder is in the Sessions tab, ready to train on
    assert window.tabs.currentWidget() is window.sessions
    assert window.sessions.folders == [str(out)] and len(window.sessions.rows) == 3
    assert window.sessions.summary.text() == ("3 of 3 sessions selected: 2 participants, "
                                              "8 ok trials — P02 has no z")
    dialog.grab().save(str(SHOTS / "research_import.png"))
    window.resize(1100, 420)
    window.grab().save(str(SHOTS / "research_import_sessions.png"))

    # the same files again: refused, nothing replaced, unless asked to
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text() == (f"{out / 'P01_FLAT.h5'}: already exists (tick \u201cReplace "
                                    "sessions already in the folder\u201d to overwrite)")
    dialog.force.setChecked(True)
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text().startswith("Imported 3 session(s)")
    assert window.sessions.folders == [str(out)]

    dialog.close()
    window.import_dialog = None
    again = window.open_import()  # the app's next run: the maps and folder as left
    assert (again.gestures.text(), again.out.text()) == ("cost14", str(out))


def test_background_job_cancel_keeps_what_finished_and_errors_are_one_line(qtbot):
    done: list[int] = []
    started = threading.Event()

    def work(progress, cancel):
        for i in range(3):
            done.append(i)
            progress((i + 1) / 10, f"item {i}")
        started.set()
        cancel.wait(30)  # the user has not clicked Cancel yet
        cancel.check()
        done.append(99)

    job = BackgroundJob(work)
    seen: list[tuple[float, str]] = []
    outcomes: list[str] = []
    job.progressed.connect(lambda f, m: seen.append((f, m)))
    job.cancelled.connect(lambda: outcomes.append("cancelled"))
    job.finished.connect(lambda r: outcomes.append("finished"))
    job.start()
    assert started.wait(10)
    qtbot.waitUntil(lambda: bool(seen) and seen[-1] == (0.3, "item 2"), timeout=5000)
    job.cancel()
    qtbot.waitUntil(lambda: bool(outcomes), timeout=10000)
    assert outcomes == ["cancelled"] and done == [0, 1, 2] and not job.running

    def refuse(progress, cancel):
        raise UserError("old.csv: not a ShearSense CSV (no header)")

    for fn, expected in ((refuse, "old.csv: not a ShearSense CSV (no header)"),
                         (lambda p, c: {}["missing"], "KeyError: 'missing'")):
        job = BackgroundJob(fn)
        failures: list[str] = []
        job.failed.connect(failures.append)
        job.start()
        qtbot.waitUntil(lambda: bool(failures), timeout=10000)
        assert failures == [expected]


def test_a_disk_filling_up_part_way_says_which_sessions_were_kept(window, qtbot, tmp_path):
    """As ``import`` on the command line: the cut session is removed, the one finished
    before it is kept and listed, and the status says both (the file-size limit of this
    process stands in for a full disk: P01 fits under it, P02 does not)."""

    src = tmp_path / "old"
    src.mkdir()
    csvs = [str(labelled_csv(src, "P01_FLAT.csv", 1, "rp")),
            str(labelled_csv(src, "P02_FLAT.csv", 2, "rpz" * 15))]
    dialog = window.open_import()
    dialog.add_files(csvs)
    dialog.gestures.setText("r=Rub,p=Poke,z=Zap")
    out = tmp_path / "sessions"
    dialog.out.setText(str(out))
    with file_size_limit(400 * 1024):
        assert dialog.start()
        qtbot.waitUntil(lambda: not dialog.job.running, timeout=30000)
    text = dialog.status.text()
    assert text.startswith(f"{out / 'P02_FLAT.h5'}: ") and "file too large" in text, text
    assert text.endswith("that session was removed, the 1 session(s) imported before it "
                         "are kept"), text
    assert sorted(p.name for p in out.iterdir()) == ["P01_FLAT.h5"]
    with SessionFile(out / "P01_FLAT.h5") as s:
        assert s.closed_cleanly
    assert window.sessions.folders == [str(out)] and len(window.sessions.rows) == 1
    assert dialog.import_button.isEnabled()
