"""The training recipe in the workspace (windows, aggregation, augmentation, per-person
scaling, balance, early stopping): the form starts at the command line's defaults, the
train and sweep panels hand it to the experiment, it is remembered, and a run trained
from the panel records it in its config."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder
from PySide6.QtCore import QSettings, Qt

from tactile_studio.cli import build_parser
from tactile_studio.cli.learn import generalisation_kwargs
from tactile_studio.ui.research.recipe_form import RecipeForm
from tactile_studio.ui.research.sweep_panel import SweepPanel
from tactile_studio.ui.research.train_panel import TrainPanel

# screenshots for review: TACTILE_STUDIO_SCREENSHOTS=docs/screenshots pytest ...
SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())
CHANGED = {"window_s": 1.0, "window_overlap": 0.25, "aggregate": "vote",
           "augment": "flip,shift", "augment_copies": 2, "participant_norm": True,
           "balance": True, "val_by": "participant"}


@pytest.mark.parametrize("command", ["train", "sweep"])
def test_the_form_starts_at_the_command_lines_defaults(qtbot, command):
    form = RecipeForm()
    qtbot.addWidget(form)
    extra = ["--model", "rf"] if command == "train" else ["--models", "rf"]
    args = build_parser().parse_args([command, "--data", "d", *extra, "--out", "o"])
    cli = {"window_s": args.window_s, "window_overlap": getattr(args, "window_overlap", 0.5),
           "aggregate": args.aggregate, **generalisation_kwargs(args)}
    del cli["adapt"]  # the panels' "Test people" choice
    assert form.kwargs() == cli
    assert form.summary() == "defaults" and not form.body.isVisible()


def test_panels_hand_the_recipe_to_the_experiment_and_remember_it(qtbot, tmp_path):
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    data = [str(tmp_path / "sessions")]
    train = TrainPanel(lambda: data, settings)
    qtbot.addWidget(train)
    train.model.setCurrentText("cnn1d")  # a network: early stopping is part of its recipe
    train.out.setText(str(tmp_path / "run"))
    train.recipe.set_kwargs(CHANGED)
    assert train.recipe.kwargs() == CHANGED
    assert train.recipe.copies.isEnabled()  # copies count only with augmentation
    config = train.config()
    assert {k: getattr(config, k) for k in CHANGED} == CHANGED
    header = train.recipe.summary_label.text()
    for words in ("1 s windows", "25% overlap", "vote", "augment flip+shift x2",
                  "participant norm", "balanced", "early stop on people"):
        assert words in header
    train.recipe.header.setChecked(True)
    assert train.recipe.body.isVisibleTo(train)
    train.resize(1300, 820)
    SHOTS.mkdir(parents=True, exist_ok=True)
    train.grab().save(str(SHOTS / "research_train_recipe.png"))
    train.save_settings()
    again = TrainPanel(lambda: data, settings)
    qtbot.addWidget(again)
    assert again.recipe.kwargs() == CHANGED
    # no augmentation: the copies box is off; the sweep panel builds its base config too
    sweep = SweepPanel(lambda: data, settings)
    qtbot.addWidget(sweep)
    sweep.out.setText(str(tmp_path / "sweep"))
    sweep.recipe.set_kwargs({**CHANGED, "augment": ""})
    assert not sweep.recipe.copies.isEnabled()
    base = sweep.config()
    assert base.augment == "" and base.window_s == 1.0 and base.aggregate == "vote"
    sweep.save_settings()
    reopened = SweepPanel(lambda: data, settings)
    qtbot.addWidget(reopened)
    assert reopened.recipe.kwargs() == {**CHANGED, "augment": ""}


@pytest.mark.slow
def test_a_run_from_the_panel_trains_with_the_recipe(qtbot, tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_CACHE_DIR", str(tmp_path / "cache"))
    make_dataset_folder(tmp_path / "data", participants=3, blocks=2,
                        gestures=("Poke", "Heavy Pat", "Back & Forth Rub"))
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    panel = TrainPanel(lambda: [str(tmp_path / "data")], settings)
    qtbot.addWidget(panel)
    panel.model.setCurrentText("rf")
    panel.preset.setCurrentText("tiny")
    panel.evaluation.setCurrentText("lopo")
    panel.out.setText(str(tmp_path / "run"))
    panel.recipe.header.setChecked(True)
    panel.recipe.window.setValue(0.5)  # the fixture's trials are cut into windows
    panel.recipe.aggregate.setCurrentIndex(panel.recipe.aggregate.findData("vote"))
    panel.recipe.kinds["flip"].setChecked(True)
    panel.recipe.balance.setChecked(True)
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: not panel.job.running, timeout=240_000)
    assert panel.job.finished.type == "done", panel.job.finished
    saved = json.loads((tmp_path / "run" / "config.json").read_text())["config"]
    assert (saved["window_s"], saved["aggregate"], saved["augment"], saved["balance"]) == \
        (0.5, "vote", "flip", True)
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    # 0.5 s windows of the fixture's trials: several per trial, voted into the trial's
    assert metrics["window_s"] == 0.5 and metrics["aggregate"] == "vote"
    assert metrics["windows"] >= 3 * metrics["n_trials"] > 0
