"""The setup's trial check: a QC model (a run folder or a model exported from one), its
top-k and threshold, and which of the protocol's gestures it cannot score.

Chosen once per study and remembered per protocol (QSettings, as the other setup fields);
the chooser opens where the experimenter last was. No model: the signal checks (contact,
saturation, a stuck channel, off-centre, gaps) still run. The model itself is loaded by
the core's ``ModelTrialCheck`` (learn/deploy/trial_check.py): here only to say what it
knows; the console loads it again for the participant when the session opens (the fold
that never saw them).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSettings, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.protocol.trial_check import TrialChecker
from tactile_studio.storage.format.trial_checks import (
    DEFAULT_PERSONALISE,
    DEFAULT_THRESHOLD,
    DEFAULT_TOP_K,
)
from tactile_studio.ui.file_dialogs import ask_folder, ask_open_file
from tactile_studio.ui.settings import get_json, set_json

KEY_QC = "collect/qc_model/"  # + protocol name: {"model", "top_k", "threshold", "personalise"}
DIALOG_KIND = "qc_model"
NO_MODEL = ("No QC model: each trial's signal is still checked (contact, saturation, a "
            "stuck channel, off-centre, gaps).")


@dataclass(frozen=True)
class QcChoice:
    """The setup's trial check (``model`` None: signal checks only)."""

    model: str | None = None
    top_k: int = DEFAULT_TOP_K
    threshold: float = DEFAULT_THRESHOLD
    ready: TrialChecker | None = None  # already built (a script's own): used as it is
    personalise: bool = False  # fit the check to the participant after their first block
    # (the setup's box starts ticked, DEFAULT_PERSONALISE, and is remembered per study)

    def checker(self, participant: str) -> TrialChecker | None:
        """The core's ModelTrialCheck for ``participant`` (None without a model); a model
        that cannot check is a one-line UserError."""
        if self.ready is not None:
            return self.ready
        if not self.model:
            return None
        from tactile_studio.learn.deploy.trial_check import ModelTrialCheck  # torch: at use
        return ModelTrialCheck(self.model, self.top_k, self.threshold, participant=participant)


