"""Text tables of a session's trials, for ``tactile-studio info`` and the console."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

from tactile_studio.protocol.quality import FLAGS
from tactile_studio.storage.format.trial_checks import check_counts, counts_line
from tactile_studio.storage.format.trials import TrialRecord, TrialStatus, records

STATUSES = tuple(s.value for s in TrialStatus)  # ok, redone, discarded


def trial_table(trials: Sequence[Mapping[str, Any] | TrialRecord],
                gestures: list[str] | None = None) -> str:
    """Trials per gesture by status, plus how many were flagged and why.

    ``gestures`` (the session's ordered label set) fixes the row order; gestures only
    seen in trials follow. Practice trials (block < 0) are counted on a line of their own.
    """
    if not trials:
        return "no trials"
    real = [t for t in records(trials) if not t.practice]
    practice = len(trials) - len(real)
    order = list(gestures or [])
    order += sorted({t.gesture for t in real} - set(order))
    counts = {g: Counter() for g in order}
    flags: Counter[str] = Counter()
    for t in real:
        c = counts[t.gesture]
        c[t.status.value] += 1
        if t.flags:
            c["flagged"] += 1
            flags.update(t.flags)
    cols = (*STATUSES, "flagged")
    width = max([len("gesture"), len("total")] + [len(g) for g in order])
    lines = [f"{'gesture':<{width}}  " + "  ".join(f"{c:>9}" for c in cols)]
    total: Counter[str] = Counter()
    for g in order:
        total.update(counts[g])
        lines.append(f"{g:<{width}}  " + "  ".join(f"{counts[g][c]:>9}" for c in cols))
    lines.append(f"{'total':<{width}}  " + "  ".join(f"{total[c]:>9}" for c in cols))
    if flags:
        known = [f for f in FLAGS if f in flags] + sorted(set(flags) - set(FLAGS))
        lines.append("flags: " + ", ".join(f"{f} {flags[f]}" for f in known))
    decided = counts_line(check_counts(trials))  # the experimenter's answers, the model's
    if decided:
        lines.append(decided)
    blocks = sorted({t.block for t in real})
    if blocks:
        lines.append(f"blocks: {len(blocks)} ({blocks[0] + 1}..{blocks[-1] + 1})")
    if practice:
        lines.append(f"practice trials: {practice}")
    return "\n".join(lines)
