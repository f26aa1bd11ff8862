"""Training in a separate process, for the GUI: the window never freezes, a crash in the
worker never takes it down, and events arrive as the typed
:mod:`~tactile_studio.learn.experiments.job_events`.

``TrainJob(config, out).start()`` spawns a fresh interpreter (multiprocessing "spawn",
so no Qt or torch state is inherited) that runs :func:`run_experiment` into ``out``.
:meth:`TrainJob.poll` returns the events that arrived since the last call:
:class:`~.job_events.Progress`, :class:`~.job_events.Epoch`, :class:`~.job_events.Fold`,
then one of :class:`~.job_events.Done` / :class:`~.job_events.Cancelled` /
:class:`~.job_events.Failed` — the last event of a job; a worker that dies without one
(killed, segfault) is reported as a ``Failed`` too.

Cancelling keeps the finished folds (the run folder is resumable: starting the same
config into the same folder trains only what is missing).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import re
import threading
import time
from typing import Any

from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.job_events import (
    Cancelled,
    Done,
    Epoch,
    Failed,
    Fold,
    JobEvent,
    Progress,
    is_final,
)

_TRAIN_HELP = {
    "optimizer": "optimiser (adam, adamw, sgd)", "lr": "learning rate",
    "batch_size": "samples per training batch", "max_epochs": "upper limit of epochs",
    "patience": "epochs without validation gain before stopping",
    "weight_decay": "L2 penalty", "momentum": "SGD momentum",
}


def model_settings(name: str, preset: str) -> list[tuple[str, Any, str]]:
    """(option, default, one line of help) for a model's architecture and training
    options at ``preset`` — the form of the train panel."""
    from tactile_studio.learn.learners import fused
    from tactile_studio.learn.learners.families import make_learner
    from tactile_studio.learn.models import model_names, model_options

    learner = make_learner(name, preset)
    described = learner.describe()
    helps = {**_TRAIN_HELP, **learner.facts.option_help}
    # a learned model is fused with rf when rf_weight > 0 (learn/learners/fused.py): listed first
    options = {fused.OPTION: 0.0, **model_options(name, preset)} if name in model_names() \
        else {}
    options.update(described.get("model_options") or {})
    options.update(described.get("train") or {})
    return [(k, v, helps.get(k, "model option")) for k, v in options.items()]


def trains_in_epochs(name: str, preset: str = "full") -> bool:
    """The model trains in epochs (a network, fused with rf or not): rf and knn fit once,
    so the panels offer them no epochs, early stopping, epoch curve or fine-tuning."""
    from tactile_studio.learn.learners.families import make_learner

    return "train" in make_learner(name, preset).describe()


def eta_from_folds(durations: list[float], done: int, total: int,
                   in_current: float) -> float | None:
    """Remaining seconds from measured fold times: the mean of the folds trained here
    times the folds left, less the time already spent on the current one (None before
    a fold has finished; the run's start-up is no fold's time)."""
    if not durations or total <= 0:
        return None
    mean = sum(durations) / len(durations)
    left = max(0, total - done)
    return max(0.0, left * mean - (in_current if left else 0.0))


def eta_seconds(fraction: float, elapsed: float) -> float | None:
    """Remaining seconds if progress stays at its average pace (None before any)."""
    if fraction <= 0.01 or elapsed <= 0:
        return None
    return max(0.0, elapsed * (1 - fraction) / fraction)


class ProgressThrottle:
    """Which progress messages cross to the window: at most one each ``interval`` of one
    kind ("epoch 3 acc 0.52" and "epoch 4 acc 0.55" are one kind: numbers aside, the
    same text), but never the first of a new kind. Throttled by time alone, "decoded"
    stood in the Train tab while rf computed its features: that message came within
    0.1 s of it and was dropped."""

    def __init__(self, interval: float = 0.1, clock=time.monotonic) -> None:  # noqa: ANN001
        self.interval, self.clock = interval, clock
        self._last, self._kind = float("-inf"), None

    def passes(self, fraction: float, message: str) -> bool:
        now, kind = self.clock(), re.sub(r"[\d.]+", "#", message)
        if now - self._last > self.interval or fraction >= 1.0 or kind != self._kind or \
                message.endswith(("done", "training")):
            self._last, self._kind = now, kind
            return True
        return False


def _worker(config: dict[str, Any], out: str, events: Any, stop: Any) -> None:
    from tactile_studio.errors import Cancelled as Stopped
    from tactile_studio.errors import UserError
    from tactile_studio.jobs import CancelToken
    from tactile_studio.learn.evaluation.summary import headline, shots_curve
    from tactile_studio.learn.experiments.experiment import run_experiment

    token = CancelToken()

    def watch() -> None:
        stop.wait()
        token.cancel()

    threading.Thread(target=watch, daemon=True).start()
    throttle = ProgressThrottle()

    def progress(fraction: float, message: str = "") -> None:
        if throttle.passes(fraction, message):
            events.put(Progress(float(fraction), message))

    def listener(event: Epoch | Fold) -> None:  # already the typed events: pass them on
        events.put(event)

    try:
        result = run_experiment(ExperimentConfig.from_dict(config), out, progress, token,
                                listener)
        events.put(Done(out=out, accuracy=float(result.metrics["accuracy"]),
                        headline=headline(result.metrics),
                        shots=shots_curve(result.metrics.get("shots")),
                        curve=[{key: s.get(key) for key in ("k", "accuracy", "trial_accuracy")}
                               for s in result.metrics.get("shots") or []]))
    except Stopped:
        events.put(Cancelled())
    except UserError as exc:
        events.put(Failed(str(exc)))
    except Exception as exc:  # noqa: BLE001 - the window shows it; the traceback goes to stderr
        import traceback

        from tactile_studio.output_faults import fault_line

        if (line := fault_line(exc)) is not None:  # the run folder cannot be written
            events.put(Failed(line))
            return
        traceback.print_exc()
        events.put(Failed(f"the training process failed: {type(exc).__name__}: {exc}"))


class TrainJob:
    def __init__(self, config: ExperimentConfig, out: str | os.PathLike) -> None:
        self.config, self.out = config, str(out)
        ctx = mp.get_context("spawn")
        self._events = ctx.Queue()
        self._stop = ctx.Event()
        self._process = ctx.Process(target=_worker, daemon=True,
                                    args=(config.to_dict(), self.out, self._events, self._stop))
        self.started = 0.0
        self.fraction = 0.0
        self.finished: Done | Cancelled | Failed | None = None
        self.fold_times: list[float] = []  # seconds per fold trained here (not resumed)
        self.folds_done = 0
        self.folds_total = 0
        self._fold_began: float | None = None  # its first epoch, or the last fold's end

    def start(self) -> TrainJob:
        self.started = time.monotonic()
        self._process.start()
        return self

    @property
    def pid(self) -> int | None:
        return self._process.pid

    @property
    def running(self) -> bool:
        return self.finished is None

    def cancel(self) -> None:
        """Ask the worker to stop after the current epoch (finished folds are kept)."""
        self._stop.set()

    def eta(self) -> float | None:
        """Seconds left, from the measured times of the folds finished so far (None
        until one has: the pace of loading data says nothing about training)."""
        now = time.monotonic()
        began = self._fold_began if self._fold_began is not None else now
        return eta_from_folds(self.fold_times, self.folds_done, self.folds_total, now - began)

    def _take(self, event: JobEvent, out: list[JobEvent]) -> None:
        out.append(event)
        now = time.monotonic()
        if isinstance(event, Progress):
            self.fraction = event.fraction
        if isinstance(event, (Epoch, Fold)):
            self.folds_total = int(event.n_folds) * max(1, int(self.config.rounds))
        if isinstance(event, Epoch) and self._fold_began is None:
            self._fold_began = now  # the first fold starts training (data loaded)
        if isinstance(event, Fold):
            self.folds_done += 1
            if not event.resumed and self._fold_began is not None:
                self.fold_times.append(now - self._fold_began)
            elif not event.resumed:  # a model without epochs: from the start
                self.fold_times.append(now - self.started)
            self._fold_began = now
        if is_final(event):
            self.finished = event

    def poll(self) -> list[JobEvent]:
        out: list[JobEvent] = []
        if self.finished is not None:
            return out
        dead = self.started and not self._process.is_alive()
        while self.finished is None:
            try:  # a dead worker's last events may still be in the pipe
                event = self._events.get(timeout=0.5) if dead else self._events.get_nowait()
            except queue.Empty:
                break
            self._take(event, out)
        if self.finished is None and dead:
            code = self._process.exitcode
            self._take(Failed(f"the training process ended unexpectedly (exit code {code}); "
                              f"finished folds are kept in {self.out}"), out)
        if self.finished is not None:
            self._process.join(timeout=5)
        return out