class QcModelField(QWidget):
    """Model path with "Run folder..." / "Model file..." / "None", top-k, threshold and a
    line saying what the model scores."""

    changed = Signal()

    def __init__(self, settings: QSettings, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings
        self._study = ""
        self._gestures: list[str] = []
        self.known: frozenset[str] | None = None  # the chosen model's gestures
        self.path = QLineEdit()
        self.path.setPlaceholderText("none: signal checks only")
        self.path.setReadOnly(True)
        self.run_button = QPushButton("Run folder\u2026")
        self.run_button.setToolTip("a training run of earlier participants (its fold that "
                                   "never saw this participant checks them)")
        self.file_button = QPushButton("Model file\u2026")
        self.file_button.setToolTip("a model exported from a run (RUN/export/<fold>.onnx)")
        self.clear_button = QPushButton("None")
        self.clear_button.setToolTip("no model: the signal checks only")
        self.top_k = QSpinBox()
        self.top_k.setRange(0, 50)
        self.top_k.setSpecialValueText("off")
        self.top_k.setToolTip("or when the prompted gesture is not among the model's most "
                              "likely k (off by default: it flagged more honest trials than "
                              "it caught mistakes on people)")
        self.threshold = QDoubleSpinBox()
        self.threshold.setRange(0.0, 1.0)
        self.threshold.setDecimals(2)
        self.threshold.setSingleStep(0.01)
        self.threshold.setToolTip("flag a trial when the model's probability of the "
                                  "prompted gesture is below this")
        self.personalise = QCheckBox("Fit the check to each participant after their first "
                                     "block")
        self.personalise.setToolTip(
            "refit the model with the participant's own first-block trials (the few-shot "
            "route), off the screen's thread; their later trials are checked by it")
        self.info = QLabel(NO_MODEL)
        self.info.setWordWrap(True)
        self.info.setStyleSheet("color: #606770;")
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.path, 1)
        for w in (self.run_button, self.file_button, self.clear_button):
            row.addWidget(w)
        settings_row = QHBoxLayout()
        settings_row.setContentsMargins(0, 0, 0, 0)
        settings_row.addWidget(QLabel("Flag a trial when p(prompted gesture) <"))
        settings_row.addWidget(self.threshold)
        settings_row.addWidget(QLabel("or it is not in the model's top"))
        settings_row.addWidget(self.top_k)
        settings_row.addStretch(1)
        box = QVBoxLayout(self)
        box.setContentsMargins(0, 0, 0, 0)
        box.addLayout(row)
        box.addLayout(settings_row)
        box.addWidget(self.personalise)
        box.addWidget(self.info)
        self.run_button.clicked.connect(self.choose_run)
        self.file_button.clicked.connect(self.choose_file)
        self.clear_button.clicked.connect(lambda: self.set_model(None))
        self.top_k.valueChanged.connect(self._remember)
        self.threshold.valueChanged.connect(self._remember)
        self.personalise.toggled.connect(self._remember)
        self._set_settings(DEFAULT_TOP_K, DEFAULT_THRESHOLD)

    # ---- per study ------------------------------------------------------------------
    def set_study(self, name: str, gestures: list[str]) -> None:
        """The protocol chosen: its remembered model and settings, and what it scores."""
        self._study, self._gestures = name, list(gestures)
        saved = get_json(self.settings, KEY_QC + name, {}) if name else {}
        saved = saved if isinstance(saved, dict) else {}
        self._set_settings(saved.get("top_k", DEFAULT_TOP_K),
                           saved.get("threshold", DEFAULT_THRESHOLD),
                           saved.get("personalise", DEFAULT_PERSONALISE) is True)
        self.set_model(saved.get("model") or None, remember=False)

    def _set_settings(self, top_k: object, threshold: object,
                      personalise: bool = DEFAULT_PERSONALISE) -> None:
        self.personalise.blockSignals(True)
        self.personalise.setChecked(personalise)
        self.personalise.blockSignals(False)
        for w, v in ((self.top_k, top_k), (self.threshold, threshold)):
            w.blockSignals(True)
            try:
                w.setValue(type(w.value())(v))
            except (TypeError, ValueError):
                pass
            w.blockSignals(False)

    def _remember(self, *_: object) -> None:
        if self._study:
            set_json(self.settings, KEY_QC + self._study, {
                "model": self.path.text() or None, "top_k": self.top_k.value(),
                "threshold": round(self.threshold.value(), 4),
                "personalise": self.personalise.isChecked()})
        self.changed.emit()

    # ---- the model --------------------------------------------------------------------
    def choose_run(self) -> None:
        folder = ask_folder(self, "QC model: a run folder", DIALOG_KIND, self.path.text())
        if folder:
            self.set_model(folder)

    def choose_file(self) -> None:
        path = ask_open_file(self, "QC model: an exported model", DIALOG_KIND,
                             "Exported models (*.onnx)")
        if path:
            self.set_model(path)

    def set_model(self, path: str | None, remember: bool = True) -> bool:
        """Use the model at ``path`` (None: none); False (said on the info line) when it
        cannot check trials; the field then keeps no model."""
        self.known = None
        text, ok = NO_MODEL, True
        if path:
            try:
                checker = QcChoice(str(path), self.top_k.value(),
                                   self.threshold.value()).checker("")
            except UserError as exc:
                text, ok, path = f"\u26a0 {exc}; no QC model", False, None
            else:
                self.known = checker.known
                text = self._scores(checker.describe())
        self.personalise.setEnabled(bool(path))
        self.path.setText(str(path or ""))
        self.path.setToolTip(str(path or ""))
        self.info.setText(text)
        self.info.setStyleSheet("color: #606770;" if ok else "color: #c0392b;")
        if remember:
            self._remember()
        return ok

    def _scores(self, about: dict[str, Any]) -> str:
        """"rf-earlier (rf) scores 8 of the 9 gestures; not scored: Tickle"."""
        known = self.known or frozenset()
        missing = [g for g in self._gestures if g not in known]
        n = len(self._gestures) - len(missing)
        run = Path(str(about.get("run") or about.get("model") or "the model")).name
        head = f"{run} ({about['family']})" if about.get("family") else run
        if not self._gestures:
            return f"{head}: knows {', '.join(sorted(known))}"
        if not n:
            return (f"\u26a0 {head} knows none of the protocol's gestures: no trial will be "
                    "scored (the signal checks still run)")
        scored = "all" if not missing else f"{n} of the"
        return (f"{head} scores {scored} {len(self._gestures)} gestures"
                + (f"; not scored: {', '.join(missing)}" if missing else ""))

    def prefill(self, model: str, top_k: int = DEFAULT_TOP_K,
                threshold: float = DEFAULT_THRESHOLD,
                personalise: bool = DEFAULT_PERSONALISE) -> bool:
        """The ``collect --qc-model`` options (remembered for the study, as if chosen)."""
        self._set_settings(top_k, threshold, personalise)
        return self.set_model(model)

    def choice(self) -> QcChoice:
        return QcChoice(self.path.text() or None, self.top_k.value(),
                        round(self.threshold.value(), 4),
                        personalise=bool(self.path.text()) and self.personalise.isChecked())
