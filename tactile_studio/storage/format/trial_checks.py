"""A trial's model check as it is decided and stored: :class:`TrialVerdict`, the rule that
makes one from a model's probabilities, and the trial record's ``check`` / ``decision``.

It lives in ``storage`` because both sides meet here: ``protocol`` (the runner stores a
verdict on the trial) and ``learn`` (a model makes it) may not import each other, and
``check``, ``info``, the exports and ``qc`` read the stored form. The rule (issue 46,
research decision 5): a trial is flagged when the model's probability of the prompted
gesture is below ``threshold``, or (``top_k`` 1 or more; 0, the default: off) the prompted
gesture is not among the model's ``top_k``; the reason names what the trial looked like,
"looks like Wide Pinch (0.61); Twist 0.07" (docs/trial-check.md).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.storage.format.trials import TrialRecord, records

MISMATCH_FLAG = "model_mismatch"
DECISIONS = ("redo", "keep")
# chosen from train's default model's out-of-fold scores on the development set's five
# people (benchmarks/bench_qc_real.py, docs/trial-check.md "Why these defaults"): with the
# check adapted and personalised, p < 0.13 flags 88% of relabelled 12 s performances and
# 8% of honest ones; a top-k rule beside it only added honest flags (top 3: +2 points per
# performance, +2 to +6 per 2 s trial) for at most one point of catch
DEFAULT_TOP_K = 0  # off
DEFAULT_THRESHOLD = 0.13
# personalise the check with the participant's first block (the few-shot route) unless the
# study said otherwise: on the same people, adapted and personalised, ROC AUC 0.968 per
# 12 s performance and 8% of honest ones flagged, against 0.951 and 13% adapted alone
DEFAULT_PERSONALISE = True
SHOWN = 3  # gestures named in a reason


@dataclass(frozen=True)
class TrialVerdict:
    """What a model says of one trial against its prompted gesture."""

    flagged: bool
    reason: str        # "looks like Wide Pinch (0.61); Twist 0.07" ("" when not flagged)
    p_prompted: float  # the model's probability of the prompted gesture
    rank: int          # 1-based rank of the prompted gesture among the model's gestures
    top: tuple[tuple[str, float], ...]  # the model's most likely gestures, best first

    def stored(self, model: str) -> dict[str, Any]:
        """The trial record's ``check`` (docs/session-format.md)."""
        return {"model": model, "p_prompted": round(float(self.p_prompted), 4),
                "rank": int(self.rank), "flagged": bool(self.flagged),
                "top": [[g, round(float(p), 4)] for g, p in self.top],
                "reason": self.reason}


def verdict(labels: Sequence[str], probs: np.ndarray, prompted: str,
            top_k: int = DEFAULT_TOP_K, threshold: float = DEFAULT_THRESHOLD
            ) -> TrialVerdict | None:
    """The verdict of probabilities ``probs`` over ``labels`` for a trial prompted as
    ``prompted``; None when the model does not know that gesture (not scored)."""
    labels = list(labels)
    if prompted not in labels:
        return None
    p = np.asarray(probs, dtype=np.float64).reshape(-1)
    order = np.argsort(-p, kind="stable")
    i = labels.index(prompted)
    rank = int(np.nonzero(order == i)[0][0]) + 1
    p_prompted = float(p[i])
    flagged = (int(top_k) > 0 and rank > int(top_k)) or p_prompted < float(threshold)
    top = tuple((labels[j], float(p[j])) for j in order[:max(SHOWN, int(top_k))])
    reason = mismatch_reason(top, prompted, p_prompted) if flagged else ""
    return TrialVerdict(flagged, reason, p_prompted, rank, top)


def rule_text(top_k: int, threshold: float) -> str:
    """The rule in words: "p < 0.13", "not in the top 3 or p < 0.1"."""
    p = f"p < {float(threshold):g}"
    return f"not in the top {int(top_k)} or {p}" if int(top_k) > 0 else p


