"""The run folder: everything a training run leaves behind, and reading it back.

Layout::

    RUN/config.json              the experiment config + what it resolved to (reproducible)
    RUN/metrics.json             overall, per-round and per-fold metrics
    RUN/confusion_matrix.csv     row-normalised, labelled
    RUN/confusion_matrix.png
    RUN/trial_confusion_matrix.csv / .png   the same per trial (windows aggregated)
    RUN/training_curves.png      torch models: loss and accuracy per epoch, every fold
    RUN/folds/r0-<fold>/fold.json          split (trial uids), history, predictions, metrics
    RUN/folds/r0-<fold>/model.safetensors  torch models: best-epoch weights
    RUN/folds/r0-<fold>/model.onnx         rf / knn: the fitted model as ONNX (skl2onnx)

A fold whose ``fold.json`` exists is finished (it is written last, atomically), which is
how re-running with the same ``--out`` resumes.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any, cast

from tactile_studio.errors import IncompleteError, UserError
from tactile_studio.file_claims import replace_whole
from tactile_studio.learn.experiments.config import upgraded
from tactile_studio.learn.experiments.run_shapes import config_problem, fold_problem
from tactile_studio.learn.learners.fold_predictions import FoldRecord
from tactile_studio.output_faults import WriteFault, said_on_fault
from tactile_studio.storage.exchange.input_files import file_sha256

CONFIG, METRICS, WEIGHTS, FOLD = "config.json", "metrics.json", "model.safetensors", "fold.json"
MODEL_FILES = (WEIGHTS, "model.onnx")  # torch weights, or a baseline's ONNX file


def model_file(fold_dir: str | os.PathLike) -> Path:
    """The fold's saved model: ``model.safetensors`` or ``model.onnx``, whichever exists
    (the torch name when neither does, so the error names the usual file)."""
    d = Path(fold_dir)
    for name in MODEL_FILES:
        if (d / name).is_file():
            return d / name
    return d / WEIGHTS


def differences(before: dict[str, Any], now: dict[str, Any]) -> str:
    """"adapt: 'none' there, 'person' now; ..." for the keys of ``now`` whose value
    differs from ``before``'s ("" if none): what a folder refusing a run says."""
    return "; ".join(f"{k}: {before.get(k)!r} there, {v!r} now"
                     for k, v in now.items() if before.get(k) != v)


