"""``run_experiment``: dataset -> folds -> training -> metrics -> run folder, as one job.

It is the single entry point the CLI and (later) the GUI call: it takes a
:class:`ExperimentConfig`, a progress callback ``(fraction, message)``, a
:class:`~tactile_studio.jobs.CancelToken` and an optional ``listener`` that receives
the typed job events :class:`~tactile_studio.learn.experiments.job_events.Epoch` /
:class:`~tactile_studio.learn.experiments.job_events.Fold` (per-epoch curves, finished
folds' accuracy): the same objects the GUI's training process sends on its queue. Cancelling
keeps finished folds on disk (and writes the
metrics of those) before ``Cancelled`` propagates; running again with the same ``out``
resumes with the unfinished folds.

Seeds: round ``r`` uses seed ``config.seed + r`` for its splits, weight initialisation
and batch order, so rounds differ and every round is reproducible.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio import __version__
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.file_claims import claim_folder
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.data.dataset import TrialDataset, build_dataset
from tactile_studio.learn.data.splits import make_folds, with_shots
from tactile_studio.learn.data.windowing import cut, window_spec
from tactile_studio.learn.evaluation.summary import (
    fold_metrics,
    headline,
    summarise,
    trials_were_cut,
)
from tactile_studio.learn.experiments.config import (  # noqa: F401 (its home, re-exported)
    NETWORK_SHOTS_BY,
    RESULT_KEYS,
    SHOTS_BY,
    ExperimentConfig,
)
from tactile_studio.learn.experiments.fold_plan import FoldPlan
from tactile_studio.learn.experiments.job_events import Epoch, Fold
from tactile_studio.learn.experiments.runfolder import RunFolder
from tactile_studio.learn.learners.baselines import BASELINES
from tactile_studio.learn.learners.contract import Learner
from tactile_studio.learn.learners.families import DataInfo, make_learner
from tactile_studio.learn.learners.fine_tune import fine_tune_head
from tactile_studio.learn.learners.fold_predictions import FoldPredictions, FoldRecord
from tactile_studio.learn.learners.fused import (
    display_name,
    person_columns,
    rf_weight,
    standardises_person_features,
)
from tactile_studio.learn.learners.generalise import (
    ADAPT_PHRASE,
    adapt_groups,
    augmenter,
    balanced_index,
    group_moments,
    participant_normalised,
    participant_val,
    pooled_reference,
)


def result_defaults() -> dict[str, Any]:
    """The result-changing settings' defaults: what a run folder or sweep written before
    a setting existed ran with (so it still resumes)."""
    out: dict[str, Any] = {}
    for f in fields(ExperimentConfig):
        if f.name in RESULT_KEYS and f.default is not MISSING:
            out[f.name] = f.default
        elif f.name in RESULT_KEYS and f.default_factory is not MISSING:
            out[f.name] = f.default_factory()
    out["shots_by"] = "join"  # a run from before --shots-by joined its shots
    return out


@dataclass
class RunResult:
    metrics: dict[str, Any]
    config: ExperimentConfig
    out: Path | None
    folds: list[FoldRecord]
    complete: bool
    dataset: dict[str, Any] = field(default_factory=dict)  # TrialDataset.summary()


Listener = Callable[[Any], None]


def _versions() -> dict[str, str]:
    import sklearn
    import torch

    return {"tactile_studio": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "torch": torch.__version__, "sklearn": sklearn.__version__}


def adapt_people(config: ExperimentConfig, ds: TrialDataset, owner: np.ndarray
                 ) -> np.ndarray | None:
    """Each sample's adaptation group (its participant, or participant and condition)
    when the run adapts to each test person, else None."""
    groups = adapt_groups(config.adapt, ds)
    return None if groups is None else groups[owner]


def _predictions(fitted, learner, x: np.ndarray, owner: np.ndarray, idx: np.ndarray,
                 labels: np.ndarray, stats, people: np.ndarray | None = None
                 ) -> dict[str, list[Any]]:
    """The test samples' probabilities; with ``people``, a model that can adapt
    (``fitted.adapted``) is adapted to each person's samples before predicting them."""
    mask = np.isin(owner, idx)
    xt = learner.apply_norm(x[mask], stats)
    if people is None or not hasattr(fitted, "adapted"):
        probs = fitted.predict_proba(xt)
    else:
        who = people[mask]
        probs = np.zeros((len(xt), 0), dtype=np.float32)
        for p in np.unique(who):
            rows = who == p
            part = fitted.adapted(xt[rows]).predict_proba(xt[rows])
            if probs.shape[1] == 0:
                probs = np.zeros((len(xt), part.shape[1]), dtype=np.float32)
            probs[rows] = part
    return FoldPredictions.of_samples(owner[mask], labels, probs).to_dict()


