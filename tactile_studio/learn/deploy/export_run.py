"""Exporting a run's fold models (``tactile-studio export-model``) and measuring the cost.

rf / knn folds are ONNX files already (skl2onnx at training time): ``onnx`` copies them to
``RUN/export/<fold>.onnx`` with the same metadata and checks them against the probabilities
recorded at training; they have no int8 form. A network fused with rf (``rf_weight``,
learn/learners/fused.py) exports as ``onnx`` only: the network as below, its forest copied beside it
to ``RUN/export/<fold>.rf.onnx``; both are scored with onnxruntime and fused with the run's
weight (the network's file names its forest and the weight in its metadata).

Every torch fold's best-epoch model is exported with the functions in
:mod:`tactile_studio.learn.deploy.export` and re-scored on that fold's test set:

* ``onnx`` — written to ``RUN/export/<fold>.onnx`` (labels, view and normalisation in
  its metadata); onnxruntime's logits are compared with torch's (max absolute
  difference; a difference above ``tolerance`` is an error);
* ``int8`` — the ONNX model statically quantised with onnxruntime, calibrated on up to
  256 of the fold's training samples, written to ``RUN/export/<fold>.int8.onnx`` (same
  metadata plus a ``quantization`` entry), loaded back and scored with onnxruntime; the
  sizes of the float and int8 ONNX files are reported.

The test sets are cut into the model's windows exactly as training did
(:func:`~tactile_studio.learn.experiments.experiment.prepare_inputs`: windows of long trials,
per-participant normalisation when the run used it), so every fold is scored on the same
samples its metrics came from. The report gives, per fold and pooled, the per-window
``accuracy_*`` and the per-trial ``trial_accuracy_*`` (windows aggregated by the run's
``aggregate``, mean probability by default, or ``vote``) of the reference (the float
torch model; for rf / knn the probabilities recorded at training) and of the exported
file, pooled the way metrics.json is (medians over rounds), so the reference figures equal
the run's metrics.json; and how many window predictions changed. It is also written to
``RUN/export/<format>.json``.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.choices import EXPORT_FORMATS
from tactile_studio.learn.data.dataset import TrialDataset
from tactile_studio.learn.data.windowing import AGGREGATES
from tactile_studio.learn.evaluation.summary import summarise
from tactile_studio.learn.experiments.experiment import ExperimentConfig, prepare_inputs
from tactile_studio.learn.experiments.runfolder import model_file, write_json
from tactile_studio.learn.learners.contract import Learner
from tactile_studio.learn.learners.fold_predictions import FoldPredictions, FoldRecord
from tactile_studio.learn.learners.fused import (
    RF_FILE,
    display_name,
    fuse,
    standardises_person_features,
)
from tactile_studio.learn.learners.generalise import ADAPT_PHRASE
from tactile_studio.learn.results.rescore import RunData, load_run_data

ONNX_TOLERANCE = 1e-3


def export_run(run: str | os.PathLike, fmt: str, data: list[str] | None = None,
               cache_dir: str | None = None, progress: ProgressFn = no_progress,
               cancel: CancelToken | None = None,
               tolerance: float = ONNX_TOLERANCE, threads: int = 0,
               aggregate: str | None = None) -> dict[str, Any]:
    """Export every fold model of ``run`` as ``fmt`` (onnx or int8) and score the files on
    the folds' test windows (see the module doc); ``threads`` are torch's and onnxruntime's
    CPU threads (0 = their defaults); ``aggregate`` (mean | vote) overrides the run's."""
    import torch

    from tactile_studio.learn.deploy import export

    _check_request(fmt, aggregate)
    if threads:
        torch.set_num_threads(threads)
    loaded = load_run_data(run, data, cache_dir, device="cpu",
                           progress=lambda f, m: progress(0.2 * f, m), cancel=cancel)
    config, resolved, records, ds, learner, info = loaded
    how = aggregate or config.aggregate
    fused_run = learner.kind == "fused"  # a network + rf (learn/learners/fused.py)
    _check_model(config.model, learner, fmt)
    if learner.kind == "baseline":
        return _export_baseline(run, loaded, progress, cancel, tolerance, how)
    quant_format = export.int8_format(config.model)
    ds, x, owner, index = _windows(learner, ds, config)
    out_dir = Path(run) / "export"
    folds, scored = [], []
    for k, rec, mask in _each_fold(records, index, owner, progress, cancel):
        xt = learner.apply_norm(x[mask], rec["norm"])
        example = learner.apply_norm(x[:1], rec["norm"])
        if fused_run:  # the network's views; the forest's trial features
            (xt, ft), example = learner.split(xt, info), learner.split(example, info)[0]
        example = torch.from_numpy(example)
        yt = ds.labels[owner[mask]]
        fitted = learner.load(model_file(rec["_dir"]), info)
        model = fitted.model.eval()
        with torch.no_grad():
            ref = model(torch.from_numpy(xt)).numpy() if len(xt) else np.zeros((0, info.n_classes))
        entry: dict[str, Any] = {"name": Path(rec["_dir"]).name, "n": int(len(yt))}
        meta = _metadata(config, ds, resolved["model"]["view"], rec["norm"])
        if fused_run:
            meta.update(rf_weight=str(learner.weight), rf_model=f"{entry['name']}.rf.onnx")
        if fmt == "onnx":
            path = out_dir / f"{entry['name']}.onnx"
            export.export_onnx(model, example, path, metadata=meta)
            got = export.load_onnx_predictor(path, threads)(xt) if len(xt) else ref
            diff = _onnx_diff(path, got, ref, tolerance)
            entry.update(path=str(path), max_abs_diff=diff)
        else:
            tr = np.array([index[u] for u in rec["train"] if u in index], dtype=np.int64)
            calib = _calibration(x[np.isin(owner, tr)], seed=k)
            path = out_dir / f"{entry['name']}.int8.onnx"
            with tempfile.TemporaryDirectory() as tmp:
                float_path = export.export_onnx(model, example, Path(tmp) / "float.onnx",
                                                metadata=meta)
                export.quantize_onnx_int8(float_path, path, learner.apply_norm(calib, rec["norm"]),
                                          quant_format=quant_format)
                float_size = float_path.stat().st_size
            predict = export.load_onnx_predictor(path, threads)
            got = predict(xt) if len(xt) else ref
            entry.update(path=str(path), size_bytes=path.stat().st_size,
                         float_size_bytes=float_size, calibration_samples=int(len(calib)))
        ref_p, got_p = _softmax(ref), _softmax(got)
        if fused_run:
            entry["rf_path"] = str(out_dir / meta["rf_model"])
            ref_p, got_p = _fuse_forest(fitted, rec, Path(entry["rf_path"]), meta, ft, ref_p,
                                        got_p, learner, info)
        scored.append(_scored(rec, owner[mask], yt, ref_p, got_p))
        folds.append(entry)
    report = _report(display_name(config.model, config.overrides), fmt, folds, scored,
                     ds.label_names, learner.windowed, how)
    report.update(_adapt_note(config, learner))
    if fmt == "int8":
        report.update(quant_format=quant_format, size_bytes=sum(f["size_bytes"] for f in folds),
                      float_size_bytes=sum(f["float_size_bytes"] for f in folds))
    return _written(out_dir, fmt, report, progress)


