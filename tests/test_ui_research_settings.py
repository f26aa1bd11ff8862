"""Every remembered choice of the Train and Sweep tabs round-trips: each bound widget is
set away from its default, the panel saves, and a new panel on the same settings shows
the same values — under the key names users' saved choices already have."""

from __future__ import annotations

from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QComboBox

from tactile_studio.ui.research.sweep_panel import SweepPanel
from tactile_studio.ui.research.train_panel import TrainPanel

RECIPE = {"window_s": 1.5, "window_overlap": 0.3, "aggregate": "vote", "augment": "flip,shift",
          "augment_copies": 3, "participant_norm": True, "balance": True}


def _other(combo: QComboBox) -> None:
    combo.setCurrentIndex((combo.currentIndex() + 1) % combo.count())


def _recipe(panel) -> None:
    kwargs = {**panel.recipe.kwargs(), **RECIPE}
    panel.recipe.set_kwargs(kwargs)


def _round_trip(qtbot, make, vary, tmp_path, names: set[str]) -> None:
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    first = make(settings)
    qtbot.addWidget(first)
    assert {b.key for b in first.bound.entries} == names  # the keys users' choices live in
    default = first.bound.values()
    vary(first)
    chosen = first.bound.values()
    same = sorted(k for k in names if chosen[k] == default[k])
    assert not same, f"not varied by the test: {same}"
    first.save_settings()
    settings.sync()
    second = make(QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(second)
    assert second.bound.values() == chosen


def test_every_train_setting_round_trips(qtbot, tmp_path):
    run = tmp_path / "runs" / "kept"
    run.mkdir(parents=True)
    (run / "config.json").write_text("{}")  # a started run: reopened as it was

    def vary(p: TrainPanel) -> None:
        p.model.setCurrentText("rf")
        for combo in (p.preset, p.channels, p.grid, p.evaluation, p.adapt, p.shots_by):
            _other(combo)
        p.rounds.setValue(3)
        p.epochs.setValue(7)
        p.shots.setText("0,1,2")
        p.out.setText(str(run))
        p.exclude_flagged.setChecked(True)
        _recipe(p)

    names = {f"research/train/{k}" for k in ("model", "preset", "channels", "grid", "evaluation",
                                             "adapt", "rounds", "epochs", "shots", "shots_by",
                                             "out", "recipe", "exclude_flagged")}
    _round_trip(qtbot, lambda s: TrainPanel(lambda: [], s), vary, tmp_path, names)


def test_every_sweep_setting_round_trips(qtbot, tmp_path):
    def vary(p: SweepPanel) -> None:
        p.set_models(["cnn1d"])
        p.set_channels(["shear"])
        for combo in (p.executor, p.adapt, p.preset, p.evaluation):
            _other(combo)
        p.jobs.setValue(p.jobs.value() % 7 + 1 if p.jobs.value() != 7 else 3)
        p.address.setText("10.0.0.5:6379")
        p.rounds.setValue(4)
        _recipe(p)

    names = {f"research/sweep/{k}" for k in ("models", "channels", "executor", "adapt",
                                             "jobs", "address", "preset", "evaluation",
                                             "rounds", "recipe")}
    _round_trip(qtbot, lambda s: SweepPanel(lambda: [], s), vary, tmp_path, names)


def test_an_evaluation_saved_before_it_was_renamed_is_kept(qtbot, tmp_path):
    """Issue 44 renamed the tabs' "protocol" to "evaluation": a choice saved under the old
    key is shown, and moved to the new key, instead of falling back to lopo."""
    path = str(tmp_path / "settings.ini")
    old = QSettings(path, QSettings.Format.IniFormat)
    old.setValue("research/train/protocol", "group-kfold")
    old.setValue("research/sweep/protocol", "all-inclusive")
    old.sync()
    settings = QSettings(path, QSettings.Format.IniFormat)
    train, sweep = TrainPanel(lambda: [], settings), SweepPanel(lambda: [], settings)
    qtbot.addWidget(train)
    qtbot.addWidget(sweep)
    assert train.evaluation.currentText() == "group-kfold"
    assert sweep.evaluation.currentText() == "all-inclusive"
    assert settings.value("research/train/evaluation") == "group-kfold"
    assert not settings.contains("research/train/protocol")