def _train_fold(plan: FoldPlan, info: DataInfo, cancel: CancelToken,
                on_epoch: Callable[[dict[str, Any]], None]) -> tuple[FoldRecord, Any]:
    t0 = time.perf_counter()
    learner, ds, x, owner, fold, seed = (plan.learner, plan.ds, plan.x, plan.owner, plan.fold,
                                         plan.seed)
    extra, balance, people, moments = plan.extra, plan.balance, plan.people, plan.moments
    tr, va = np.isin(owner, fold.train), np.isin(owner, fold.val)
    y = ds.labels
    x_tr, y_tr = x[tr], y[owner[tr]]
    if extra is not None:  # augmented copies of the training windows
        x_aug, o_aug = extra(fold.train, seed)
        x_tr, y_tr = np.concatenate([x_tr, x_aug]), np.concatenate([y_tr, y[o_aug]])
    if balance:
        keep = balanced_index(y_tr, np.random.default_rng([seed, 0xBA1]))
        x_tr, y_tr = x_tr[keep], y_tr[keep]
    stats = learner.norm_stats(x_tr)  # training part of this split only
    fitted, history, best = learner.fit(
        info, (learner.apply_norm(x_tr, stats), y_tr),
        (learner.apply_norm(x[va], stats), y[owner[va]]), seed, cancel, on_epoch, norm=stats)
    cancel.check()
    rec = _fold_record(plan, fitted, stats, history, best, t0)
    if moments is not None and people is not None:  # a forest's view as trained
        rec["as_trained"] = pooled_reference(moments, np.unique(people[tr])).tolist()
    return rec, fitted


def _fold_record(plan: FoldPlan, fitted: Any, stats: dict[str, Any],
                 history: list[dict[str, Any]], best: Any, t0: float) -> FoldRecord:
    """A finished fold as runfolder saves it: its trials, normalisation, training curve
    and the test (and held-out) predictions of ``fitted``."""
    learner, ds, x, owner, fold, people = (plan.learner, plan.ds, plan.x, plan.owner,
                                           plan.fold, plan.people)
    round_, k, seed = plan.round_, plan.k, plan.seed
    y = ds.labels
    uid = np.array(ds.uids)
    rec: FoldRecord = {
        "round": round_, "fold": k, "name": fold.name, "seed": seed,
        "test_participants": fold.test_participants,
        "train": uid[fold.train].tolist(), "val": uid[fold.val].tolist(),
        "test": uid[fold.test].tolist(), "heldout": uid[fold.heldout].tolist(),
        "norm": stats, "history": history, "best_epoch": best,
        "predictions": _predictions(fitted, learner, x, owner, fold.test, y, stats, people),
        "seconds": time.perf_counter() - t0,
    }
    if fold.shots is not None:
        rec["shots"] = fold.shots
    if len(fold.heldout):
        rec["heldout_predictions"] = _predictions(fitted, learner, x, owner, fold.heldout, y,
                                                  stats, people)
    return rec


def shot_trials(fold, participants: np.ndarray) -> np.ndarray:
    """A shot fold's shot performances: its training trials of its test people (under
    lopo and group-kfold no other trial of theirs is trained on)."""
    return fold.train[np.isin(participants[fold.train], fold.test_participants)]


def _without_shots(fold, participants: np.ndarray):
    """The K = 0 fold of a shot fold: its training without the shot performances."""
    return replace(fold, name=f"{fold.name.rsplit(' k', 1)[0]} k0", shots=0,
                   train=np.setdiff1d(fold.train, shot_trials(fold, participants)))


def _fine_tune_fold(plan: FoldPlan, base: tuple[Any, dict[str, Any]], cancel: CancelToken
                    ) -> tuple[FoldRecord, Any]:
    """``--shots-by fine-tune``: the fold's K = 0 model (``base``: fitted, its
    normalisation) with its output layers fine-tuned on the windows of the fold's shot
    performances, as live calibration does (learners/fine_tune.py); tested on the same
    trials as K = 0. No training curve (history empty)."""
    t0 = time.perf_counter()
    learner, ds, x, owner, fold, people = (plan.learner, plan.ds, plan.x, plan.owner,
                                           plan.fold, plan.people)
    seed = plan.seed
    fitted0, stats = base
    sel = np.isin(owner, shot_trials(fold, ds.participants))
    test = np.isin(owner, fold.test)
    # adapted runs test the held-out person's windows with the batch norm re-estimated on
    # them (_predictions): the output layers are fine-tuned on those features too
    adapt_to = (learner.apply_norm(x[test], stats)
                if people is not None and len(np.unique(people[test])) == 1 else None)
    fitted = fine_tune_head(fitted0, learner.apply_norm(x[sel], stats),
                            ds.labels[owner[sel]], ds.n_classes, seed, cancel=cancel,
                            adapt_to=adapt_to)
    cancel.check()
    rec = _fold_record(plan, fitted, stats, [], None, t0)
    rec["fine_tuned_windows"] = int(sel.sum())
    return rec, fitted


