"""Choices the train and sweep panels share, so both say the same thing the same way."""

from __future__ import annotations

from PySide6.QtWidgets import QComboBox

from tactile_studio.learn.generalise import ADAPT_AUTO, ADAPT_PHRASE


def adapt_combo() -> QComboBox:
    """"Test people": networks adapted (the default), as trained, or adapted to each
    person (``ExperimentConfig.adapt``)."""
    combo = QComboBox()
    combo.addItem("networks adapted, rf/knn as trained", ADAPT_AUTO)
    for key, phrase in ADAPT_PHRASE.items():
        combo.addItem(phrase, key)
    combo.setToolTip("adapted: each test person is met with statistics of their own "
                     "unlabelled windows (networks re-estimate batch norm, rf/knn "
                     "standardise the person's features), per condition (surface) too "
                     "if the sessions name one; needs the person's whole "
                     "session: for lopo / group-kfold. Live, a network adapts to the "
                     "participant's last touches; rf/knn need a recording first. "
                     "The default adapts networks only: they gained 2-12 points, "
                     "rf/knn about nothing")
    return combo
