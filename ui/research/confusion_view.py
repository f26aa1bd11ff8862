"""The linked confusion matrix: mode, order and filters above, the matrix, and the
trials behind the clicked cell (double-click one to open it in the session player)."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QBuffer, QByteArray, QIODevice, QRect, QSize, Signal
from PySide6.QtGui import QPainter
from PySide6.QtSvg import QSvgGenerator
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.learn.results.confusion import ConfusionModel
from tactile_studio.learn.results.trialpreds import RunPredictions, TrialPrediction
from tactile_studio.ui.research.matrix_widget import MatrixWidget
from tactile_studio.ui.write_faults import write_image

MODES = [("Counts", "counts"), ("Row % (of true)", "row"), ("Column % (of predicted)", "column")]
TRIAL_COLUMNS = ("participant", "session", "trial", "true", "predicted", "confidence",
                 "runner-up")


class ConfusionView(QWidget):
    trialActivated = Signal(object)  # TrialPrediction

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.run: RunPredictions | None = None
        self.model: ConfusionModel | None = None
        self.cell_rows: list[TrialPrediction] = []
        self.title = QLabel("Open a run from the Runs tab.")
        self.mode = QComboBox()
        for text, _ in MODES:
            self.mode.addItem(text)
        self.ordered = QCheckBox("Order by confusion")
        self.participant = QComboBox()
        self.condition = QComboBox()
        self.shots = QComboBox()  # a few-shot run's K (train --shots); hidden otherwise
        self.shots.setToolTip("few-shot personalisation: the folds trained with K labelled "
                              "performances per gesture of the test person (each test "
                              "trial is scored once per K)")
        self.shots_label = QLabel("Shots per gesture")
        self.export_png = QPushButton("PNG…")
        self.export_svg = QPushButton("SVG…")
        self.export_csv = QPushButton("CSV…")
        bar = QHBoxLayout()
        for w in (QLabel("Show"), self.mode, self.ordered, QLabel("Participant"),
                  self.participant, QLabel("Condition"), self.condition,
                  self.shots_label, self.shots):
            bar.addWidget(w)
        bar.addStretch(1)
        for w in (QLabel("Export"), self.export_png, self.export_svg, self.export_csv):
            bar.addWidget(w)
        for button in (self.export_png, self.export_svg, self.export_csv):
            button.setEnabled(False)  # nothing to export until a run is shown
        self.matrix = MatrixWidget()
        self.matrix.tooltip = self._tooltip
        self.cell_label = QLabel("Click a cell to list its trials.")
        self.cell_label.setWordWrap(True)
        self.table = QTableWidget(0, len(TRIAL_COLUMNS))
        self.table.setHorizontalHeaderLabels(TRIAL_COLUMNS)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.table.verticalHeader().hide()
        side = QWidget()
        sl = QVBoxLayout(side)
        sl.setContentsMargins(0, 0, 0, 0)
        sl.addWidget(self.cell_label)
        sl.addWidget(self.table, 1)
        split = QSplitter()
        split.addWidget(self.matrix)
        split.addWidget(side)
        split.setStretchFactor(0, 1)
        split.setStretchFactor(1, 1)
        split.setSizes([760, 640])
        self.table.horizontalHeader().setStretchLastSection(True)
        lay = QVBoxLayout(self)
        lay.addWidget(self.title)
        lay.addLayout(bar)
        lay.addWidget(split, 1)
        self.mode.currentIndexChanged.connect(self.refresh)
        self.ordered.toggled.connect(self._order_changed)
        self.participant.currentIndexChanged.connect(self._filter_changed)
        self.condition.currentIndexChanged.connect(self._filter_changed)
        self.shots.currentIndexChanged.connect(self._shots_changed)
        self.matrix.cellClicked.connect(self.show_cell)
        self.table.cellDoubleClicked.connect(
            lambda r, _c: self.trialActivated.emit(self.cell_rows[r]))

    # --- data --------------------------------------------------------------------------
    def set_run(self, run: RunPredictions) -> None:
        self.run = run
        self.model = ConfusionModel(run.labels, run.trials)
        for button in (self.export_png, self.export_svg, self.export_csv):
            button.setEnabled(True)
        for combo, values in ((self.participant, self.model.participants),
                              (self.condition, self.model.conditions)):
            combo.blockSignals(True)
            combo.clear()
            combo.addItem("all")
            combo.addItems(values)
            combo.blockSignals(False)
        self.shots.blockSignals(True)
        self.shots.clear()
        for k in self.model.shot_counts:
            self.shots.addItem(f"K = {k}", k)
        self.shots.blockSignals(False)
        for w in (self.shots, self.shots_label):
            w.setVisible(bool(self.model.shot_counts))
        self._redraw_from_scratch()

    @property
    def mode_key(self) -> str:
        return MODES[self.mode.currentIndex()][1]

    def _filter_changed(self) -> None:
        if self.model is None:
            return
        p, c = self.participant.currentText(), self.condition.currentText()
        self.model.set_filter(None if p == "all" else p, None if c == "all" else c)
        self.refresh()

    def _shots_changed(self) -> None:
        if self.model is None or self.shots.currentData() is None:
            return
        self.model.set_shots(int(self.shots.currentData()))
        self._redraw_from_scratch()

    def _redraw_from_scratch(self) -> None:
        """Another run or K: its order, no selected cell, no trial rows of the last one."""
        if self.ordered.isChecked():
            self.model.order_by_confusion()
        self.table.setRowCount(0)
        self.cell_rows = []
        self.matrix.selected = None
        self.refresh()

    def _order_changed(self, on: bool) -> None:
        if self.model is not None:
            self.model.order_by_confusion() if on else self.model.reset_order()
            self.refresh()

    def refresh(self) -> None:
        m = self.model
        if m is None or self.run is None:
            return
        mode = self.mode_key
        values = m.matrix(mode)
        texts = [[str(int(v)) if mode == "counts" else (f"{100 * v:.0f}%" if v else "")
                  for v in row] for row in values]
        if mode == "counts":
            texts = [[t if t != "0" else "" for t in row] for row in texts]
        pc = m.per_class()
        margins = {k.upper() if k == "f1" else k[0].upper(): [f"{v:.2f}" for v in pc[k]]
                   for k in ("precision", "recall", "f1")}
        scale = float(values.max()) if mode == "counts" and values.size else 1.0
        shown = len(m.selected())
        title = (f"{self.run.name} · {self.run.config.get('model', '')} · "
                 f"{self.run.config.get('channels') or 'all'} · accuracy "
                 f"{100 * m.accuracy():.1f}% over {shown} trials"
                 + (f" · K={m.shots} shot(s) per gesture" if m.shots is not None else ""))
        self.title.setText(str(self.run.path))
        self.matrix.set_matrix(m.ordered_labels(), values, texts, margins, False,
                               max(scale, 1.0), title)

    def _tooltip(self, row: int, col: int) -> str:
        assert self.model is not None
        n, of_true, of_pred = self.model.cell_info(row, col)
        labels = self.model.ordered_labels()
        return (f"true {labels[row]} → predicted {labels[col]}: {n} trials\n"
                f"{100 * of_true:.1f}% of {labels[row]} · {100 * of_pred:.1f}% of the "
                f"{labels[col]} predictions")

    def show_cell(self, row: int, col: int) -> None:
        assert self.model is not None
        labels = self.model.ordered_labels()
        self.cell_rows = self.model.cell_trials(row, col)
        self.cell_label.setText(f"{len(self.cell_rows)} trial(s): true {labels[row]}, "
                                f"predicted {labels[col]} (double-click to play)")
        names = self.model.labels
        self.table.setRowCount(len(self.cell_rows))
        for r, t in enumerate(self.cell_rows):
            for c, v in enumerate((t.participant, t.session, str(t.number), names[t.true],
                                   names[t.pred], f"{t.confidence:.2f}", names[t.runner_up])):
                self.table.setItem(r, c, QTableWidgetItem(v))

    # --- export ------------------------------------------------------------------------
    def export(self, path: str | Path) -> None:
        """PNG, SVG or CSV by the file's suffix."""
        path = Path(path)
        if self.model is None:
            return
        if path.suffix.lower() == ".csv":
            self.model.write_csv(path, self.mode_key)
            return
        size = self.matrix.minimumSizeHint().expandedTo(QSize(700, 600))
        if path.suffix.lower() == ".svg":
            # drawn in memory, written by Python: an unwritable place raises its OSError
            # (Qt's own file writing fails silently)
            data = QByteArray()
            buffer = QBuffer(data)
            buffer.open(QIODevice.OpenModeFlag.WriteOnly)
            gen = QSvgGenerator()
            gen.setOutputDevice(buffer)
            gen.setSize(size)
            gen.setViewBox(QRect(0, 0, size.width(), size.height()))
            gen.setTitle(self.run.name if self.run else "confusion matrix")
            p = QPainter(gen)
            self.matrix.paint(p, size.width(), size.height())
            p.end()
            buffer.close()
            path.write_bytes(bytes(data.data()))
        else:
            from PySide6.QtGui import QColor, QImage

            img = QImage(size, QImage.Format.Format_ARGB32)
            img.fill(QColor("white"))
            p = QPainter(img)
            self.matrix.paint(p, size.width(), size.height())
            p.end()
            write_image(img, path)