def run_header(config: ExperimentConfig, channels: str | None, windowed: bool
               ) -> dict[str, Any]:
    """What metrics.json (train, sweep) and rescore.json (evaluate) say about the run."""
    header = {"model": config.model, "evaluation": config.evaluation, "channels": channels,
              "grid": config.grid, "preset": config.preset, "windowed": windowed,
              "aggregate": config.aggregate}
    weight = rf_weight(config.overrides)
    if weight > 0:  # fused with rf (learn/learners/fused.py)
        header["rf_weight"] = weight
    if config.adapt != "none":
        header["adapt"] = config.adapt
    if config.shots and config.shots_by != "join":
        header["shots_by"] = config.shots_by
    return header


def run_title(config: ExperimentConfig, channels: str | None) -> str:
    """The run's title on its figures: model (fused with rf if so), preset, evaluation."""
    return (f"{display_name(config.model, config.overrides)} ({config.preset}) · "
            f"{config.evaluation} · {channels}"
            + (f" · {ADAPT_PHRASE[config.adapt]}" if config.adapt != "none" else ""))


def prepare_inputs(learner, ds: TrialDataset, config: ExperimentConfig):
    """(dataset as trained on, samples X, owner trial per sample, number of windows,
    window spec, augmenter or None, moments): the model inputs ``config`` asks for.
    ``moments``: each person's feature moments before rf/knn (or a fused model's forest)
    standardise their features per person (``--adapt``; ``group_moments``), else None."""
    if config.participant_norm:
        ds = participant_normalised(ds)
    spec = window_spec(config.window_s, config.window_overlap, ds.trial_s)
    pieces, piece_owner = cut(ds, spec)
    x, sample_piece = learner.samples(pieces)
    groups, moments = adapt_groups(config.adapt, ds), None
    if groups is not None:  # features standardised by each person's own statistics
        if standardises_person_features(learner):  # a forest's view as trained: pooled
            moments = group_moments(person_columns(learner, x), groups[piece_owner[sample_piece]])
        x = learner.adapt_inputs(x, groups[piece_owner[sample_piece]])
    extra = augmenter(learner, pieces, piece_owner, config.augment, config.augment_copies)
    return ds, x, piece_owner[sample_piece], len(pieces), spec, extra, moments


def folds_for(config: ExperimentConfig, ds: TrialDataset, round_: int) -> list:
    """Round ``round_``'s folds (seed ``config.seed + round_``), validation by
    participant when ``config.val_by`` asks for it."""
    seed = config.seed + round_
    folds = make_folds(config.evaluation, ds.labels, ds.participants, seed, config.folds,
                       config.heldout_fraction, config.val_fraction, config.split)
    if config.val_by == "participant":
        folds = [participant_val(f, ds.participants, config.val_fraction, seed) for f in folds]
    if config.shots:
        folds = with_shots(folds, ds.labels, tuple(sorted(config.shots)), seed)
    return folds


def run_experiment(config: ExperimentConfig, out: str | os.PathLike | None = None,
                   progress: ProgressFn = no_progress, cancel: CancelToken | None = None,
                   listener: Listener | None = None, model_spec: Any = None,
                   dataset: TrialDataset | None = None) -> RunResult:
    """Train and evaluate ``config.model`` under ``config.evaluation``; see module doc.

    ``dataset`` skips building (used as it is when ``config.channels`` is None or its
    channel set; otherwise it must hold every channel, e.g. ``build_dataset(...)``'s
    default for shear data);
    ``model_spec`` supplies a ModelSpec not in the registry.
    """
    cancel = cancel or CancelToken()
    listener = listener or (lambda event: None)
    config = config.resolved()
    config.validate()
    # a run folder that cannot be written part way: one line, the finished folds kept
    faults = RunFolder(out).kept_on_fault() if out is not None else nullcontext()
    with faults:
        # one writer per run folder: claimed before any data is read, for the whole run
        held = claim_folder(out, "run folder") if out is not None else nullcontext()
        with held, _torch_threads(config.threads, config.model not in BASELINES):
            return _run(config, out, progress, cancel, listener, model_spec, dataset)