def mismatch_reason(top: Sequence[tuple[str, float]], prompted: str, p_prompted: float) -> str:
    """"looks like Wide Pinch (0.61); Twist 0.07": the most likely other gesture, then
    the prompted one's own probability."""
    other = next(((g, p) for g, p in top if g != prompted), None)
    if other is None:
        return f"{prompted} only {p_prompted:.2f}"
    return f"looks like {other[0]} ({other[1]:.2f}); {prompted} {p_prompted:.2f}"


def check_problems(trial: Mapping[str, Any]) -> list[str]:
    """What is inconsistent in one stored trial's check and decision (``check``):
    the ``model_mismatch`` flag without a flagged check or the other way round, a
    probability or rank out of range, a decision that is not redo/keep or was made on
    a trial that was never flagged, a redo decision on a trial that was not redone."""
    out: list[str] = []
    flags = list(trial.get("flags") or [])
    check = trial.get("check")
    decision = trial.get("decision")
    if check is not None:
        if not isinstance(check, Mapping):
            return ["its check is not a record"]
        p, rank = check.get("p_prompted"), check.get("rank")
        if not isinstance(p, (int, float)) or not 0.0 <= float(p) <= 1.0:
            out.append(f"check p_prompted {p!r} is not a probability")
        if not isinstance(rank, int) or rank < 1:
            out.append(f"check rank {rank!r} is not a rank")
        if bool(check.get("flagged")) != (MISMATCH_FLAG in flags):
            out.append("check and its model_mismatch flag disagree")
    elif MISMATCH_FLAG in flags:
        out.append("flagged model_mismatch without a stored check")
    if decision is not None:
        if decision not in DECISIONS:
            out.append(f"decision {decision!r} is not redo or keep")
        elif not flags:
            out.append(f"decision {decision} on a trial without flags")
        elif decision == "redo" and trial.get("status") not in ("redone", "discarded"):
            out.append("decision redo but the trial was not redone")
    return out


def check_counts(trials: Iterable[Mapping[str, Any] | TrialRecord]) -> dict[str, Any]:
    """What ``info`` says of a session's checks: trials flagged (practice left out), per
    flag, those the model checked, and the experimenter's decisions."""
    real = [t for t in records(trials) if not t.practice]
    flagged = [t for t in real if t.flags]
    by_flag: dict[str, int] = {}
    for t in flagged:
        for f in t.flags:
            by_flag[str(f)] = by_flag.get(str(f), 0) + 1
    decisions = {d: sum(1 for t in flagged if t.decision == d) for d in DECISIONS}
    return {"flagged": len(flagged), "by_flag": by_flag,
            "model_checked": sum(1 for t in real if t.check),
            "decisions": decisions,
            "undecided": len(flagged) - sum(decisions.values())}


def counts_line(counts: Mapping[str, Any]) -> str:
    """"decisions: redo 2, keep 1, undecided 0; 40 checked by the model" for ``info``'s
    trial table ("" when nothing was flagged nor checked)."""
    if not counts["flagged"] and not counts["model_checked"]:
        return ""
    d = counts["decisions"]
    text = f"decisions: redo {d['redo']}, keep {d['keep']}, undecided {counts['undecided']}"
    if counts["model_checked"]:
        text += f"; {counts['model_checked']} checked by the model"
    return text


CSV_COLUMNS = ["check_model", "p_prompted", "rank", "predicted", "check_reason", "decision",
               "performed"]


def csv_fields(trial: Mapping[str, Any]) -> dict[str, Any]:
    """A trial's check, decision and performed gesture as flat CSV columns (empty when
    not stored)."""
    c = trial.get("check") if isinstance(trial.get("check"), Mapping) else {}
    top = c.get("top") or []
    return {"check_model": c.get("model", ""), "p_prompted": c.get("p_prompted", ""),
            "rank": c.get("rank", ""), "predicted": top[0][0] if top else "",
            "check_reason": c.get("reason", ""), "decision": trial.get("decision") or "",
            "performed": trial.get("performed") or ""}
