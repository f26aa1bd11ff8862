"""The collection runner's side of the model check (issue 46): what it asks of a checker.

The runner holds a checker only through :class:`TrialChecker` (the learn side's
``tactile_studio.learn.deploy.trial_check.ModelTrialCheck`` is one; a test may pass its
own): when a trial ends it asks ``check(...)`` for a :class:`TrialVerdict`, adds the flag
``model_mismatch`` when the verdict is flagged, and stores the verdict on the trial
(``check``; docs/session-format.md). ``protocol`` and ``learn`` may not import each other,
so the verdict type lives in ``storage`` (:mod:`tactile_studio.storage.format.trial_checks`).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.format.trial_checks import (
    DEFAULT_THRESHOLD,
    DEFAULT_TOP_K,
    MISMATCH_FLAG,
    TrialVerdict,
    mismatch_reason,
    verdict,
)


@runtime_checkable
class TrialChecker(Protocol):
    """A model that says whether a finished trial looks like its prompted gesture."""

    known: frozenset[str]  # the gestures it can score; others are not checked

    def describe(self) -> dict[str, Any]:
        """The model's id (``model``), version and settings (``top_k``, ``threshold``),
        stored in the session's metadata (``trial_check``)."""
        ...

    def check(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray, rate_hz: float,
              prompted: str) -> TrialVerdict | None:
        """The verdict on a trial's raw counts (T, channels); None when ``prompted`` is
        not among ``known``."""
        ...


def unknown_gestures(checker: TrialChecker, gestures: list[str]) -> list[str]:
    """The protocol's gestures the checker does not know (not scored; the setup says so)."""
    return [g for g in gestures if g not in checker.known]


__all__ = ["DEFAULT_THRESHOLD", "DEFAULT_TOP_K", "MISMATCH_FLAG", "TrialChecker",
           "TrialVerdict", "mismatch_reason", "unknown_gestures", "verdict"]