# CPU threads of one training process unless asked (``--threads``): one. Measured on the
# 2-core machine (benchmarks/bench_train_threads.py, FINDINGS section 7): torch's default
# (two OpenMP threads) on a loaded machine spin-waits at every parallel region's barrier
# for a sibling the scheduler has parked, 22x the CPU and ~12x the wall time per step of
# one thread; a cnn1d fold on real data took 7-9 min instead of under one.
TRAIN_THREADS = 1


@contextmanager
def _torch_threads(n: int | None, torch_too: bool = True) -> Iterator[None]:
    """Use ``n`` CPU threads (None: :data:`TRAIN_THREADS`) for the duration: torch's
    intra-op threads (``torch_too``: not imported for rf/knn) and the OpenMP / BLAS
    pools of numpy and scikit-learn (threadpoolctl; HistGradientBoosting's OpenMP has the
    same spin-wait trap). Process-wide settings, restored afterwards."""
    from threadpoolctl import threadpool_limits

    n = n or TRAIN_THREADS
    torch = None
    if torch_too:
        import torch
    previous = torch.get_num_threads() if torch is not None else 0
    if torch is not None:
        torch.set_num_threads(n)
    try:
        with threadpool_limits(limits=n):
            yield
    finally:
        if torch is not None:
            torch.set_num_threads(previous)


def _run_dataset(config: ExperimentConfig, dataset: TrialDataset | None,
                 progress: ProgressFn, cancel: CancelToken) -> TrialDataset:
    """The run's trials: ``dataset`` (its channels selected) or built from the config's
    data; at least two gestures."""
    if dataset is None:
        ds = build_dataset(config.data, config.grid, config.channels, config.cache_dir,
                           config.use_cache, lambda f, m: progress(0.05 * f, m), cancel,
                           config.exclude_flagged)
    else:
        ds = dataset if config.channels in (None, dataset.channels) else \
            dataset.select(config.channels)
    if ds.n_classes < 2:
        raise UserError(f"the data has one gesture only ({ds.label_names[0]}); "
                        "classification needs at least 2")
    return ds


