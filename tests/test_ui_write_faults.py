"""Windows that write files show one line when the place cannot be written (no traceback):
the research workspace's confusion export (PNG, SVG, CSV), the wellness report, the
Record button. The place is a path through a regular file (ENOTDIR; tests run as root,
where chmod does not stop writes)."""

from __future__ import annotations

import pytest
from learn_fixtures import make_dataset_folder
from PySide6.QtGui import QImage
from PySide6.QtWidgets import QMessageBox

from tactile_studio.cli import main
from tactile_studio.errors import UserError
from tactile_studio.ui.write_faults import write_image


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "appdata"))
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))


@pytest.fixture
def blocker(tmp_path):
    path = tmp_path / "blocker"
    path.write_text("a regular file: nothing can be made under it")
    return path


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("run")
    make_dataset_folder(root / "data", participants=3, blocks=2,
                        gestures=("Poke", "Heavy Pat", "Back & Forth Rub"))
    assert main(["train", "--data", str(root / "data"), "--model", "rf", "--preset", "tiny",
                 "--eval", "lopo", "--out", str(root / "run"), "--cache-dir",
                 str(root / "cache"), "--set", "n_estimators=20"]) == 0
    return root / "run"


def test_confusion_export_says_why_it_wrote_nothing(qtbot, run_folder, blocker, tmp_path):
    from tactile_studio.ui.research.window import ResearchWindow

    w = ResearchWindow()
    qtbot.addWidget(w)
    assert w.open_run(str(run_folder))
    for suffix in ("png", "svg", "csv"):
        assert not w.export_confusion(blocker / f"m.{suffix}")
        assert w.message.text() == f"{blocker}/m.{suffix}: cannot write (Not a directory)"
    # a good place still gets real files (the images are now written by Python)
    for suffix in ("png", "svg", "csv"):
        assert w.export_confusion(tmp_path / f"m.{suffix}")
        assert w.message.text() == f"exported {tmp_path}/m.{suffix}"
    assert not QImage(str(tmp_path / "m.png")).isNull()
    assert "<svg" in (tmp_path / "m.svg").read_text()


def test_wellness_report_that_cannot_be_saved_is_a_message(qtbot, blocker):
    from tactile_studio.ui.wellness_wizard import WellnessWizard

    w = WellnessWizard("simulated", {"speed": 0, "seed": 21})
    qtbot.addWidget(w)
    w.show()
    w.setup.weight.setValue(200)
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(lambda: page.isComplete(), timeout=5000)
    w.next()
    assert w.result_page.save_report(str(blocker / "r.html")) is None
    boxes = [b for b in w.result_page.findChildren(QMessageBox) if b.isVisible()]
    assert len(boxes) == 1
    assert boxes[0].text() == f"{blocker}/r.html: cannot write (Not a directory)"
    boxes[0].close()


def test_record_button_into_an_unwritable_place_shows_one_line(qtbot, blocker):
    from tactile_studio.ui.main_window import MainWindow

    w = MainWindow(device="simulated", settings={"rate": "200", "gesture": "idle"},
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    assert w.panel.connect_device()
    assert not w.panel.start_recording(str(blocker / "s.h5"))
    assert w.panel.error_text() == f"{blocker}/s.h5: cannot write (Not a directory)"
    assert w.acquisition.recorder is None
    w.shutdown()


def test_an_image_format_qt_cannot_write_is_refused_by_name(qtbot, tmp_path):
    image = QImage(4, 4, QImage.Format.Format_RGB32)
    with pytest.raises(UserError, match="x.nope: cannot encode an image as NOPE"):
        write_image(image, tmp_path / "x.nope")
    assert not QImage(str(write_image(image, tmp_path / "x.png"))).isNull()


def test_background_and_training_jobs_end_in_the_one_line(qtbot, run_folder, blocker):
    import time

    from tactile_studio.learn.experiments.experiment import ExperimentConfig
    from tactile_studio.learn.experiments.train_job import TrainJob
    from tactile_studio.ui.background_job import BackgroundJob

    job = BackgroundJob(lambda progress, cancel: (blocker / "x.h5").write_bytes(b""))
    failures: list[str] = []
    job.failed.connect(failures.append)
    job.start()
    qtbot.waitUntil(lambda: bool(failures), timeout=10000)
    assert failures == [f"{blocker}/x.h5: cannot write (Not a directory)"]

    data = run_folder.parent / "data"
    cfg = ExperimentConfig(data=[str(data)], model="knn", evaluation="lopo", preset="tiny",
                           cache_dir=str(run_folder.parent / "cache"))
    train = TrainJob(cfg, blocker / "run").start()
    deadline = time.monotonic() + 120
    while train.running and time.monotonic() < deadline:
        train.poll()
        time.sleep(0.05)
    train.poll()
    assert train.finished.type == "error"
    assert train.finished.message.startswith(f"{blocker}/run")
    assert train.finished.message.endswith("cannot write (Not a directory)")
