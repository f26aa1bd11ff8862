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
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import MISSING, asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio import __version__
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.data.augment import parse_kinds
from tactile_studio.learn.data.dataset import GRIDS, TrialDataset, build_dataset
from tactile_studio.learn.data.splits import PROTOCOLS, make_folds, with_shots
from tactile_studio.learn.data.windowing import AGGREGATES, cut, window_spec
from tactile_studio.learn.evaluation.summary import (
    fold_metrics,
    headline,
    summarise,
    trials_were_cut,
)
from tactile_studio.learn.experiments.job_events import Epoch, Fold
from tactile_studio.learn.experiments.runfolder import RunFolder
from tactile_studio.learn.learners.baselines import BASELINES
from tactile_studio.learn.learners.families import DataInfo, make_learner
from tactile_studio.learn.learners.fine_tune import fine_tune_head
from tactile_studio.learn.learners.fused import (
    ADAPT_OPTION,
    display_name,
    forest_adapts,
    person_columns,
    rf_weight,
    standardises_person_features,
)
from tactile_studio.learn.learners.generalise import (
    ADAPT_AUTO,
    ADAPT_CHOICES,
    ADAPT_PHRASE,
    VAL_BY,
    Moments,
    adapt_groups,
    augmenter,
    balanced_index,
    group_moments,
    participant_normalised,
    participant_val,
    pooled_reference,
    resolve_adapt,
)

# Config fields that change results (a resumed run must match on these).
RESULT_KEYS = ("data", "model", "channels", "grid", "protocol", "rounds", "preset", "epochs",
               "overrides", "seed", "folds", "heldout_fraction", "val_fraction", "split",
               "window_s", "window_overlap", "aggregate", "augment", "augment_copies",
               "participant_norm", "balance", "val_by", "adapt", "shots", "shots_by")
SHOTS_BY = ("auto", "join", "fine-tune")  # how a held-out person's shots reach the model
# what ``auto`` means for a network (rf, knn and fused models always join): measured on
# the simulator, docs/learning/figures.md "Few-shot personalisation, measured"
NETWORK_SHOTS_BY = "fine-tune"


