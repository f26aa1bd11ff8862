"""What the experimenter reads about flagged trials: one reason per trial and, at each
block's end, one line per gesture ("Twist: 2 of 4 look like Wide Pinch").

Qt-free wording over the trial records, so the console, the headless collection and a
report say the same thing. A trial's reason is its signal flags in words
(:data:`~tactile_studio.protocol.quality.FLAG_TEXT`) and, when a model checked it, the
reason of its stored ``check`` ("looks like Wide Pinch (0.61); Twist 0.07").
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any

from tactile_studio.protocol.quality import FLAG_TEXT, describe
from tactile_studio.storage.format.trial_checks import MISMATCH_FLAG
from tactile_studio.storage.format.trials import TrialRecord, records


def looks_like(trial: TrialRecord) -> str | None:
    """The gesture a model took a flagged trial for (None: no model flag): the most
    likely gesture in its stored check other than the prompted one."""
    if MISMATCH_FLAG not in trial.flags or not trial.check:
        return None
    return next((str(g) for g, _p in trial.check.get("top") or () if g != trial.gesture), None)


def trial_reason(trial: Mapping[str, Any] | TrialRecord) -> str:
    """Why a trial is flagged, read at a glance ("" when it is not): the signal flags in
    words, the model's flag as its reason (quality.describe, as the redo prompt)."""
    t = trial if isinstance(trial, TrialRecord) else TrialRecord.from_dict(trial)
    return describe(list(t.flags), t.check)


def _what(flag_or_gesture: tuple[str, str], n: int) -> str:
    kind, name = flag_or_gesture
    if kind == "looks":
        return f"look{'s' if n == 1 else ''} like {name}"
    return FLAG_TEXT.get(name, name)


def block_summary(trials: Iterable[Mapping[str, Any] | TrialRecord],
                  through_block: int) -> list[str]:
    """One line per gesture with flagged performances in blocks ``0..through_block``
    (practice left out), counted over every performance of the gesture so far, redone
    ones included (a redo is a second performance): "Twist: 2 of 4 look like Wide Pinch,
    1 of 4 no contact". Gestures in the order they were first performed; [] when nothing
    was flagged."""
    performed: Counter[str] = Counter()
    reasons: dict[str, Counter[tuple[str, str]]] = {}
    for t in records(trials):
        if t.practice or t.block > through_block:
            continue
        performed[t.gesture] += 1
        seen = reasons.setdefault(t.gesture, Counter())
        other = looks_like(t)
        if other is not None:
            seen[("looks", other)] += 1
        elif MISMATCH_FLAG in t.flags:
            seen[("flag", MISMATCH_FLAG)] += 1
        for f in t.flags:
            if f != MISMATCH_FLAG:
                seen[("flag", f)] += 1
    lines = []
    for gesture, n in performed.items():
        seen = reasons.get(gesture) or Counter()
        if not seen:
            continue
        parts = [f"{k} of {n} {_what(what, k)}" for what, k in seen.most_common()]
        lines.append(f"{gesture}: {', '.join(parts)}")
    return lines
