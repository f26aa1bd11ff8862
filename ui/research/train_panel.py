"""Train / evaluate panel: an experiment from the model registry, run in a worker
process (learn/experiments/train_job.py) with live per-fold curves, a fold table, ETA, cancel and
resume; the channel ablation (normal / shear / both) is one click."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pyqtgraph as pg
from PySide6.QtCore import QSettings, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import CHANNEL_SETS, SHOTS_BY
from tactile_studio.learn.data.splits import parse_shot_counts
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.job_events import (
    Cancelled,
    Done,
    Epoch,
    Failed,
    Fold,
    JobEvent,
    Progress,
)
from tactile_studio.learn.experiments.train_job import (
    TrainJob,
    model_settings,
    trains_in_epochs,
)
from tactile_studio.learn.learners.baselines import DEFAULT_MODEL
from tactile_studio.learn.learners.families import available_models
from tactile_studio.learn.learners.generalise import ADAPT_AUTO
from tactile_studio.paths import data_dir
from tactile_studio.ui.file_dialogs import ask_folder
from tactile_studio.ui.research.bound_settings import BoundSettings
from tactile_studio.ui.research.choices import (
    SHOTS_BY_TEXT,
    adapt_combo,
    channels_combo,
    evaluation_combo,
    grid_combo,
    preset_combo,
)
from tactile_studio.ui.research.job_panel import JobPanel
from tactile_studio.ui.research.recipe_form import DEFAULTS as RECIPE_DEFAULTS
from tactile_studio.ui.research.recipe_form import RecipeForm
from tactile_studio.ui.research.tables import make_table
from tactile_studio.ui.research.timeline import PALETTE
from tactile_studio.ui.settings import (
    app_settings,
)

FOLD_COLUMNS = ["run", "fold", "epochs", "best val acc", "test accuracy per trial", "status"]
KEY = "research/train/"


def _typed(text: str, default: Any) -> Any:
    if isinstance(default, bool):
        return text.strip().lower() in ("1", "true", "yes", "on")
    for kind in (int, float):
        if isinstance(default, kind):
            return kind(text)
    return text


class TrainPanel(JobPanel):
    CANCELLING = "cancelling after the current epoch (finished folds are kept)…"
    runFinished = Signal(str)
    ablationFinished = Signal(list)
    sweepRequested = Signal(str, str)  # model, channel set: continue in the Sweep tab
    error = Signal(str)

    def __init__(self, data_paths: Callable[[], list[str]], settings: QSettings | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.data_paths = data_paths
        self.settings = settings or app_settings()
        self.job: TrainJob | None = None
        self.queue: list[tuple[ExperimentConfig, str]] = []
        self.ablation: list[str] = []
        self.curves: dict[tuple[str, int, int], Any] = {}
        self.history: dict[tuple[str, int, int], tuple[list[float], list[float]]] = {}
        self.fold_rows: dict[tuple[str, int, int], int] = {}
        self._build_run_choices()
        self._build_shot_choices()
        out_row = self._build_run_folder()
        split = QSplitter()
        split.addWidget(self._build_setup_side(out_row))
        split.addWidget(self._build_results_side())
        split.setSizes([430, 800])
        QVBoxLayout(self).addWidget(split)
        self._connect()
        self.bound = self._bind_settings()
        self._load_settings()
        self.fill_options()
        self._evaluation_changed()
        self._set_running(False)

    # --- the tab's parts -----------------------------------------------------------------
    def _build_run_choices(self) -> None:
        """Model, preset, channels, grid, evaluation, rounds, epochs, test people."""
        self.model = QComboBox()
        for name, text in available_models().items():
            self.model.addItem(name)
            self.model.setItemData(self.model.count() - 1, text, 3)  # tooltip role
        self.model.setCurrentText(DEFAULT_MODEL)
        self.preset = preset_combo()
        self.channels = channels_combo()
        self.grid = grid_combo()
        self.evaluation = evaluation_combo()
        self.rounds = QSpinBox()
        self.rounds.setRange(1, 20)
        self.epochs = QSpinBox()
        self.epochs.setRange(0, 1000)
        self.epochs.setSpecialValueText("model default")
        self.adapt = adapt_combo()

    def _build_shot_choices(self) -> None:
        """Few-shot personalisation (train --shots, --shots-by) and the flagged trials."""
        self.shots = QLineEdit()
        self.shots.setPlaceholderText("off (e.g. 0,1,2)")
        self.shots.setToolTip(
            "Few-shot personalisation (lopo / group-kfold): each held-out person once per "
            "K, with K labelled performances per gesture of theirs and their other "
            "performances tested (the same ones at every K): the curve over K shows what a "
            "few labelled touches of a new person gain. rf and knn refit with them; a "
            "network is trained once without them and its output layers fine-tuned on "
            "them (train --shots-by). Whole performances, never single windows")
        self.shots_by = QComboBox()  # train --shots-by
        for value in SHOTS_BY:
            self.shots_by.addItem(SHOTS_BY_TEXT[value], value)
        self.shots_by.setToolTip(
            "How the shots reach the model. join: they join the training, one training per "
            "K. fine-tune (networks only): the fold is trained once without them and its "
            "output layers fine-tuned on each K's shots, as live calibration does. auto: "
            "fine-tune for a network (as good on the simulator, half the time), join for "
            "rf, knn and a network fused with rf")
        self.exclude_flagged = QCheckBox("leave out trials the collection flagged")
        self.exclude_flagged.setToolTip(
            "train --exclude-flagged: trials with a quality flag (no contact, saturated, a "
            "stuck channel, off-centre...) or a model check's flag are left out of training "
            "and testing (the run's config says so); off: every ok trial is used")

    def _build_run_folder(self) -> QHBoxLayout:
        """The run folder line and its Browse button."""
        self.out = QLineEdit()
        self.out.setPlaceholderText("run folder (re-use it to resume)")
        self.out.setToolTip("Named from the model and the time, under the runs folder "
                            "(the last one used); type or browse for another")
        self._auto_out = ""  # the folder name the panel chose (it follows the model)
        self.browse_out = QPushButton("Browse…")
        self.browse_out.clicked.connect(self.choose_out)
        out_row = QHBoxLayout()
        out_row.setContentsMargins(0, 0, 0, 0)
        out_row.addWidget(self.out, 1)
        out_row.addWidget(self.browse_out)
        return out_row

    def _build_setup_side(self, out_row: QHBoxLayout) -> QWidget:
        """The left side: the form, the recipe, the options table and the buttons."""
        self.recipe = RecipeForm()
        self.options = QTableWidget(0, 3)
        self.options.setHorizontalHeaderLabels(["option", "value", "help"])
        self.options.verticalHeader().hide()
        self.options.horizontalHeader().setStretchLastSection(True)
        self.form = form = QFormLayout()
        for label, w in (("Model", self.model), ("Preset", self.preset),
                         ("Channels", self.channels), ("Grid", self.grid),
                         ("Evaluation", self.evaluation), ("Rounds", self.rounds),
                         ("Epochs", self.epochs), ("Test people", self.adapt),
                         ("Shots per gesture of\nthe held-out person", self.shots),
                         ("Shots reach the model", self.shots_by),
                         ("Flagged trials", self.exclude_flagged)):
            form.addRow(label, w)
        form.addRow("Run folder", out_row)
        self.start_button = QPushButton("Train")
        self.cancel_button = QPushButton("Cancel")
        self.resume_button = QPushButton("Resume")
        self.ablate_button = QPushButton("Channel ablation: " + " / ".join(CHANNEL_SETS))
        self.sweep_button = QPushButton("Compare several models in parallel (Sweep tab)…")
        self.sweep_button.setToolTip("models x channel sets on local worker processes or "
                                     "a Ray cluster, with a results table")
        buttons = QHBoxLayout()
        for b in (self.start_button, self.cancel_button, self.resume_button):
            buttons.addWidget(b)
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addLayout(form)
        ll.addWidget(self.recipe)
        ll.addWidget(QLabel("Model and training options (edit a value to override it)"))
        ll.addWidget(self.options, 1)
        ll.addLayout(buttons)
        ll.addWidget(self.ablate_button)
        ll.addWidget(self.sweep_button)
        return left

    def _build_results_side(self) -> QWidget:
        """The right side: progress, status, the validation curves and the fold table."""
        self.progress = QProgressBar()
        self.status = QLabel("Pick sessions in the Sessions tab, then Train.")
        self.status.setWordWrap(True)
        self.plot = pg.PlotWidget(background="w")
        self.plot.setLabel("left", "validation accuracy")
        self.plot.setLabel("bottom", "epoch")
        self.plot.setYRange(0, 1)
        # the legend at the bottom right, in two columns: at the top right it covered the
        # curves where accuracy ends up; below them it is clear once training learns
        self.plot.addLegend(offset=(-10, -10), labelTextSize="8pt", colCount=2,
                            verSpacing=-6)
        self.folds = make_table(FOLD_COLUMNS)
        right = QWidget()
        rl = QVBoxLayout(right)
        rl.addWidget(self.progress)
        rl.addWidget(self.status)
        rl.addWidget(self.plot, 3)
        rl.addWidget(self.folds, 2)
        return right

    def _connect(self) -> None:
        self.model.currentIndexChanged.connect(self.fill_options)
        self.model.currentIndexChanged.connect(lambda _: self._follow_model())
        self.preset.currentIndexChanged.connect(self.fill_options)
        self.evaluation.currentIndexChanged.connect(self._evaluation_changed)
        self.start_button.clicked.connect(self.start)
        self.resume_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel)
        self.ablate_button.clicked.connect(self.start_ablation)
        self.sweep_button.clicked.connect(lambda: self.sweepRequested.emit(
            self.model.currentText(), self.channels.currentText()))

    # --- setup -------------------------------------------------------------------------
    def _text_choices(self) -> tuple[tuple[str, QComboBox], ...]:
        return (("model", self.model), ("preset", self.preset), ("channels", self.channels),
                ("grid", self.grid), ("evaluation", self.evaluation))

    def _bind_settings(self) -> BoundSettings:
        """Every remembered choice of the tab, in one list (see bound_settings.py)."""
        b = BoundSettings(KEY)
        for key, combo in self._text_choices():
            b.combo_text(key, combo)
        b.combo_data("adapt", self.adapt, ADAPT_AUTO)
        b.spin("rounds", self.rounds, 1)
        b.spin("epochs", self.epochs, 0)
        b.text("shots", self.shots)
        b.combo_data("shots_by", self.shots_by, "auto")
        b.text("out", self.out)
        b.check("exclude_flagged", self.exclude_flagged)
        b.renamed("evaluation", formerly="protocol")  # issue 44's rename
        b.json("recipe", self.recipe.kwargs, self.recipe.set_saved, {})
        return b

    def _load_settings(self) -> None:
        """The choices of the last run started here (a name no longer offered is skipped)."""
        self.bound.load(self.settings)
        if not self.out.text() or not (Path(self.out.text()) / "config.json").is_file():
            self.new_run_folder()  # a finished or never-started folder: a new run's name

    def save_settings(self) -> None:
        self.bound.save(self.settings)

    def fill_options(self) -> None:
        try:
            rows = model_settings(self.model.currentText(), self.preset.currentText())
            epochs = trains_in_epochs(self.model.currentText(), self.preset.currentText())
        except UserError as exc:
            self.error.emit(str(exc))
            rows, epochs = [], True
        self._offer_epoch_options(epochs)
        self.defaults = {k: v for k, v, _ in rows}
        self.options.setRowCount(len(rows))
        for r, (k, v, h) in enumerate(rows):
            for c, text in enumerate((k, str(v), h)):
                item = QTableWidgetItem(text)
                if c != 1:
                    item.setFlags(item.flags() & ~item.flags().ItemIsEditable)
                self.options.setItem(r, c, item)
        self.options.resizeColumnsToContents()

    def _offer_epoch_options(self, on: bool) -> None:
        """A model that trains in epochs (a network) gets its epochs, early stopping,
        fine-tuning and the validation-curve plot; rf and knn fit once: none of these,
        and the fold table takes the plot's room."""
        self.epoch_model = on
        self.form.setRowVisible(self.epochs, on)
        self.form.setRowVisible(self.shots_by, on)  # rf / knn: the shots always join
        self.recipe.offer_epoch_options(on)
        self.plot.setVisible(on)
        for name in ("epochs", "best val acc"):
            self.folds.setColumnHidden(FOLD_COLUMNS.index(name), not on)

    def overrides(self) -> dict[str, Any]:
        out = {}
        for r in range(self.options.rowCount()):
            key, text = self.options.item(r, 0).text(), self.options.item(r, 1).text()
            default = self.defaults.get(key)
            if text != str(default):
                try:
                    out[key] = _typed(text, default)
                except ValueError:
                    raise UserError(f"option {key}: {text!r} is not a {type(default).__name__}") \
                        from None
        return out

    def config(self, channels: str | None = None) -> ExperimentConfig:
        data = self.data_paths()
        if not data:
            raise UserError("no sessions selected: pick sessions with ok trials in the "
                            "Sessions tab")
        recipe = self.recipe.kwargs()
        if not self.epoch_model:  # what is not offered is not asked for (rf / knn)
            recipe["val_by"] = RECIPE_DEFAULTS["val_by"]
        return ExperimentConfig(
            data=data, model=self.model.currentText(), preset=self.preset.currentText(),
            channels=channels or self.channels.currentText(), grid=self.grid.currentText(),
            evaluation=self.evaluation.currentText(), rounds=self.rounds.value(),
            epochs=(self.epochs.value() or None) if self.epoch_model else None,
            overrides=self.overrides(), threads=1,
            device="cpu", adapt=self.adapt.currentData(), shots=self.shot_counts(),
            shots_by=self.shots_by.currentData() if self.epoch_model else "auto",
            exclude_flagged=self.exclude_flagged.isChecked(), **recipe)

    def shot_counts(self) -> tuple[int, ...]:
        """The K of few-shot personalisation ("0,1,2"), () when off or not offered."""
        if not self.shots.isEnabled():
            return ()
        return parse_shot_counts(self.shots.text())

    def _evaluation_changed(self) -> None:
        """Shots need people held out: lopo and group-kfold only."""
        held_out = self.evaluation.currentText() in ("lopo", "group-kfold")
        self.shots.setEnabled(held_out)
        self.shots_by.setEnabled(held_out)

    def runs_root(self) -> Path:
        """Where new runs go: the parent of the last run folder used here, else ``runs``
        under the app's data folder."""
        last = str(self.settings.value(KEY + "runs_root", "") or "")
        return Path(last) if last else data_dir() / "runs"

    def new_run_folder(self) -> str:
        """A fresh run folder named from the model and the time, in the runs root."""
        name = f"{self.model.currentText()}-{time.strftime('%Y%m%d-%H%M%S')}"
        self._auto_out = str(self.runs_root() / name)
        self.out.setText(self._auto_out)
        self._set_resume_button()
        return self._auto_out

    def _follow_model(self) -> None:
        if self.out.text() == self._auto_out:  # a name the panel chose follows the model
            self.new_run_folder()

    def choose_out(self) -> str:
        """Browse for the run folder (an existing one resumes; a new one is made)."""
        folder = ask_folder(self, "Run folder", "runs", self.out.text().strip() or None)
        if folder:
            self.out.setText(folder)
            self._auto_out = ""
            self.settings.setValue(KEY + "runs_root", str(Path(folder).parent))
            self._set_resume_button()
        return folder

    def _out(self) -> str:
        if not self.out.text().strip():
            self.new_run_folder()
        out = Path(self.out.text().strip()).expanduser()
        self.settings.setValue(KEY + "runs_root", str(out.parent))
        return str(out)

    # --- running -----------------------------------------------------------------------
    def start(self) -> bool:
        try:
            self.queue = [(self.config(), self._out())]
        except UserError as exc:
            self.error.emit(str(exc))
            return False
        self.ablation = []
        self.save_settings()
        return self._next()

    def start_ablation(self) -> bool:
        try:
            root = self._out()
            self.queue = [(self.config(c), str(Path(root) / c)) for c in CHANNEL_SETS]
        except UserError as exc:
            self.error.emit(str(exc))
            return False
        self.ablation = [out for _, out in self.queue]
        self.save_settings()
        return self._next()

    def _next(self) -> bool:
        if not self.queue:
            return False
        config, out = self.queue.pop(0)
        self.launch(TrainJob(config, out).start(),
                    f"training {config.model} ({config.channels}) into {out}…")
        return True

    def before_cancel(self) -> None:
        self.queue = []
        self.ablation = []

    def _set_running(self, on: bool) -> None:
        super()._set_running(on)
        self.ablate_button.setEnabled(not on)
        self._running = on
        self._set_resume_button()

    def _set_resume_button(self) -> None:
        on = getattr(self, "_running", False)
        self.resume_button.setEnabled(not on and bool(self.out.text().strip()) and
                                      (Path(self.out.text().strip()) / "config.json").is_file())

    def on_event(self, job: TrainJob, e: JobEvent) -> None:
        run = Path(job.out).name
        if isinstance(e, Progress):
            self.progress.setValue(int(1000 * e.fraction) // 10)
            eta = job.eta()
            self.status.setText(e.message + (
                f" · about {eta:.0f} s left" if eta is not None
                else " · time left known after the first fold"))
        elif isinstance(e, Epoch):
            self._epoch(run, e)
        elif isinstance(e, Fold):
            self._fold(run, e)

    def _epoch(self, run: str, e: Epoch) -> None:
        key = (run, int(e.round), int(e.fold))
        if int(e.epoch) == 1:  # a fold (re)starts: e.g. the one cancelled, on resume
            self.history[key] = ([], [])
        xs, ys = self.history.setdefault(key, ([], []))
        xs.append(float(e.epoch))
        ys.append(e.accuracy)
        if key not in self.curves:
            colour = PALETTE[len(self.curves) % len(PALETTE)]
            self.curves[key] = self.plot.plot(pen=pg.mkPen(colour, width=2),
                                              name=f"{run} {e.fold_name}")
        self.curves[key].setData(xs, ys)
        self._row(key, e.fold_name, len(xs), max(ys), None, "training")

    def _fold(self, run: str, e: Fold) -> None:
        key = (run, int(e.round), int(e.fold))
        xs, ys = self.history.get(key, ([], []))
        acc = f"{100 * e.trial_accuracy:.1f}%" + (
            f" ({100 * e.accuracy:.1f}% per window)" if e.cut else "")
        self._row(key, e.fold_name, len(xs) or None, max(ys) if ys else None, acc,
                  "resumed" if e.resumed else "done")

    def _row(self, key, name: str, epochs, best, acc: str | None, status: str) -> None:
        if key not in self.fold_rows:
            self.fold_rows[key] = self.folds.rowCount()
            self.folds.insertRow(self.folds.rowCount())
        r = self.fold_rows[key]
        values = [key[0], name, "" if epochs is None else str(epochs),
                  "" if best is None else f"{100 * best:.1f}%",
                  acc or "", status]
        for c, v in enumerate(values):
            self.folds.setItem(r, c, QTableWidgetItem(v))

    def on_finished(self, job: TrainJob) -> None:
        f = job.finished
        self._set_running(False)
        if isinstance(f, Done):
            self.progress.setValue(100)
            curve = f" · few-shot curve {f.shots}" if f.shots else ""
            self.status.setText(f"finished: {f.headline}{curve} ({job.out})")
            for s in f.curve:  # the curve under the folds: all people per K
                acc = s.get("trial_accuracy")
                acc = s.get("accuracy") if acc is None else acc
                self._row((Path(job.out).name, -1, int(s["k"])), f"all, K={s['k']}", None,
                          None, None if acc is None else f"{100 * acc:.1f}%",
                          "few-shot curve")
            self.runFinished.emit(job.out)
            if not self.queue and self.out.text() == self._auto_out:
                self.new_run_folder()  # Train again makes a new run, not a resume
            if self.queue:
                self._next()
            elif self.ablation:
                runs, self.ablation = self.ablation, []
                self.ablationFinished.emit(runs)
        elif isinstance(f, Cancelled):
            self.status.setText(f"cancelled; finished folds are kept in {job.out} — Resume "
                                "continues")
        else:
            message = f.message if isinstance(f, Failed) else "the run ended without a result"
            self.status.setText("stopped: " + message)
            self.error.emit(message)
        self._set_running(False)