@dataclass
class ExperimentConfig:
    data: list[str]
    model: str
    channels: str | None = None          # normal | shear | both; None = all the data has
    grid: str = "physical"               # physical | virtual
    protocol: str = "lopo"               # all-inclusive | lopo | group-kfold
    rounds: int = 1
    preset: str = "full"                 # full | tiny
    epochs: int | None = None            # overrides the model's max_epochs
    overrides: dict[str, Any] = field(default_factory=dict)  # training + model options
    seed: int = 0
    folds: int = 10                      # k of group-kfold
    heldout_fraction: float = 0.1        # group-kfold held-out participants
    val_fraction: float = 0.15           # validation share of training participants' trials
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)  # all-inclusive train/val/test
    window_s: float | None = None        # long trials -> windows this long (None: protocol's)
    window_overlap: float = 0.5          # share of a window overlapping the next
    aggregate: str = "mean"              # trial prediction from windows: mean | vote
    augment: str = ""                    # flip,rotate,shift,warp,scale | all ("" none)
    augment_copies: int = 1              # augmented copies of every training window
    participant_norm: bool = False       # scale each participant to a typical person
    balance: bool = False                # repeat rarer classes' training samples
    val_by: str = "trial"                # validation: trials | whole training participants
    # none | person | person-condition: each test person's own statistics; auto: person
    # for a network under lopo / group-kfold (train's default), resolved before a run
    adapt: str = "none"
    # few-shot personalisation: each held-out fold once per K, with K labelled
    # performances per gesture of the test person in the training (() = off)
    shots: tuple[int, ...] = ()
    # join: the shots join the training (one training per K); fine-tune: the fold is
    # trained once without them and a copy's output layers fine-tuned per K (networks);
    # auto: NETWORK_SHOTS_BY for a network, join for rf / knn / fused (resolved())
    shots_by: str = "auto"
    device: str = "auto"
    threads: int | None = None           # torch CPU threads (None: torch's default)
    cache_dir: str | None = None
    use_cache: bool = True

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["data"] = [str(Path(p).resolve()) for p in self.data]
        d["split"] = list(self.split)
        d["shots"] = list(self.shots)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ExperimentConfig:
        known = {k: v for k, v in d.items() if k in cls.__dataclass_fields__}
        if "split" in known:
            known["split"] = tuple(known["split"])
        if "shots" in known:
            known["shots"] = tuple(int(k) for k in known["shots"] or ())
        return cls(**known)

    @property
    def forest(self) -> bool:
        """rf / knn, or a network fused with rf: features, not batch norm, adapt."""
        return self.model in BASELINES or rf_weight(self.overrides) > 0

    @property
    def can_adapt(self) -> bool:
        """False for a forest trained on augmented windows: they carry no person's
        statistics to standardise its features by. A network fused with rf can, when
        its forest stays as trained (``rf_adapt=0``): only the network adapts then."""
        if not (self.forest and self.augment):
            return True
        return self.model not in BASELINES and not forest_adapts(self.overrides)

    def resolved(self) -> ExperimentConfig:
        """This config with ``adapt="auto"`` (generalise.resolve_adapt) and
        ``shots_by="auto"`` made concrete for its model and protocol; what a run folder
        records and every fold reads."""
        overrides = self.overrides
        if (self.adapt == ADAPT_AUTO and self.protocol != "all-inclusive"
                and self.model not in BASELINES and self.forest
                and ADAPT_OPTION not in overrides):
            # auto adapts the network, and keeps the fused forest as rf alone is kept
            # (recorded, so the run reads the same when it is resumed or deployed)
            overrides = {**overrides, ADAPT_OPTION: 0}
        adapt = resolve_adapt(self.adapt, self.protocol,
                              replace(self, overrides=overrides).can_adapt,
                              network=self.model not in BASELINES)
        shots_by = self.shots_by
        if shots_by == "auto":  # join without shots: what a run before the setting did
            shots_by = NETWORK_SHOTS_BY if self.shots and not self.forest else "join"
        if (adapt, shots_by, overrides) == (self.adapt, self.shots_by, self.overrides):
            return self
        return replace(self, adapt=adapt, shots_by=shots_by, overrides=overrides)

    def validate(self) -> None:
        if self.protocol not in PROTOCOLS:
            raise UserError(f"unknown evaluation protocol {self.protocol!r} "
                            f"(available: {', '.join(PROTOCOLS)})")
        if self.grid not in GRIDS:
            raise UserError(f"unknown grid {self.grid!r} (available: {', '.join(GRIDS)})")
        if self.rounds < 1:
            raise UserError(f"--rounds must be at least 1, got {self.rounds}")
        if self.threads is not None and self.threads < 1:
            raise UserError(f"--threads must be at least 1, got {self.threads}")
        if self.epochs is not None and self.epochs < 1:
            raise UserError(f"--epochs must be at least 1, got {self.epochs}")
        if not 0 < self.val_fraction < 1 or not 0 < self.heldout_fraction < 1:
            raise UserError("validation and held-out fractions must be between 0 and 1")
        if self.aggregate not in AGGREGATES:
            raise UserError(f"unknown aggregate {self.aggregate!r} "
                            f"(available: {', '.join(AGGREGATES)})")
        if self.window_s is not None and self.window_s <= 0:
            raise UserError(f"--window must be positive, got {self.window_s}")
        if not 0 <= self.window_overlap < 1:
            raise UserError(f"window overlap must be in [0, 1), got {self.window_overlap}")
        parse_kinds(self.augment)
        if self.augment_copies < 0:
            raise UserError(f"augment_copies must be 0 or more, got {self.augment_copies}")
        if self.val_by not in VAL_BY:
            raise UserError(f"unknown validation split {self.val_by!r} "
                            f"(available: {', '.join(VAL_BY)})")
        if self.adapt not in ADAPT_CHOICES:
            raise UserError(f"unknown adaptation {self.adapt!r} "
                            f"(available: {', '.join(ADAPT_CHOICES)})")
        resolved = self.resolved()
        adapt = resolved.adapt
        if adapt != "none" and self.protocol == "all-inclusive":
            raise UserError(f"--adapt {adapt} meets each test person with their own "
                            "session; "
                            "use it with a protocol that holds whole people out (lopo, "
                            "group-kfold), not all-inclusive")
        if adapt != "none" and not resolved.can_adapt:
            raise UserError(f"--adapt {adapt} standardises {self.model}'s features per "
                            "person; "
                            "it does not combine with --augment (augmented windows have no "
                            "person's statistics of their own)"
                            + ("; --set rf_adapt=0 adapts its network alone"
                               if self.model not in BASELINES else ""))
        if len(self.split) != 3 or min(self.split) <= 0:
            raise UserError("the all-inclusive split needs three positive fractions")
        if self.shots:
            if self.protocol == "all-inclusive":
                raise UserError("--shots gives a held-out person's labelled performances to "
                                "the training; use it with lopo or group-kfold, not "
                                "all-inclusive")
            if min(self.shots) < 0 or len(set(self.shots)) != len(self.shots):
                raise UserError(f"--shots takes distinct counts of 0 or more, got "
                                f"{','.join(map(str, self.shots))}")
        if self.shots_by not in SHOTS_BY:
            raise UserError(f"unknown --shots-by {self.shots_by!r} "
                            f"(available: {', '.join(SHOTS_BY)})")
        if self.shots_by == "fine-tune" and self.forest:
            name = display_name(self.model, self.overrides)
            raise UserError(f"{name} has no fine-tuning: its shots join the training "
                            "(--shots-by join)")


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
    folds: list[dict[str, Any]]
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
                 labels: np.ndarray, stats, people: np.ndarray | None = None) -> dict[str, Any]:
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
    return {"owner": owner[mask].tolist(), "y_true": labels[owner[mask]].tolist(),
            "probs": np.round(probs, 5).tolist()}


