"""Sweep panel: several models x channel sets under one evaluation, run by the
same executors as ``tactile-studio sweep`` (local worker processes or a Ray cluster),
with per-task progress, cancel and the sweep's results table. The sweep itself is
:class:`~tactile_studio.learn.experiments.sweep_job.SweepJob` (core); this widget only gathers the
choices, shows the events and remembers the choices in QSettings."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSettings, Qt, Signal
from PySide6.QtGui import QFont
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import CHANNEL_SETS, EXECUTORS
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.job_events import (
    Cancelled,
    Done,
    Failed,
    JobEvent,
    Progress,
    Task,
)
from tactile_studio.learn.experiments.sweep_job import ExecutorChoice, SweepJob
from tactile_studio.learn.learners.families import available_models
from tactile_studio.learn.learners.generalise import ADAPT_AUTO
from tactile_studio.ui.file_dialogs import ask_folder, remember
from tactile_studio.ui.research.bound_settings import BoundSettings
from tactile_studio.ui.research.choices import (
    EXECUTOR_TEXT,
    adapt_combo,
    evaluation_combo,
    preset_combo,
)
from tactile_studio.ui.research.job_panel import JobPanel
from tactile_studio.ui.research.recipe_form import RecipeForm
from tactile_studio.ui.research.tables import fill_row, make_table
from tactile_studio.ui.settings import (
    app_settings,
)

RESULT_COLUMNS = ["model", "channels", "folds", "accuracy", "trial acc.", "macro F1",
                  "bal. acc.", "kappa", "train s"]
TASK_COLUMNS = ["task", "model", "channels", "fold accuracy", "train s"]
KEY = "research/sweep/"


def _pct(v: Any) -> str:
    return "" if v is None else f"{100 * v:.1f}%"


def _clock(seconds: float | None) -> str:
    if seconds is None:
        return "–"
    s = int(round(seconds))
    return (f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600
            else f"{s // 60}:{s % 60:02d}")


class SweepPanel(JobPanel):
    CANCELLING = "cancelling: stopping the workers (finished tasks are kept)…"
    sweepFinished = Signal(str)   # the sweep folder (its runs/ hold one run per row)
    openRequested = Signal(str)   # a results row's run folder
    error = Signal(str)

    def __init__(self, data_paths: Callable[[], list[str]], settings: QSettings | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.data_paths = data_paths
        self.settings = settings or app_settings()
        self.job: SweepJob | None = None
        self.rows: list[dict[str, Any]] = []
        split = QSplitter()
        split.addWidget(self._build_setup_side(self._build_models_and_channels()))
        split.addWidget(self._build_results_side())
        split.setSizes([380, 820])
        QVBoxLayout(self).addWidget(split)
        self.start_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel)
        self.browse.clicked.connect(self._browse)
        self.executor.currentIndexChanged.connect(self._executor_changed)
        self.results.cellDoubleClicked.connect(self._open_row)
        self.bound = self._bind_settings()
        self._load_settings()
        self._executor_changed()
        self._set_running(False)

    # --- the tab's parts -----------------------------------------------------------------
    def _build_models_and_channels(self) -> QHBoxLayout:
        """The models to tick (every one the pipeline accepts); returns the row of
        channel-set boxes."""
        self.models = QListWidget()
        for name, text in available_models().items():
            item = QListWidgetItem(name)
            item.setToolTip(text)
            item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
            item.setCheckState(Qt.CheckState.Unchecked)
            self.models.addItem(item)
        self.models.setSpacing(1)
        rows = self.models.sizeHintForRow(0) + 2 * self.models.spacing()
        self.models.setFixedHeight(rows * self.models.count() + 2 * self.models.frameWidth() + 4)
        self.channel_boxes = {c: QCheckBox(c) for c in CHANNEL_SETS}
        channels = QHBoxLayout()
        for box in self.channel_boxes.values():
            channels.addWidget(box)
        channels.addStretch(1)
        return channels

    def _build_setup_side(self, channels: QHBoxLayout) -> QWidget:
        """The left side: the form (models, channels, training, executor, folder) and
        the buttons."""
        self.preset = preset_combo()
        self.evaluation = evaluation_combo()
        self.rounds = QSpinBox()
        self.rounds.setRange(1, 20)
        self.epochs = QSpinBox()
        self.epochs.setRange(0, 1000)
        self.epochs.setSpecialValueText("model default")
        self.adapt = adapt_combo()
        self.recipe = RecipeForm()
        executor_row = self._build_executor()
        form = QFormLayout()
        form.addRow("Models", self.models)
        form.addRow("Channel sets", channels)
        for label, w in (("Preset", self.preset), ("Evaluation", self.evaluation),
                         ("Rounds", self.rounds), ("Epochs", self.epochs),
                         ("Test people", self.adapt), *executor_row):
            form.addRow(label, w)
        form.addRow("Sweep folder", self._build_sweep_folder())
        form.addRow(self.recipe)
        self.start_button = QPushButton("Start sweep")
        self.cancel_button = QPushButton("Cancel")
        buttons = QHBoxLayout()
        buttons.addWidget(self.start_button)
        buttons.addWidget(self.cancel_button)
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addLayout(form)
        ll.addLayout(buttons)
        ll.addStretch(1)
        return left

    def _build_executor(self) -> tuple[tuple[str, QWidget], ...]:
        """Where the tasks run (sweep --executor, --jobs, --address): the form's rows."""
        self.executor = QComboBox()
        for name in EXECUTORS:
            self.executor.addItem(EXECUTOR_TEXT[name], name)
        self.jobs = QSpinBox()
        self.jobs.setRange(1, 512)
        self.jobs.setToolTip("worker processes (local) or CPUs of a local Ray instance")
        self.address = QLineEdit()
        self.address.setPlaceholderText("HOST:PORT (empty: a local Ray instance)")
        return (("Executor", self.executor), ("Jobs", self.jobs),
                ("Ray address", self.address))

    def _build_sweep_folder(self) -> QHBoxLayout:
        self.out = QLineEdit()
        self.out.setPlaceholderText("sweep folder (re-use it to continue a sweep)")
        self.browse = QPushButton("Browse…")
        out_row = QHBoxLayout()
        out_row.addWidget(self.out, 1)
        out_row.addWidget(self.browse)
        return out_row

    def _build_results_side(self) -> QWidget:
        """The right side: progress, the results table and the finished tasks."""
        self.progress = QProgressBar()
        self.counts = QLabel("")
        self.status = QLabel("Pick sessions in the Sessions tab, tick models and channel "
                             "sets, then Start sweep.")
        self.status.setWordWrap(True)
        self.results = make_table(RESULT_COLUMNS)
        self.results.horizontalHeader().setSortIndicator(-1, Qt.SortOrder.AscendingOrder)
        self.results.setSortingEnabled(True)
        self.results.setToolTip("double-click a row to open its run's confusion matrix")
        self.tasks = make_table(TASK_COLUMNS)
        right = QWidget()
        rl = QVBoxLayout(right)
        rl.addWidget(self.progress)
        rl.addWidget(self.counts)
        rl.addWidget(self.status)
        rl.addWidget(QLabel("Results (pooled over folds; trial acc. aggregates each trial's "
                            "windows; rows fill in as folds finish)"))
        rl.addWidget(self.results, 3)
        rl.addWidget(QLabel("Finished tasks (newest first)"))
        rl.addWidget(self.tasks, 2)
        return right

    # --- choices -------------------------------------------------------------------------
    def checked_models(self) -> list[str]:
        return [self.models.item(i).text() for i in range(self.models.count())
                if self.models.item(i).checkState() == Qt.CheckState.Checked]

    def set_models(self, names: list[str]) -> None:
        for i in range(self.models.count()):
            item = self.models.item(i)
            item.setCheckState(Qt.CheckState.Checked if item.text() in names
                               else Qt.CheckState.Unchecked)

    def checked_channels(self) -> list[str]:
        return [c for c, box in self.channel_boxes.items() if box.isChecked()]

    def set_channels(self, sets: list[str]) -> None:
        for c, box in self.channel_boxes.items():
            box.setChecked(c in sets)

    def executor_choice(self) -> ExecutorChoice:
        name = self.executor.currentData()
        return ExecutorChoice(name, self.jobs.value(),
                              self.address.text().strip() or None if name == "ray" else None)

    def config(self) -> ExperimentConfig:
        data = self.data_paths()
        if not data:
            raise UserError("no sessions selected: pick sessions with ok trials in the "
                            "Sessions tab")
        if not self.checked_models():
            raise UserError("tick at least one model")
        if not self.checked_channels():
            raise UserError("tick at least one channel set")
        if not self.out.text().strip():
            raise UserError("choose a sweep folder first")
        return ExperimentConfig(data=data, model=self.checked_models()[0],
                                preset=self.preset.currentText(),
                                evaluation=self.evaluation.currentText(),
                                rounds=self.rounds.value(), epochs=self.epochs.value() or None,
                                threads=1, device="cpu", adapt=self.adapt.currentData(),
                                **self.recipe.kwargs())

    def _executor_changed(self) -> None:
        self.address.setEnabled(self.executor.currentData() == "ray")

    def _browse(self) -> None:
        folder = ask_folder(self, "Sweep folder", "sweep", prefer=self.out.text().strip())
        if folder:
            self.out.setText(folder)

    def _bind_settings(self) -> BoundSettings:
        """Every remembered choice of the tab, in one list (see bound_settings.py)."""
        b = BoundSettings(KEY)
        b.json("models", self.checked_models, self.set_models, ["rf", "knn"])
        b.json("channels", self.checked_channels, self.set_channels, ["normal", "both"])
        b.combo_data("executor", self.executor, "local")
        b.combo_data("adapt", self.adapt, ADAPT_AUTO)
        b.spin("jobs", self.jobs, os.cpu_count() or 1)
        b.text("address", self.address)
        b.combo_text("preset", self.preset)
        b.combo_text("evaluation", self.evaluation)
        b.renamed("evaluation", formerly="protocol")  # issue 44's rename
        b.spin("rounds", self.rounds, 1)
        b.json("recipe", self.recipe.kwargs, self.recipe.set_saved, {})
        return b

    def _load_settings(self) -> None:
        self.bound.load(self.settings)

    def save_settings(self) -> None:
        s = self.settings
        self.bound.save(s)
        if self.out.text().strip():  # a typed folder is where the next Browse… starts
            remember("sweep", Path(self.out.text().strip()).expanduser().parent)
        s.sync()

    # --- running -------------------------------------------------------------------------
    def start(self) -> bool:
        try:
            base = self.config()
        except UserError as exc:
            self.error.emit(str(exc))
            self.status.setText(str(exc))
            return False
        self.save_settings()
        self.tasks.setRowCount(0)
        self._show_rows([])
        self.progress.setValue(0)
        out = str(Path(self.out.text().strip()).expanduser())
        job = SweepJob(base, self.checked_models(), self.checked_channels(),
                       self.executor_choice(), out).start()
        self.launch(job, f"starting: {len(self.checked_models())} model(s) x "
                         f"{len(self.checked_channels())} channel set(s), "
                         f"{self.evaluation.currentText()}, into {out}")
        return True

    def on_event(self, job: SweepJob, e: JobEvent) -> None:
        if isinstance(e, Progress):
            self.progress.setValue(int(100 * e.fraction))
            self.status.setText(e.message)
        elif isinstance(e, Task):
            self._task_row(e)
            self._partial_row(e.row)

    def after_events(self, job: SweepJob) -> None:
        self.counts.setText(f"tasks {job.done} / {job.total or '?'} · elapsed "
                            f"{_clock(job.elapsed())} · about {_clock(job.eta())} left")

    def _task_row(self, e: Task) -> None:
        self.tasks.insertRow(0)  # newest first: the latest task is always in view
        fill_row(self.tasks, 0, [e.id, e.model, e.channels, e.accuracy, e.seconds],
                 [None, None, None, _pct(e.accuracy), f"{e.seconds:.1f}"])

    def _partial_row(self, row: dict[str, Any]) -> None:
        """While running: the (model, channel set)'s row over its folds finished so far."""
        rows = [r for r in self.rows
                if (r["model"], r["channels"]) != (row["model"], row["channels"])]
        self._show_rows(sorted([*rows, row], key=self._order))

    def _order(self, row: dict[str, Any]) -> tuple[int, int]:
        """The sweep's own order: models, then channel sets, as chosen."""
        job = self.job
        models, sets = (job.models, job.channel_sets) if job is not None else ([], [])
        return (models.index(row["model"]) if row["model"] in models else len(models),
                sets.index(row["channels"]) if row["channels"] in sets else len(sets))

    def on_finished(self, job: SweepJob) -> None:
        f = job.finished
        self._set_running(False)
        self.counts.setText(f"tasks {job.done} / {job.total} · took {_clock(job.elapsed())}")
        if isinstance(f, Done):
            self.progress.setValue(100)
            self._show_rows(f.rows)
            best = max((r for r in f.rows if r.get("trial_accuracy") is not None),
                       key=lambda r: r["trial_accuracy"], default=None)
            self.status.setText(f"finished into {job.out}" + (
                f"; best per trial: {best.get('name', best['model'])} on {best['channels']} "
                f"({_pct(best['trial_accuracy'])})" if best else ""))
            self.sweepFinished.emit(job.out)
        elif isinstance(f, Cancelled):
            self._show_rows(f.rows)
            self.status.setText(f"{f.message}; Start sweep with the same folder continues")
            self.sweepFinished.emit(job.out)
        else:
            message = f.message if isinstance(f, Failed) else "the sweep ended without a result"
            self.status.setText("stopped: " + message)
            self.error.emit(message)

    def _show_rows(self, rows: list[dict[str, Any]]) -> None:
        self.rows = list(rows)
        self.results.setSortingEnabled(False)
        self.results.horizontalHeader().setSortIndicator(-1, Qt.SortOrder.AscendingOrder)
        self.results.setRowCount(len(rows))
        best = max((r.get("trial_accuracy") or -1.0 for r in rows), default=None)
        for i, row in enumerate(rows):
            keys = ("accuracy", "trial_accuracy", "f1_macro", "balanced_accuracy", "kappa")
            values = [row.get("name", row["model"]), row["channels"],
                      f"{row['folds_done']}/{row['folds']}",
                      *(row.get(k) for k in keys), row.get("train_seconds")]
            texts = [None, None, None, *(_pct(row.get(k)) for k in keys[:4]),
                     "" if row.get("kappa") is None else f"{row['kappa']:.3f}",
                     "" if row.get("train_seconds") is None else f"{row['train_seconds']:.1f}"]
            fill_row(self.results, i, values, texts)
            for c in range(len(RESULT_COLUMNS)):
                self.results.item(i, c).setData(Qt.ItemDataRole.UserRole + 1, row.get("run"))
            if best is not None and best >= 0 and row.get("trial_accuracy") == best:
                font = QFont(self.results.font())
                font.setBold(True)
                for c in range(len(RESULT_COLUMNS)):
                    self.results.item(i, c).setFont(font)
        self.results.setSortingEnabled(True)

    def _open_row(self, r: int, _c: int) -> None:
        run = self.results.item(r, 0).data(Qt.ItemDataRole.UserRole + 1)
        if run:
            self.openRequested.emit(str(run))
