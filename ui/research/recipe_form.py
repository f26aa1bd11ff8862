"""The training recipe beyond the model: how long trials become windows, how a trial's
windows make its prediction, and what helps a model meet unseen people (augmentation,
per-participant scaling, class balance, early stopping on whole people).

The train and sweep panels share this form, so the GUI offers what ``train`` and
``sweep`` offer on the command line (``--window``, ``--overlap``, ``--aggregate``,
``--augment``, ``--augment-copies``, ``--participant-norm``, ``--balance``, ``--val-by``)
with the same defaults. Folded by default: the defaults are the recipe the measured
figures use, and the header says when they are changed.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from PySide6.QtCore import QSettings, Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QSpinBox,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.learn.data.augment import KINDS
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.ui.settings import get_json, set_json

FIELDS = ("window_s", "window_overlap", "aggregate", "augment", "augment_copies",
          "participant_norm", "balance", "val_by")
# ExperimentConfig's defaults for the fields this form sets (the CLI's too)
DEFAULTS: dict[str, Any] = {f.name: f.default for f in fields(ExperimentConfig)
                            if f.name in FIELDS}


class RecipeForm(QWidget):
    """Window, aggregation and generalisation options as ``ExperimentConfig`` fields."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.header = QToolButton()
        self.header.setCheckable(True)
        self.header.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.header.setArrowType(Qt.ArrowType.RightArrow)
        self.header.setAutoRaise(True)
        self.header.setText("Windows and generalisation:")
        self.summary_label = QLabel()
        self.summary_label.setWordWrap(True)  # a long list of changes must not widen the panel
        self.window = QDoubleSpinBox()
        self.window.setRange(0.0, 120.0)
        self.window.setSingleStep(0.5)
        self.window.setDecimals(1)
        self.window.setSuffix(" s")
        self.window.setSpecialValueText("the protocol's trial length (else 2 s)")
        self.window.setToolTip("trials longer than 1.5 windows (imported performances, "
                               "free play) are cut into windows this long for training")
        self.overlap = QSpinBox()
        self.overlap.setRange(0, 90)
        self.overlap.setSingleStep(10)
        self.overlap.setSuffix(" %")
        self.overlap.setToolTip("share of a window overlapping the next")
        self.aggregate = QComboBox()
        self.aggregate.addItem("mean probability of its windows", "mean")
        self.aggregate.addItem("majority vote of its windows", "vote")
        self.aggregate.setToolTip("how a long trial's windows make the trial's prediction "
                                  "(trial accuracy)")
        self.kinds = {k: QCheckBox(k) for k in KINDS}
        self.kinds["flip"].setToolTip("mirror images of the grid, shear turned with it")
        self.kinds["rotate"].setToolTip("90° rotations, shear turned with the grid")
        self.kinds["shift"].setToolTip("translations by whole taxels")
        self.kinds["warp"].setToolTip("time warping: 0.8-1.25x the tempo")
        self.kinds["scale"].setToolTip("harder or softer touch, more or less drag")
        kinds = QHBoxLayout()
        kinds.setContentsMargins(0, 0, 0, 0)
        for box in self.kinds.values():
            kinds.addWidget(box)
        kinds.addStretch(1)
        self.copies = QSpinBox()
        self.copies.setRange(1, 20)
        self.copies.setToolTip("augmented copies of every training window")
        self.val_by = QComboBox()
        self.val_by.addItem("held-back training trials", "trial")
        self.val_by.addItem("held-back training participants", "participant")
        self.val_by.setToolTip("what early stopping watches: trials of the training people, "
                               "or whole training people (closer to an unseen person)")
        self.participant_norm = QCheckBox("scale each participant's normal and shear to a "
                                          "typical person")
        self.balance = QCheckBox("repeat rarer gestures when training")
        self.body = QWidget()
        self.form = form = QFormLayout(self.body)
        form.setContentsMargins(16, 0, 0, 0)
        kinds_row = QWidget()
        kinds_row.setLayout(kinds)
        for label, w in (("Window", self.window), ("Overlap", self.overlap),
                         ("Trial from", self.aggregate), ("Augment", kinds_row),
                         ("Copies", self.copies), ("Early stopping", self.val_by),
                         ("People", self.participant_norm), ("Classes", self.balance)):
            form.addRow(label, w)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        top = QHBoxLayout()
        top.addWidget(self.header)
        top.addWidget(self.summary_label, 1)
        layout.addLayout(top)
        layout.addWidget(self.body)
        self.header.toggled.connect(self._unfold)
        for spin in (self.window, self.overlap, self.copies):
            spin.valueChanged.connect(self._changed)
        for combo in (self.aggregate, self.val_by):
            combo.currentIndexChanged.connect(self._changed)
        for box in (*self.kinds.values(), self.participant_norm, self.balance):
            box.toggled.connect(self._changed)
        self.set_kwargs(DEFAULTS)
        self._unfold(False)

    # --- values ------------------------------------------------------------------------
    def kwargs(self) -> dict[str, Any]:
        """The recipe as ``ExperimentConfig`` keyword arguments."""
        window = self.window.value()
        return {"window_s": window if window > 0 else None,
                "window_overlap": self.overlap.value() / 100,
                "aggregate": self.aggregate.currentData(),
                "augment": ",".join(k for k, box in self.kinds.items() if box.isChecked()),
                "augment_copies": self.copies.value(),
                "participant_norm": self.participant_norm.isChecked(),
                "balance": self.balance.isChecked(),
                "val_by": self.val_by.currentData()}

    def set_kwargs(self, values: dict[str, Any]) -> None:
        """Show ``values`` (missing or unknown ones keep the default)."""
        v = {**DEFAULTS, **{k: x for k, x in values.items() if k in DEFAULTS}}
        self.window.setValue(float(v["window_s"] or 0.0))
        self.overlap.setValue(round(100 * float(v["window_overlap"])))
        self.aggregate.setCurrentIndex(max(0, self.aggregate.findData(v["aggregate"])))
        kinds = KINDS if v["augment"] == "all" else str(v["augment"]).split(",")
        for k, box in self.kinds.items():
            box.setChecked(k in kinds)
        self.copies.setValue(int(v["augment_copies"]))
        self.participant_norm.setChecked(bool(v["participant_norm"]))
        self.balance.setChecked(bool(v["balance"]))
        self.val_by.setCurrentIndex(max(0, self.val_by.findData(v["val_by"])))
        self._changed()

    def summary(self) -> str:
        """The changes from the defaults in a few words ("defaults" if none)."""
        v = self.kwargs()
        parts = []
        if v["window_s"] is not None:
            parts.append(f"{v['window_s']:g} s windows")
        if v["window_overlap"] != DEFAULTS["window_overlap"]:
            parts.append(f"{100 * v['window_overlap']:.0f}% overlap")
        if v["aggregate"] == "vote":
            parts.append("vote")
        if v["augment"]:
            copies = f" x{v['augment_copies']}" if v["augment_copies"] > 1 else ""
            kinds = "all" if len(v["augment"].split(",")) == len(KINDS) \
                else v["augment"].replace(",", "+")
            parts.append(f"augment {kinds}{copies}")
        if v["participant_norm"]:
            parts.append("participant norm")
        if v["balance"]:
            parts.append("balanced")
        if v["val_by"] == "participant":
            parts.append("early stop on people")
        return ", ".join(parts) or "defaults"

    def offer_epoch_options(self, on: bool) -> None:
        """Early stopping only for a model that trains in epochs (not rf / knn)."""
        self.form.setRowVisible(self.val_by, on)

    # --- settings ----------------------------------------------------------------------
    def load(self, settings: QSettings, key: str) -> None:
        saved = get_json(settings, key, {})
        self.set_kwargs(saved if isinstance(saved, dict) else {})

    def set_saved(self, saved: Any) -> None:
        """A saved value (anything but a dict, e.g. a damaged entry, is the empty recipe)."""
        self.set_kwargs(saved if isinstance(saved, dict) else {})

    def save(self, settings: QSettings, key: str) -> None:
        set_json(settings, key, self.kwargs())

    # --- view --------------------------------------------------------------------------
    def _changed(self, *_: Any) -> None:
        self.copies.setEnabled(any(box.isChecked() for box in self.kinds.values()))
        self.summary_label.setText(self.summary())

    def _unfold(self, on: bool) -> None:
        self.body.setVisible(on)
        self.header.setArrowType(Qt.ArrowType.DownArrow if on else Qt.ArrowType.RightArrow)
