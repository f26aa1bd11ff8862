"""File dialogs open where the user last was, and the research workspace reopens with its
session folders and runs, across restarts of the app: the research
workspace's Open session (shared with the main window's File menu), its folder pickers,
the confusion export's suggested name, and the fallback when that folder is gone.

The native dialogs are modal and cannot be clicked headless, so Qt's static dialog
functions are replaced by a stand-in that records the folder they were opened in and
answers as the user would; everything behind them is the real widget."""

from __future__ import annotations

from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder, write_participant
from PySide6.QtWidgets import QFileDialog, QMainWindow

from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.ui.research.menu import add_research_menu
from tactile_studio.ui.research.window import ResearchWindow


class Dialogs:
    """Answers the next dialog with ``answer`` and records where each one opened."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.opened_in: list[str] = []
        self.answer = ""
        for name in ("getOpenFileName", "getSaveFileName"):
            monkeypatch.setattr(QFileDialog, name, staticmethod(self._file))
        monkeypatch.setattr(QFileDialog, "getExistingDirectory", staticmethod(self._folder))

    def _file(self, parent, title, start, filters=""):
        self.opened_in.append(start)
        return self.answer, ""

    def _folder(self, parent, title, start):
        self.opened_in.append(start)
        return self.answer


@pytest.fixture
def dialogs(monkeypatch, tmp_path):
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    return Dialogs(monkeypatch)


def test_open_session_starts_where_the_last_one_was_even_after_a_restart(qtbot, tmp_path,
                                                                        dialogs):
    (tmp_path / "study").mkdir()
    session = write_participant(tmp_path / "study" / "P01.h5", "P01", 1, blocks=1, trial_s=0.5)
    window = ResearchWindow()
    qtbot.addWidget(window)
    window._browse_session()
    assert dialogs.opened_in[-1] == str(Path.home())  # nothing remembered yet
    dialogs.answer = str(session)
    window._browse_session()
    window._browse_session()
    assert dialogs.opened_in[-1] == str(session.parent)
    assert window.tabs.currentWidget() is window.player  # the chosen session did open

    again = ResearchWindow()  # the app restarted: settings persist
    qtbot.addWidget(again)
    again._browse_session()
    assert dialogs.opened_in[-1] == str(session.parent)
    main = QMainWindow()
    qtbot.addWidget(main)
    menu = main.menuBar().addMenu("&File")
    add_research_menu(main, main.menuBar().addMenu("&View"), menu)
    dialogs.answer = ""
    next(a for a in menu.actions() if a.text() == "&Open session…").trigger()
    assert dialogs.opened_in[-1] == str(session.parent)  # File > Open session shares it

    # a folder picker starts beside the folder last chosen; a vanished folder: home
    runs = tmp_path / "lab" / "runs-2026"
    runs.mkdir(parents=True)
    dialogs.answer = str(runs)
    window.runs._browse()
    window.runs._browse()
    assert dialogs.opened_in[-1] == str(runs.parent) and window.runs.root.text() == str(runs)
    runs.rmdir()
    runs.parent.rmdir()
    dialogs.answer = ""
    window.runs._browse()
    assert dialogs.opened_in[-1] == str(Path.home())


def test_confusion_export_suggests_the_runs_name_in_the_last_export_folder(qtbot, tmp_path,
                                                                          dialogs):
    make_dataset_folder(tmp_path / "data", participants=3, blocks=1, trial_s=1.0)
    config = ExperimentConfig(data=[str(tmp_path / "data")], model="knn", preset="tiny",
                              evaluation="lopo", cache_dir=str(tmp_path / "cache"))
    run_experiment(config, tmp_path / "runs" / "knn-lopo")
    window = ResearchWindow()
    qtbot.addWidget(window)
    conf = window.confusion
    assert not conf.export_png.isEnabled()  # nothing shown, nothing to export
    window.runs.set_root(str(tmp_path / "runs"))
    window.runs.select_paths(str(tmp_path / "runs" / "knn-lopo"))
    window.runs.open_button.click()
    assert conf.model is not None and conf.export_png.isEnabled()
    figures = tmp_path / "figures"
    figures.mkdir()
    dialogs.answer = str(figures / "fig3.png")
    conf.export_png.click()
    assert dialogs.opened_in[-1] == str(Path.home() / "knn-lopo-confusion.png")
    assert (figures / "fig3.png").stat().st_size > 0
    dialogs.answer = ""
    conf.export_csv.click()
    assert dialogs.opened_in[-1] == str(figures / "knn-lopo-confusion.csv")


def test_the_workspace_reopens_with_its_session_folders_and_runs(qtbot, tmp_path, dialogs):
    make_dataset_folder(tmp_path / "a", participants=2, blocks=1, trial_s=0.5)
    make_dataset_folder(tmp_path / "b", participants=1, blocks=1, trial_s=0.5, first_style=7)
    (tmp_path / "runs").mkdir()
    window = ResearchWindow()
    qtbot.addWidget(window)
    assert window.sessions.folders == [] and window.runs.root.text() == ""
    window.sessions.set_folders([str(tmp_path / "a"), str(tmp_path / "b")])
    window.runs.set_root(str(tmp_path / "runs"))

    again = ResearchWindow()  # the app's next run
    qtbot.addWidget(again)
    assert again.sessions.folders == [str(tmp_path / "a"), str(tmp_path / "b")]
    assert len(again.sessions.rows) == 3 and again.runs.root.text() == str(tmp_path / "runs")
    # a folder deleted since is dropped, the rest kept
    for f in (tmp_path / "b").iterdir():
        f.unlink()
    (tmp_path / "b").rmdir()
    third = ResearchWindow()
    qtbot.addWidget(third)
    assert third.sessions.folders == [str(tmp_path / "a")] and len(third.sessions.rows) == 2


def test_record_and_sweep_folders_carry_over_from_their_former_keys(qtbot, tmp_path, dialogs):
    """The Record dialog, the sweep folder picker and the live panel's pickers kept their
    folders under keys of their own before they shared ui/file_dialogs.py: an update must
    not forget them."""
    from PySide6.QtCore import QSettings

    from tactile_studio.acquisition import LiveAcquisition
    from tactile_studio.ui.device_panel import DevicePanel

    recordings, sweeps = tmp_path / "recordings", tmp_path / "sweeps"
    recordings.mkdir()
    sweeps.mkdir()
    old = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    old.setValue("record/last_dir", str(recordings))
    old.setValue("research/sweep/last_dir", str(sweeps))
    old.setValue("live/last_run_dir", str(sweeps))  # the live panel's, moved in session 20
    old.setValue("live/last_calibration_dir", str(recordings))
    old.sync()
    from tactile_studio.ui.file_dialogs import start_folder
    assert start_folder("live_run") == str(sweeps)
    assert start_folder("live_calibration") == str(recordings)
    panel = DevicePanel(LiveAcquisition(compress_in_background=True))
    qtbot.addWidget(panel)
    dialogs.answer = ""
    assert panel.ask_record_path() is None
    opened = Path(dialogs.opened_in[-1])
    assert opened.parent == recordings and opened.name.startswith("session-")
    (tmp_path / "today").mkdir()
    dialogs.answer = str(tmp_path / "today" / "P07")
    assert panel.ask_record_path() == str(tmp_path / "today" / "P07.h5")
    panel.ask_record_path()
    assert Path(dialogs.opened_in[-1]).parent == tmp_path / "today"

    window = ResearchWindow()
    qtbot.addWidget(window)
    sweep = window.sweep
    sweep.out.setText("")
    dialogs.answer = ""
    sweep._browse()
    assert dialogs.opened_in[-1] == str(sweeps)
    # a folder the form shows wins (its parent while it does not exist yet)
    sweep.out.setText(str(sweeps / "next-sweep"))
    sweep._browse()
    assert dialogs.opened_in[-1] == str(sweeps)
    (sweeps / "next-sweep").mkdir()
    sweep._browse()
    assert dialogs.opened_in[-1] == str(sweeps / "next-sweep")
    # a sweep started into a typed folder: the next Browse… starts beside it
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    sweep.out.setText(str(elsewhere / "s1"))
    sweep.save_settings()
    sweep.out.setText("")
    sweep._browse()
    assert dialogs.opened_in[-1] == str(elsewhere)
