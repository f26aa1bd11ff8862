"""Choices the train and sweep panels share, so both say the same thing the same way."""

from __future__ import annotations

from PySide6.QtWidgets import QComboBox

from tactile_studio.learn.choices import CHANNEL_SETS, EVALUATIONS, GRIDS
from tactile_studio.learn.learners.contract import PRESETS
from tactile_studio.learn.learners.generalise import ADAPT_AUTO, ADAPT_PHRASE

# train --shots-by's values (learn/choices.py SHOTS_BY) said in the panel's words
SHOTS_BY_TEXT = {"auto": "auto: fine-tune a network, refit rf / knn",
                 "join": "join the training (one training per K)",
                 "fine-tune": "fine-tune the output layers (networks)"}
# sweep --executor's values (learn/choices.py EXECUTORS) said in the panel's words
EXECUTOR_TEXT = {"local": "Local worker processes", "ray": "Ray cluster"}


def evaluation_combo() -> QComboBox:
    """"Evaluation": the splits of learn/choices.py, the default (lopo) first."""
    combo = QComboBox()
    combo.addItems(list(EVALUATIONS))
    return combo


def channels_combo() -> QComboBox:
    """"Channels": every channel ("both") first, the panel's default, then the others."""
    combo = QComboBox()
    combo.addItems(sorted(CHANNEL_SETS, key=lambda c: c != "both"))
    return combo


def grid_combo() -> QComboBox:
    """"Grid": the sensor's taxels (the default) or the virtual grid."""
    combo = QComboBox()
    combo.addItems(list(GRIDS))
    return combo


def adapt_combo() -> QComboBox:
    """"Test people": adapted where they are held out (the default), as trained, or
    adapted to each person (``ExperimentConfig.adapt``)."""
    combo = QComboBox()
    combo.addItem("networks adapted when held out (auto)", ADAPT_AUTO)
    for key, phrase in ADAPT_PHRASE.items():
        combo.addItem(phrase, key)
    combo.setToolTip("adapted: each test person is met with statistics of their own "
                     "unlabelled windows (networks re-estimate batch norm, rf/knn "
                     "standardise the person's features), per condition (surface) too "
                     "if the sessions name one; needs the person's whole "
                     "session: for lopo / group-kfold. Live, the model adapts to the "
                     "participant's last touches and predicts as trained until it has "
                     "them. The default adapts a network whenever people are held out "
                     "and leaves rf/knn as trained: on the real recordings adapting "
                     "gained cnn3d 3.3 points and cost rf 1.7")
    return combo


def preset_combo() -> QComboBox:
    """The model size: ``full`` (the default, as in the CLI) or ``tiny``."""
    combo = QComboBox()
    combo.addItems(list(PRESETS))  # full first: the default
    combo.setItemData(0, "each model's recipe for unseen people (the figures in "
                         "docs/learning/figures.md)", 3)  # tooltip role
    combo.setItemData(1, "the CPU-test size: quick, but under the random forest on hard "
                         "virtual people and on the real recordings", 3)
    combo.setToolTip("full: each model's recipe for unseen people; tiny: the CPU-test size")
    return combo