def _onnx_diff(path: Path, got: np.ndarray, ref: np.ndarray, tolerance: float) -> float:
    """The largest difference of the ONNX file's logits from torch's; one line refuses
    the file when it exceeds ``tolerance`` (relative to the logits' size)."""
    diff = float(np.abs(got - ref).max()) if len(got) else 0.0
    if diff > tolerance * max(1.0, float(np.abs(ref).max())):
        raise UserError(f"{path}: ONNX logits differ from torch by {diff:.3g} "
                        f"(tolerance {tolerance:g})")
    return diff


def _written(out_dir: Path, fmt: str, report: dict[str, object],
             progress: ProgressFn) -> dict[str, object]:
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / f"{fmt}.json", report)
    progress(1.0, "exported")
    return report


def _check_request(fmt: str, aggregate: str | None) -> None:
    if fmt not in EXPORT_FORMATS:
        raise UserError(f"unknown export format {fmt!r} "
                        f"(available: {', '.join(EXPORT_FORMATS)})")
    if aggregate is not None and aggregate not in AGGREGATES:
        raise UserError(f"unknown aggregate {aggregate!r} (available: {', '.join(AGGREGATES)})")


def _check_model(model: str, learner: Learner, fmt: str) -> None:
    """Refuse, in one line, a format the run's model does not export as."""
    if learner.kind == "fused" and fmt != "onnx":
        raise UserError(f"model '{model}' is fused with rf: it exports as onnx only "
                        "(the network's .onnx beside the forest's .rf.onnx)")
    if learner.kind == "baseline":
        if fmt != "onnx":
            raise UserError(f"model '{model}' is a scikit-learn baseline: it exports "
                            "as onnx only (int8 is for torch models)")
        return
    if "onnx" not in learner.facts.export:
        raise UserError(f"model '{model}' declares no ONNX export "
                        f"(it exports as: {', '.join(learner.facts.export) or 'nothing'})")
    if fmt == "int8" and not learner.facts.quantizable:
        from tactile_studio.learn.models import MODELS

        small = ", ".join(n for n, s in MODELS.items() if s.quantizable)
        raise UserError(f"model '{model}' has no int8 export (quantizable: {small})")