def clean_json(value: Any) -> Any:
    """NaN/inf -> None and numpy scalars -> Python, recursively (strict JSON)."""
    if isinstance(value, dict):
        return {str(k): clean_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean_json(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        try:
            value = value.item()
        except (ValueError, TypeError):
            value = value.tolist()
            return clean_json(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@contextmanager
def naming(path: str | os.PathLike) -> Iterator[None]:
    """Writing ``path``: an OS fault that names no file (a write or close failing part
    way, as on a full disk, in PIL, safetensors or our own ``write_text``) is raised
    again as an ``OSError`` naming ``path``, so it reads as one line like any other."""
    try:
        yield
    except OSError as exc:
        if exc.filename is not None or exc.errno is None:
            raise
        raise OSError(exc.errno, exc.strerror or os.strerror(exc.errno),
                      os.fspath(path)) from exc
    except Exception as exc:
        # safetensors' writer reports the OS's error in its message only
        match = re.search(r"\(os error (\d+)\)", str(exc))
        if type(exc).__name__ != "SafetensorError" or match is None:
            raise
        code = int(match[1])
        raise OSError(code, os.strerror(code), os.fspath(path)) from exc


def write_json(path: Path, data: Any) -> None:
    """Whole or not at all: written to a temporary name of this process's own, then
    renamed over ``path`` (a failed write leaves no temporary behind)."""
    text = json.dumps(clean_json(data), indent=1, allow_nan=False)
    replace_whole(path, lambda tmp: tmp.write_text(text))


def read_json(path: Path) -> Any:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise UserError(f"{path}: missing (not a finished run folder?)") from None
    except ValueError:
        raise UserError(f"{path}: not valid JSON (damaged run folder)") from None


class RunFolder:
    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    @property
    def folds_dir(self) -> Path:
        return self.path / "folds"

    def kept_on_fault(self) -> AbstractContextManager[None]:
        """Writing the run: a place that cannot be written (full, read-only...) ends in
        one line naming the file, and says which finished folds are kept to resume from
        (exit 3 when there are some: the run ended short; else 1)."""
        def error(line: str) -> UserError:
            kept = len(list(self.folds_dir.glob(f"*/{FOLD}")))
            if not kept:
                return WriteFault(line)
            return IncompleteError(f"{line}; the {kept} finished fold(s) are kept: train "
                                   "again with the same --out to resume")
        return said_on_fault(error)

    def start(self, config: dict[str, Any], resolved: dict[str, Any],
              compare_keys: tuple[str, ...], defaults: dict[str, Any] | None = None) -> bool:
        """Create the folder and config.json, or check an existing one matches (resume).

        Returns True when resuming an earlier run with the same settings and data. A key
        missing from an older run's config counts as its value in ``defaults`` (a setting
        added since, which that run ran without).
        """
        cfg_path = self.path / CONFIG
        if self.path.exists() and not self.path.is_dir():
            raise UserError(f"{self.path}: exists and is not a folder")
        if cfg_path.exists():
            old = read_json(cfg_path)
            before = {**clean_json(defaults or {}), **upgraded(old.get("config", {}))}
            diff = differences(before, {k: clean_json(config.get(k)) for k in compare_keys})
            if diff:
                raise UserError(f"{self.path} holds a different run (differs in {diff}); "
                                "choose another --out")
            if old.get("resolved", {}).get("dataset", {}).get("fingerprint") != \
                    resolved.get("dataset", {}).get("fingerprint"):
                raise UserError(f"{self.path}: the data changed since this run started; "
                                "choose another --out")
            return True
        if self.path.is_dir() and any(self.path.iterdir()):
            raise UserError(f"{self.path}: folder is not empty and holds no run; "
                            "choose another --out")
        self.folds_dir.mkdir(parents=True, exist_ok=True)
        write_json(cfg_path, {"config": config, "resolved": resolved})
        return False

    def fold_dir(self, round_: int, name: str) -> Path:
        safe = re.sub(r"[^A-Za-z0-9_.-]", "_", name)  # participant ids become folder names
        return self.folds_dir / f"r{round_}-{safe}"

    def load_fold(self, round_: int, name: str) -> FoldRecord | None:
        """The finished fold's record to resume from; None when it is to be trained: not
        finished, or damaged (its model file gone or not the one trained for it, its
        fold.json unreadable), as every reader of the folder would refuse it."""
        rec, why = _fold_record(self.fold_dir(round_, name))
        return None if why else rec

    def save_fold(self, record: FoldRecord, fitted: Any) -> None:
        d = self.fold_dir(record["round"], record["name"])
        d.mkdir(parents=True, exist_ok=True)
        with naming(d / fitted.file_name):
            fitted.save(d / fitted.file_name)
        # what was saved, so a model file copied in from another fold is told apart
        record["model_sha256"] = {f.name: file_sha256(f) for f in sorted(d.iterdir())
                                  if f.is_file() and f.name != FOLD}
        write_json(d / FOLD, record)

    def write_results(self, metrics: dict[str, Any], records: list[FoldRecord],
                      title: str) -> None:
        from tactile_studio.learn.evaluation import plots

        write_json(self.path / METRICS, metrics)
        write_confusion_csv(self.path / "confusion_matrix.csv", metrics["labels"],
                            metrics["confusion_matrix"])
        windows, trials = metrics.get("windows"), metrics.get("n_trials")
        unit = "windows" if windows is not None and windows != trials else "trials"
        with naming(self.path / "confusion_matrix.png"):
            plots.confusion_png(self.path / "confusion_matrix.png", metrics["labels"],
                                metrics["confusion_counts"], title, unit)
        if "trial_confusion_matrix" in metrics:
            write_confusion_csv(self.path / "trial_confusion_matrix.csv", metrics["labels"],
                                metrics["trial_confusion_matrix"])
            with naming(self.path / "trial_confusion_matrix.png"):
                plots.confusion_png(self.path / "trial_confusion_matrix.png",
                                    metrics["labels"], metrics["trial_confusion_counts"],
                                    title + " · per trial", "trials")
        if any(r.get("history") for r in records):
            with naming(self.path / "training_curves.png"):
                plots.curves_png(self.path / "training_curves.png", records, title)


def write_confusion_csv(path: Path, labels: list[str], matrix: list[list[float]]) -> None:
    with naming(path), open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["true \\ predicted", *labels])
        for name, row in zip(labels, matrix):
            w.writerow([name, *(f"{v:.4f}" for v in row)])


FOLD_KEYS = ("round", "fold", "name", "test")  # what every reader of fold.json relies on


def _fold_record(d: Path, n_classes: int | None = None) -> tuple[FoldRecord | None, str]:
    """(record, "") of the finished fold in ``d``; (None, "") when it is unfinished (no
    fold.json yet: training resumes it); (None, why) when it is damaged (``n_classes``:
    the run's, which its recorded predictions must fit)."""
    if not (d / FOLD).is_file():
        return None, ""
    if not model_file(d).is_file():
        return None, (f"{d}: fold {d.name} is finished but its model file is missing "
                      f"({' or '.join(MODEL_FILES)}); train again with the same --out to redo it")
    try:
        rec = read_json(d / FOLD)
    except UserError as exc:
        return None, f"fold {d.name}: {exc}"
    if not isinstance(rec, dict) or any(k not in rec for k in FOLD_KEYS):
        return None, f"{d / FOLD}: fold {d.name} is damaged (not a fold record of this version)"
    why = fold_problem(d / FOLD, rec, n_classes)
    if why:  # before any of its names is used: model_sha256 names files in the fold
        return None, f"{why} (fold {d.name} is damaged)"
    saved = rec.get("model_sha256")
    if isinstance(saved, dict):  # runs written before fingerprints have none to check
        for name, digest in saved.items():
            f = d / str(name)
            if not f.is_file():
                return None, (f"{f}: fold {d.name} is finished but its model file is "
                              "missing; train again with the same --out to redo it")
            if _model_digest(f) != digest:
                return None, (f"{f}: fold {d.name}'s model file is not the one trained "
                              "for it (replaced or copied from another fold or run); train "
                              "again with the same --out to redo it")
    return cast(FoldRecord, rec), ""  # its shape checked by fold_problem above


_DIGESTS: dict[tuple[str, int, int], str] = {}


def _model_digest(path: Path) -> str:
    """A model file's SHA-256, read once per version of the file: the workspace checks
    every run it lists at each rescan, and a paper-size network's folds hold ~20 MB each."""
    st = path.stat()
    key = (str(path.resolve()), st.st_ctime_ns, st.st_size)  # ctime: any write changes it
    if key not in _DIGESTS:
        _DIGESTS[key] = file_sha256(path)
    return _DIGESTS[key]


def _metrics_problem(run: Path, finished: set[tuple[int, str]]) -> str:
    """Why ``run``'s metrics.json cannot be trusted ("" when absent or sound): it must be
    the summary of folds that are all still there."""
    path = run / METRICS
    if not path.is_file():
        return ""  # a run stopped before its first fold finished, or still training
    try:
        m = read_json(path)
    except UserError as exc:
        return str(exc)
    if not isinstance(m, dict) or not isinstance(m.get("per_fold"), list) \
            or not isinstance(m.get("labels"), list):
        return f"{path}: damaged (valid JSON, but not a run's metrics: no per-fold list)"
    for f in m["per_fold"]:
        if not isinstance(f, dict) or not isinstance(f.get("round"), int) \
                or not isinstance(f.get("name"), str):
            return f"{path}: damaged (a per-fold entry of another shape)"
        safe = re.sub(r"[^A-Za-z0-9_.-]", "_", f["name"])
        if (f["round"], safe) not in finished:
            fold = f"r{f['round']}-{safe}"
            return (f"{run / 'folds' / fold}: fold {fold} scored in metrics.json is "
                    "missing or unfinished")
    return ""


def run_problems(path: str | os.PathLike) -> tuple[list[str], dict[str, Any] | None,
                                                   list[FoldRecord]]:
    """Everything wrong with a run folder, one line each naming the fold or file, with
    what could be read: (problems, config.json contents, finished fold records in order).
    The one integrity check every reader uses (evaluate, export-model, compare, live
    inference, the research workspace), so a fold that lost its model is never silently
    left out of a score."""
    run = Path(path)
    if not run.is_dir():
        return [f"{run}: no such run folder"], None, []
    problems: list[str] = []
    cfg: dict[str, Any] | None = None
    try:
        cfg = read_json(run / CONFIG)
        if not isinstance(cfg, dict) or not isinstance(cfg.get("config"), dict) \
                or not isinstance(cfg.get("resolved"), dict):
            problems.append(f"{run / CONFIG}: damaged (valid JSON, but not a run's config)")
            cfg = None
    except UserError as exc:
        problems.append(str(exc))
    if cfg is not None:  # a stranger's run folder: each field as we write it
        cfg["config"] = upgraded(cfg["config"])
        why = config_problem(run / CONFIG, cfg)
        if why:
            problems.append(f"{why} (damaged, or not written by this version)")
            cfg = None
    n_classes = cfg["resolved"]["data_info"]["n_classes"] if cfg is not None else None
    records, finished = [], set()
    for d in sorted((run / "folds").glob("r*-*")):
        rec, why = _fold_record(d, n_classes)
        if why:
            problems.append(why)
        elif rec is not None:
            rec["_dir"] = str(d)
            records.append(rec)
        if (d / FOLD).is_file():  # finished, sound or not (a damaged one is named above)
            round_, _, name = d.name[1:].partition("-")
            finished.add((int(round_) if round_.isdigit() else round_, name))
    try:
        records.sort(key=lambda r: (r["round"], r["fold"]))
    except TypeError:
        problems.append(f"{run}: fold.json files of another shape (round/fold not numbers)")
    why = _metrics_problem(run, finished)
    if why:
        problems.append(why)
    return problems, cfg, records


def check_run(path: str | os.PathLike) -> tuple[dict[str, Any], list[FoldRecord]]:
    """(config.json contents, finished fold records) of a sound run folder; a damaged one
    raises UserError with its first problem (and how many more there are)."""
    problems, cfg, records = run_problems(path)
    if problems:
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        raise UserError(problems[0] + more)
    if cfg is None or not records:
        raise UserError(f"{path}: the run has no finished folds")
    return cfg, records


def read_run(path: str | os.PathLike) -> tuple[dict[str, Any], list[FoldRecord]]:
    """(config.json contents, finished fold records in order) of a run folder; a missing
    or damaged fold model is an error naming the fold (:func:`check_run`)."""
    return check_run(path)