def _train_fold(learner, info: DataInfo, ds: TrialDataset, x: np.ndarray, owner: np.ndarray,
                fold, round_: int, k: int, seed: int, cancel: CancelToken,
                on_epoch: Callable[[dict[str, Any]], None], extra: Any = None,
                balance: bool = False, people: np.ndarray | None = None,
                moments: Moments | None = None) -> tuple[dict[str, Any], Any]:
    t0 = time.perf_counter()
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
    rec = _fold_record(learner, ds, x, owner, fold, round_, k, seed, fitted, stats, history,
                       best, people, t0)
    if moments is not None and people is not None:  # a forest's view as trained
        rec["as_trained"] = pooled_reference(moments, np.unique(people[tr])).tolist()
    return rec, fitted


def _fold_record(learner, ds: TrialDataset, x: np.ndarray, owner: np.ndarray, fold,
                 round_: int, k: int, seed: int, fitted: Any, stats: dict[str, Any],
                 history: list[dict[str, Any]], best: Any, people: np.ndarray | None,
                 t0: float) -> dict[str, Any]:
    """A finished fold as runfolder saves it: its trials, normalisation, training curve
    and the test (and held-out) predictions of ``fitted``."""
    y = ds.labels
    uid = np.array(ds.uids)
    rec = {
        "round": round_, "fold": k, "name": fold.name, "seed": seed,
        "test_participants": fold.test_participants,
        "train": uid[fold.train].tolist(), "val": uid[fold.val].tolist(),
        "test": uid[fold.test].tolist(), "heldout": uid[fold.heldout].tolist(),
        **({"shots": fold.shots} if fold.shots is not None else {}),
        "norm": stats, "history": history, "best_epoch": best,
        "predictions": _predictions(fitted, learner, x, owner, fold.test, y, stats, people),
        "seconds": time.perf_counter() - t0,
    }
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


def _fine_tune_fold(learner, ds: TrialDataset, x: np.ndarray, owner: np.ndarray, fold,
                    round_: int, k: int, seed: int, base: tuple[Any, dict[str, Any]],
                    cancel: CancelToken, people: np.ndarray | None
                    ) -> tuple[dict[str, Any], Any]:
    """``--shots-by fine-tune``: the fold's K = 0 model (``base``: fitted, its
    normalisation) with its output layers fine-tuned on the windows of the fold's shot
    performances, as live calibration does (learners/fine_tune.py); tested on the same
    trials as K = 0. No training curve (history empty)."""
    t0 = time.perf_counter()
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
    rec = _fold_record(learner, ds, x, owner, fold, round_, k, seed, fitted, stats, [],
                       None, people, t0)
    rec["fine_tuned_windows"] = int(sel.sum())
    return rec, fitted


