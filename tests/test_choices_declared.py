"""Every list of choices the learning pipeline offers is declared once
(tactile_studio/learn/choices.py, and the few its rooms own): the CLI's ``choices=`` and the
Train and Sweep tabs' combo boxes offer exactly the declared values, none more, none
missing. A copy typed somewhere (a fourth split in the panel, a channel set missing from
the CLI) fails here by name."""

from __future__ import annotations

import argparse

import pytest

from tactile_studio.cli import build_parser
from tactile_studio.learn.choices import (
    AGGREGATES,
    BASELINES,
    CHANNEL_SETS,
    EVALUATIONS,
    EXECUTORS,
    GRIDS,
    SHOTS_BY,
)
from tactile_studio.learn.learners.contract import PRESETS
from tactile_studio.learn.learners.families import available_models
from tactile_studio.learn.learners.generalise import ADAPT, ADAPT_CHOICES, VAL_BY
from tactile_studio.ui.research.sweep_panel import SweepPanel
from tactile_studio.ui.research.train_panel import TrainPanel
from tactile_studio.ui.settings import SETTINGS_ENV

# every option of the learning commands that offers choices: its declaration, plus the
# values the command adds of its own (sweep's "all": every channel the data has)
DECLARED = {
    "evaluation": (EVALUATIONS, ()), "grid": (GRIDS, ()), "channels": (CHANNEL_SETS, ()),
    "channel_sets": (CHANNEL_SETS, ()), "shots_by": (SHOTS_BY, ()),
    "aggregate": (AGGREGATES, ()), "executor": (EXECUTORS, ()), "preset": (PRESETS, ()),
    "val_by": (VAL_BY, ()), "adapt": (ADAPT_CHOICES, ()),
}
OWN = {("sweep", "channels"): ("all",)}
LEARNING = ("train", "ablate", "sweep", "evaluate")


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: sub.choices[name] for name in LEARNING}


def _offered(combo) -> list:  # noqa: ANN001 - a QComboBox
    """What a combo box offers: its items' data, else their text."""
    return [combo.itemData(i) if combo.itemData(i) is not None else combo.itemText(i)
            for i in range(combo.count())]


def test_the_cli_offers_exactly_the_declared_choices():
    seen = set()
    for name, command in _commands().items():
        for action in command._actions:
            if not action.choices:
                continue
            assert action.dest in DECLARED, (
                f"{name} --{action.dest}: a list of choices not declared in learn/choices.py")
            declared, extra = DECLARED[action.dest]
            if (name, action.dest) == ("evaluate", "adapt"):
                declared = ADAPT  # re-scoring keeps the run's adaptation unless told
            extra = OWN.get((name, action.dest), extra)
            assert sorted(action.choices) == sorted((*declared, *extra)), (name, action.dest)
            seen.add(action.dest)
    assert seen == set(DECLARED)  # every declaration is offered somewhere


def test_the_help_names_the_declared_models():
    train = _commands()["train"]
    help_text = next(a.help for a in train._actions if a.dest == "model")
    for name in BASELINES:
        assert name in help_text


@pytest.fixture
def settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


def test_the_train_tab_offers_exactly_the_declared_choices(qtbot, settings):
    panel = TrainPanel(lambda: [])
    qtbot.addWidget(panel)
    assert sorted(_offered(panel.evaluation)) == sorted(EVALUATIONS)
    assert panel.evaluation.currentText() == EVALUATIONS[0]
    assert sorted(_offered(panel.channels)) == sorted(CHANNEL_SETS)
    assert sorted(_offered(panel.grid)) == sorted(GRIDS)
    assert sorted(_offered(panel.shots_by)) == sorted(SHOTS_BY)
    assert sorted(_offered(panel.preset)) == sorted(PRESETS)
    assert sorted(_offered(panel.adapt)) == sorted(ADAPT_CHOICES)
    assert sorted(_offered(panel.model)) == sorted(available_models())
    assert set(BASELINES) <= set(_offered(panel.model))


def test_the_sweep_tab_offers_exactly_the_declared_choices(qtbot, settings):
    panel = SweepPanel(lambda: [])
    qtbot.addWidget(panel)
    assert sorted(_offered(panel.evaluation)) == sorted(EVALUATIONS)
    assert sorted(panel.channel_boxes) == sorted(CHANNEL_SETS)
    assert sorted(_offered(panel.executor)) == sorted(EXECUTORS)
    assert sorted(_offered(panel.preset)) == sorted(PRESETS)
    assert sorted(_offered(panel.adapt)) == sorted(ADAPT_CHOICES)
    models = [panel.models.item(i).text() for i in range(panel.models.count())]
    assert sorted(models) == sorted(available_models())