def _metadata(config: ExperimentConfig, ds: TrialDataset, view: object,
              norm: object) -> dict[str, str]:
    """What a fold's exported file carries: labels, model, view and normalisation."""
    return {"labels": json.dumps(ds.label_names), "model": config.model,
            "preset": config.preset, "channels": ds.channels,
            "view": json.dumps(view), "norm": json.dumps(norm)}


def _export_baseline(run: str | os.PathLike, loaded: RunData, progress: ProgressFn,
                     cancel: CancelToken | None, tolerance: float, how: str
                     ) -> dict[str, Any]:
    """rf / knn folds are ONNX files already: copy each to ``RUN/export/<fold>.onnx`` with
    the run's metadata, run it with onnxruntime on the fold's test trials and compare with
    the probabilities recorded when the fold was trained (the "torch" fields of the report
    hold that reference for these models)."""
    from tactile_studio.learn.learners.baselines import BaselineModel

    config, resolved, records, ds, learner, info = loaded
    ds, x, owner, index = _windows(learner, ds, config)
    out_dir = Path(run) / "export"
    folds, scored = [], []
    for _, rec, mask in _each_fold(records, index, owner, progress, cancel):
        yt = ds.labels[owner[mask]]
        source = model_file(rec["_dir"])
        learner.load(source, info)  # a clear error for a damaged or pre-ONNX fold model
        name = Path(rec["_dir"]).name
        path = out_dir / f"{name}.onnx"
        _copy_onnx(source, path, _metadata(config, ds, resolved["model"]["view"], {}))
        exported = BaselineModel.load(path, learner.name, learner.options, info.n_classes)
        got = exported.predict_proba(x[mask])
        ref = FoldPredictions.from_dict(rec["predictions"]).probs
        if len(ref) != len(got):
            raise UserError(f"fold {rec['name']}: the data gives {len(got)} test windows, "
                            f"the run recorded {len(ref)}")
        diff = float(np.abs(got - ref).max()) if len(got) else 0.0
        if diff > tolerance:
            raise UserError(f"{path}: ONNX probabilities differ from the run's by {diff:.3g} "
                            f"(tolerance {tolerance:g})")
        folds.append({"name": name, "n": int(len(yt)), "path": str(path), "max_abs_diff": diff})
        scored.append(_scored(rec, owner[mask], yt, ref, got))
    report = _report(config.model, "onnx", folds, scored, ds.label_names, learner.windowed, how)
    report.update(_adapt_note(config, learner))
    write_json(out_dir / "onnx.json", report)
    progress(1.0, "exported")
    return report


def _copy_onnx(source: Path, path: Path, metadata: dict[str, str]) -> None:
    """Copy an ONNX file, its own metadata updated with ``metadata``."""
    import onnx

    from tactile_studio.learn.deploy.export import _save_onnx

    proto = onnx.load_model(str(source))
    meta = {p.key: p.value for p in proto.metadata_props}
    meta.update(metadata)
    _save_onnx(proto, meta, path, "ONNX model")


def _fuse_forest(fitted, rec: FoldRecord, path: Path, meta: dict[str, str],  # noqa: ANN001
                 features: np.ndarray, ref: np.ndarray, got: np.ndarray, learner,  # noqa: ANN001
                 info) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """A fused fold: copy its forest beside the network's file and fuse both probability
    sets (reference: torch + the saved forest; export: the network's and the forest's
    exported files, as a consumer of the export would)."""
    from tactile_studio.learn.learners.baselines import BaselineModel

    shared = {k: v for k, v in meta.items() if k in ("labels", "preset", "channels", "rf_weight")}
    _copy_onnx(Path(rec["_dir"]) / RF_FILE, path, {**shared, "fused_with": meta["model"]})
    exported = BaselineModel.load(path, "rf", learner.forest.options, info.n_classes)
    return (fuse(ref, fitted.forest.predict_proba(features), learner.weight),
            fuse(got, exported.predict_proba(features), learner.weight))


def _windows(learner, ds, config):  # noqa: ANN001, ANN202
    """The run's samples as trained (windows of long trials), their owners, and each
    trial's row by uid."""
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    return ds, x, owner, {u: i for i, u in enumerate(ds.uids)}


