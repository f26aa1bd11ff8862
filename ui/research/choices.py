"""Choices the train and sweep panels share, so both say the same thing the same way."""

from __future__ import annotations

from PySide6.QtWidgets import QComboBox


def adapt_combo() -> QComboBox:
    """"Test people": as trained, or adapted to each person (``ExperimentConfig.adapt``)."""
    combo = QComboBox()
    combo.addItem("as trained", "none")
    combo.addItem("adapted to each person", "person")
    combo.setToolTip("adapted: each test person is met with statistics of their own "
                     "unlabelled windows (networks re-estimate batch norm, rf/knn "
                     "standardise the person's features); needs the person's whole "
                     "session: for lopo / group-kfold, not for live use of rf/knn")
    return combo