def _resolved(learner: Learner, info: DataInfo, ds: TrialDataset) -> dict[str, object]:
    """What the config resolved to on this data and machine (config.json's "resolved")."""
    return {"model": learner.describe(), "data_info": info.to_dict(),
            "dataset": ds.summary(), "versions": _versions(),
            # the CPU threads the folds train with (what a run's times depend on)
            "threads": {"torch": sys.modules["torch"].get_num_threads()
                        if "torch" in sys.modules else None,
                        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY", "")},
            "created": time.strftime("%Y-%m-%dT%H:%M:%S")}


def _start_folder(out: str | os.PathLike | None, config: ExperimentConfig,
                  resolved: dict[str, object], ds: TrialDataset) -> RunFolder | None:
    """The run folder started (or resumed) with its config and trial table; None when the
    run keeps nothing."""
    if out is None:
        return None
    folder = RunFolder(out)
    folder.start(config.to_dict(), resolved, RESULT_KEYS, result_defaults())
    from tactile_studio.learn.experiments.trialinfo import write_trial_table

    write_trial_table(folder.path, ds.uids, ds.participants.tolist(), config.data)
    return folder


def _fold_event(rec: FoldRecord, ds: TrialDataset, learner: Learner,
                config: ExperimentConfig, r: int, k: int, n_folds: int, name: str,
                resumed: bool) -> Fold:
    """The listener's event for a finished (or resumed) fold: its accuracies."""
    fm = fold_metrics(rec, ds.label_names, learner.windowed, aggregate=config.aggregate)
    return Fold(round=r, fold=k, n_folds=n_folds, fold_name=name,
                accuracy=float(fm["accuracy"]), trial_accuracy=float(fm["trial_accuracy"]),
                cut=trials_were_cut(fm), resumed=resumed)


def _cancelled(records: list[FoldRecord], folder: RunFolder | None, ds: TrialDataset,
               learner: Learner, header: dict[str, object], title: str,
               total_units: int) -> Cancelled:
    """A cancelled run: the folds finished so far written as partial results, and the
    one line saying how many and where they are kept."""
    if records and folder is not None:
        metrics = summarise(records, ds.label_names, learner.windowed, header, False)
        folder.write_results(metrics, records, title + " (partial)")
    kept = f", kept in {folder.path}; the same --out resumes" if folder is not None else ""
    return Cancelled(f"training cancelled: {len(records)} of {total_units} folds "
                     f"finished{kept}")


def _run(config: ExperimentConfig, out, progress: ProgressFn, cancel: CancelToken,
         listener: Listener, model_spec: Any, dataset: TrialDataset | None) -> RunResult:
    learner = make_learner(config.model, config.preset, config.overrides, config.epochs,
                           config.device, model_spec)
    ds = _run_dataset(config, dataset, progress, cancel)
    info = DataInfo.of(ds)
    learner.check(info)
    first_folds = folds_for(config, ds, 0)  # fails early on too few participants
    header = run_header(config, ds.channels, learner.windowed)
    if config.shots:  # the trials a plain run would test: said beside the shots' test set
        header["data_trials"] = len(ds)
    resolved = _resolved(learner, info, ds)
    folder = _start_folder(out, config, resolved, ds)
    progress(0.05, f"making model inputs: {len(ds)} trials, {learner.facts.view} view")
    ds, x, owner, n_pieces, spec, extra, moments = prepare_inputs(learner, ds, config)
    header.update(window_s=spec.seconds, windows=n_pieces)
    total_units = config.rounds * len(first_folds)
    records: list[FoldRecord] = []
    done = 0
    title = run_title(config, ds.channels)
    fine = config.shots_by == "fine-tune" and bool(config.shots)
    # fine-tune: the K = 0 model (fitted, its normalisation) of the fold named base_name
    base_name, base = "", (None, {})
    try:
        for r in range(config.rounds):
            seed = config.seed + r
            folds = first_folds if r == 0 else folds_for(config, ds, r)
            for k, fold in enumerate(folds):
                cancel.check()
                where = f"round {r + 1}/{config.rounds} fold {k + 1}/{len(folds)} ({fold.name})"
                rec = folder.load_fold(r, fold.name) if folder is not None else None
                resumed = rec is not None
                if rec is None:
                    history: list[dict[str, Any]] = []
                    max_ep = learner.max_epochs

                    def on_epoch(e: dict[str, Any], r=r, k=k, fold=fold, where=where,
                                 history=history, max_ep=max_ep) -> None:
                        history.append(e)
                        frac = 0.05 + 0.92 * (done + min(e["epoch"] / max_ep, 1.0)) / total_units
                        acc = e["val_acc"] if e["val_acc"] == e["val_acc"] else e["train_acc"]
                        progress(frac, f"{where} epoch {e['epoch']} acc {acc:.2f}")
                        listener(Epoch.of(r, k, len(folds), fold.name, e))

                    people = adapt_people(config, ds, owner)
                    plan = FoldPlan(learner, ds, x, owner, fold, r, k, seed, people, extra,
                                    config.balance, moments)
                    zero_fold = _without_shots(fold, ds.participants)
                    name = f"{r} {zero_fold.name}"
                    if fine and fold.shots and name != base_name:  # K = 0 not trained here
                        progress(0.05 + 0.92 * done / total_units, f"{where} training K = 0")
                        zero, fitted0 = _train_fold(replace(plan, fold=zero_fold), info,
                                                    cancel, on_epoch)
                        base_name, base = name, (fitted0, zero["norm"])
                    if fine and fold.shots:
                        progress(0.05 + 0.92 * done / total_units, f"{where} fine-tuning")
                        rec, fitted = _fine_tune_fold(plan, base, cancel)
                    else:
                        progress(0.05 + 0.92 * done / total_units, f"{where} training")
                        rec, fitted = _train_fold(plan, info, cancel, on_epoch)
                        if fine:  # K = 0: the model each K of this fold fine-tunes
                            base_name, base = name, (fitted, rec["norm"])
                    if folder is not None:
                        folder.save_fold(rec, fitted)
                records.append(rec)
                done += 1
                progress(0.05 + 0.92 * done / total_units, f"{where} done")
                listener(_fold_event(rec, ds, learner, config, r, k, len(folds), fold.name,
                                     resumed))
    except Cancelled:
        raise _cancelled(records, folder, ds, learner, header, title, total_units) from None
    progress(0.98, "writing results")
    metrics = summarise(records, ds.label_names, learner.windowed, header, True)
    if folder is not None:
        folder.write_results(metrics, records, title)
    progress(1.0, headline(metrics))
    return RunResult(metrics, config, Path(out) if out is not None else None, records, True,
                     resolved["dataset"])