def _each_fold(records: list[FoldRecord], index: dict[str, int], owner: np.ndarray,
               progress: ProgressFn, cancel: CancelToken | None,
               ) -> Iterator[tuple[int, FoldRecord, np.ndarray]]:
    """Each fold with the mask of its test windows, saying which fold it is at and
    stopping when cancelled (export's last 80%)."""
    for k, rec in enumerate(records):
        if cancel is not None:
            cancel.check()
        progress(0.2 + 0.8 * k / len(records), f"fold {rec['name']}")
        yield k, rec, _test_mask(rec, index, owner)


def _test_mask(rec: FoldRecord, index: dict[str, int], owner: np.ndarray) -> np.ndarray:
    """The samples (windows) of the fold's test trials."""
    missing = [u for u in rec["test"] if u not in index]
    if missing:
        raise UserError(f"test trial {missing[0]} of fold {rec['name']} is not in the data")
    return np.isin(owner, np.array([index[u] for u in rec["test"]], dtype=np.int64))


def _softmax(logits: np.ndarray) -> np.ndarray:
    z = np.asarray(logits, dtype=np.float64)
    if not len(z):
        return z
    e = np.exp(z - z.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


def _scored(rec: FoldRecord, owner: np.ndarray, y: np.ndarray, ref: np.ndarray,
            got: np.ndarray) -> tuple[FoldRecord, FoldRecord]:
    """Two fold records (reference, exported) in the run's layout, for ``summarise``."""
    def one(probs: np.ndarray) -> FoldRecord:
        p = FoldPredictions(owner, y, np.asarray(probs, dtype=np.float64))
        out = rec.copy()
        out.pop("heldout_predictions", None)
        out["predictions"] = p.to_dict()
        return out
    return one(ref), one(got)


def _adapt_note(config, learner) -> dict[str, str]:  # noqa: ANN001 - config, learner
    """What a file exported from a run adapted to each person (``--adapt person`` or
    ``person-condition``) lacks: the person's statistics, which only that person's own
    session can give."""
    if config.adapt == "none":
        return {}
    what = ("it carries the training people's batch-norm statistics, so the accuracies "
            "here are without adaptation" if not standardises_person_features(learner) else
            "it expects features standardised by each person's own mean and spread "
            "(learn/learners/generalise.py person_standardised), as scored here")
    return {"adapt": config.adapt,
            "adapt_note": f"the run {ADAPT_PHRASE[config.adapt]}; {what}"}


def _report(model: str, fmt: str, folds: list[dict[str, Any]],
            scored: list[tuple[FoldRecord, FoldRecord]], labels: list[str],
            windowed: bool, how: str) -> dict[str, Any]:
    """Per-fold and pooled window / trial accuracy of the reference and the export, pooled
    as metrics.json pools them (so the reference figures are the run's)."""
    header = {"aggregate": how}
    for entry, (ref, got) in zip(folds, scored):
        r = summarise([ref], labels, windowed, header, True)
        g = summarise([got], labels, windowed, header, True)
        before = FoldPredictions.from_dict(ref["predictions"]).y_pred
        after = FoldPredictions.from_dict(got["predictions"]).y_pred
        entry.update(n_trials=r["n_trials"], accuracy_torch=r["accuracy"],
                     accuracy_export=g["accuracy"], trial_accuracy_torch=r["trial_accuracy"],
                     trial_accuracy_export=g["trial_accuracy"],
                     changed_predictions=int(np.sum(np.asarray(before) != np.asarray(after))))
    r = summarise([s[0] for s in scored], labels, windowed, header, True)
    g = summarise([s[1] for s in scored], labels, windowed, header, True)
    report = {"model": model, "format": fmt, "aggregate": how, "folds": folds,
              "n": int(sum(f["n"] for f in folds)), "n_trials": r["n_trials"],
              "accuracy_torch": r["accuracy"], "accuracy_export": g["accuracy"],
              "trial_accuracy_torch": r["trial_accuracy"],
              "trial_accuracy_export": g["trial_accuracy"],
              "changed_predictions": int(sum(f["changed_predictions"] for f in folds))}
    report["accuracy_change"] = report["accuracy_export"] - report["accuracy_torch"]
    report["trial_accuracy_change"] = (report["trial_accuracy_export"]
                                       - report["trial_accuracy_torch"])
    return report


def _calibration(x_train: np.ndarray, seed: int) -> np.ndarray:
    """Up to CALIBRATION_SAMPLES training samples, drawn evenly at random (the samples
    are ordered by trial, so the first few hundred would cover only a few gestures)."""
    from tactile_studio.learn.deploy.export import CALIBRATION_SAMPLES

    if len(x_train) <= CALIBRATION_SAMPLES:
        return x_train
    pick = np.random.default_rng(seed).choice(len(x_train), CALIBRATION_SAMPLES, replace=False)
    return x_train[np.sort(pick)]