def run_header(config: ExperimentConfig, channels: str | None, windowed: bool
               ) -> dict[str, Any]:
    """What metrics.json (train, sweep) and rescore.json (evaluate) say about the run."""
    header = {"model": config.model, "protocol": config.protocol, "channels": channels,
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
    """The run's title on its figures: model (fused with rf if so), preset, protocol."""
    return (f"{display_name(config.model, config.overrides)} ({config.preset}) · "
            f"{config.protocol} · {channels}"
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
    folds = make_folds(config.protocol, ds.labels, ds.participants, seed, config.folds,
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
    """Train and evaluate ``config.model`` under ``config.protocol``; see module doc.

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
    with _torch_threads(config.threads), faults:
        return _run(config, out, progress, cancel, listener, model_spec, dataset)


@contextmanager
def _torch_threads(n: int | None) -> Iterator[None]:
    """Use ``n`` torch CPU threads for the duration (the setting is process-wide)."""
    if not n:
        yield
        return
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def _run(config: ExperimentConfig, out, progress: ProgressFn, cancel: CancelToken,
         listener: Listener, model_spec: Any, dataset: TrialDataset | None) -> RunResult:
    learner = make_learner(config.model, config.preset, config.overrides, config.epochs,
                           config.device, model_spec)
    if dataset is None:
        ds = build_dataset(config.data, config.grid, config.channels, config.cache_dir,
                           config.use_cache, lambda f, m: progress(0.05 * f, m), cancel)
    else:
        ds = dataset if config.channels in (None, dataset.channels) else \
            dataset.select(config.channels)
    if ds.n_classes < 2:
        raise UserError(f"the data has one gesture only ({ds.label_names[0]}); "
                        "classification needs at least 2")
    info = DataInfo.of(ds)
    learner.check(info)
    first_folds = folds_for(config, ds, 0)  # fails early on too few participants
    header = run_header(config, ds.channels, learner.windowed)
    if config.shots:  # the trials a plain run would test: said beside the shots' test set
        header["data_trials"] = len(ds)
    resolved = {"model": learner.describe(), "data_info": info.to_dict(),
                "dataset": ds.summary(), "versions": _versions(),
                "created": time.strftime("%Y-%m-%dT%H:%M:%S")}
    folder = RunFolder(out) if out is not None else None
    if folder is not None:
        folder.start(config.to_dict(), resolved, RESULT_KEYS, result_defaults())
        from tactile_studio.learn.data.trialinfo import write_trial_table

        write_trial_table(folder.path, ds.uids, ds.participants.tolist(), config.data)
    progress(0.05, f"making model inputs: {len(ds)} trials, {learner.facts.view} view")
    ds, x, owner, n_pieces, spec, extra, moments = prepare_inputs(learner, ds, config)
    header["window_s"] = spec.seconds
    header["windows"] = n_pieces
    total_units = config.rounds * len(first_folds)
    records: list[dict[str, Any]] = []
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
                    zero_fold = _without_shots(fold, ds.participants)
                    name = f"{r} {zero_fold.name}"
                    if fine and fold.shots and name != base_name:  # K = 0 not trained here
                        progress(0.05 + 0.92 * done / total_units, f"{where} training K = 0")
                        zero, fitted0 = _train_fold(
                            learner, info, ds, x, owner, zero_fold, r, k, seed, cancel,
                            on_epoch, extra, config.balance, people, moments)
                        base_name, base = name, (fitted0, zero["norm"])
                    if fine and fold.shots:
                        progress(0.05 + 0.92 * done / total_units, f"{where} fine-tuning")
                        rec, fitted = _fine_tune_fold(learner, ds, x, owner, fold, r, k, seed,
                                                      base, cancel, people)
                    else:
                        progress(0.05 + 0.92 * done / total_units, f"{where} training")
                        rec, fitted = _train_fold(learner, info, ds, x, owner, fold, r, k,
                                                  seed, cancel, on_epoch, extra,
                                                  config.balance, people, moments)
                        if fine:  # K = 0: the model each K of this fold fine-tunes
                            base_name, base = name, (fitted, rec["norm"])
                    if folder is not None:
                        folder.save_fold(rec, fitted)
                records.append(rec)
                done += 1
                progress(0.05 + 0.92 * done / total_units, f"{where} done")
                fm = fold_metrics(rec, ds.label_names, learner.windowed,
                                  aggregate=config.aggregate)
                listener(Fold(round=r, fold=k, n_folds=len(folds), fold_name=fold.name,
                              accuracy=float(fm["accuracy"]),
                              trial_accuracy=float(fm["trial_accuracy"]),
                              cut=trials_were_cut(fm), resumed=resumed))
    except Cancelled:
        if records and folder is not None:
            metrics = summarise(records, ds.label_names, learner.windowed, header, False)
            folder.write_results(metrics, records, title + " (partial)")
        kept = f", kept in {folder.path}; the same --out resumes" if folder is not None else ""
        raise Cancelled(f"training cancelled: {len(records)} of {total_units} folds "
                        f"finished{kept}") from None
    progress(0.98, "writing results")
    metrics = summarise(records, ds.label_names, learner.windowed, header, True)
    if folder is not None:
        folder.write_results(metrics, records, title)
    progress(1.0, headline(metrics))
    return RunResult(metrics, config, Path(out) if out is not None else None, records, True,
                     resolved["dataset"])
