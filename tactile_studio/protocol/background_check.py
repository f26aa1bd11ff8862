"""A trial check that runs beside the runner, not in it: :class:`BackgroundCheck`.

The runner scores a finished trial at the tick that ends it. In the console that tick is
the GUI's timer, so a model that takes 50-300 ms (a forest's features, a CNN on CPU) froze
the heatmap and the buttons for that long at every beep. Wrapped in a BackgroundCheck the
same checker scores the trial on one worker thread: the trial is written at once with its
signal flags, the verdict joins it (``check``, ``model_mismatch``) at the first tick after
the model answers, and a held session waits for it (at most ``wait_s``) before the next
key is taken. Headless collection keeps the plain checker (nothing to keep responsive).
Adapting the check to the participant's statistics after each block runs on the same
worker, so the trials ended meanwhile are scored, in order, by the model as it then is.
Personalising it after the first block takes seconds (a forest is refit): a checker that
can make a fresh copy of itself (``fresh()``) is personalised on that copy on a second
worker while the first goes on scoring with the check as it was, and the copy takes over
once it is ready, so no verdict waits for the refit. A checker without ``fresh`` is
personalised on the scoring worker (its verdicts wait).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from tactile_studio.protocol.trial_check import TrialChecker, TrialVerdict
from tactile_studio.sensor.layout import Layout

WAIT_S = 2.0  # a held trial waits this long for its verdict, then the session goes on
PERSONALISE_WAIT_S = 60.0  # a session ending waits this long for a personalisation underway


class BackgroundCheck:
    """``checker`` on a worker thread (a TrialChecker itself: ``check`` still answers
    in the caller's thread, for whoever wants to wait)."""

    def __init__(self, checker: TrialChecker, wait_s: float = WAIT_S) -> None:
        self.checker = checker
        self.known = checker.known
        self.wait_s = float(wait_s)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trial-check")
        self._refit = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trial-check-fit")
        # the last adaptation asked for, replayed on a personalised copy before it takes over
        self._adapted_with: tuple[Layout, list[Any], float] | None = None

    def describe(self) -> dict[str, Any]:
        return self.checker.describe()

    def check(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray, rate_hz: float,
              prompted: str) -> TrialVerdict | None:
        return self.checker.check(layout, raw, baseline, rate_hz, prompted)

    def submit(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray, rate_hz: float,
               prompted: str) -> Future[tuple[TrialVerdict | None, str]]:
        """Score a trial on the worker (copies of the frames: the ring moves on); the
        future gives (verdict, the id of the model that gave it)."""
        raw, baseline = np.array(raw), np.array(baseline)

        def score() -> tuple[TrialVerdict | None, str]:
            checker = self.checker  # one model for the verdict and its id (see fresh)
            verdict = checker.check(layout, raw, baseline, rate_hz, prompted)
            return verdict, str(checker.describe()["model"])
        return self._pool.submit(score)

    @property
    def can_personalise(self) -> bool:
        return hasattr(self.checker, "personalise")

    def personalise_later(self, layout: Layout,
                          trials: Sequence[tuple[np.ndarray, np.ndarray, str]],
                          rate_hz: float) -> Future[int]:
        """Personalise the checker off the screen's thread; the future gives the number of
        trials used, or raises the checker's UserError (the check then stays as it was).
        On a fresh copy when the checker can make one: the trials that end meanwhile are
        scored at once by the check as it was; else on the scoring worker."""
        trials = list(trials)
        fresh = getattr(self.checker, "fresh", None)
        if fresh is None:
            return self._pool.submit(getattr(self.checker, "personalise"), layout, trials,
                                     rate_hz)

        def fit() -> int:
            copy = fresh()
            n = int(copy.personalise(layout, trials, rate_hz))
            adapted = self._adapted_with
            if adapted is not None and getattr(copy, "adapts", False):
                copy.adapt(*adapted)  # the person's statistics, as the check had them
            self.checker = copy  # later verdicts (and adaptations) are the copy's
            return n
        return self._refit.submit(fit)

    @property
    def adapts(self) -> bool:
        return bool(getattr(self.checker, "adapts", False))

    def adapt_later(self, layout: Layout,
                    trials: Sequence[tuple[np.ndarray, np.ndarray, str]],
                    rate_hz: float) -> Future[tuple[int, str]]:
        """Adapt the checker to the participant's trials on the worker (the trials scored
        after it wait for it); the future gives (trials it rests on, the model's id)."""
        trials = list(trials)
        self._adapted_with = (layout, trials, rate_hz)

        def run() -> tuple[int, str]:
            checker = self.checker  # the personalised copy once it has taken over
            n = getattr(checker, "adapt")(layout, trials, rate_hz)
            return n, str(checker.describe()["model"])
        return self._pool.submit(run)

    def close(self) -> None:
        """Let the worker end after the check it is running (none is lost: the runner
        waits for a pending verdict before the session ends)."""
        self._pool.shutdown(wait=False, cancel_futures=False)
        self._refit.shutdown(wait=False, cancel_futures=False)
