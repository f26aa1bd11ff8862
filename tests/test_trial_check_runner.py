"""The runner's model check (issue 46): each finished trial is scored by the session's
TrialChecker; a flagged verdict adds ``model_mismatch`` with its reason to the trial, the
redo prompt and the trial-ended event; Redo and Keep are stored as the decision."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from collect_fixtures import do_trial, make_rig, mini_protocol, start

from tactile_studio.protocol.randomise import block_orders
from tactile_studio.protocol.trial_check import TrialChecker, TrialVerdict, verdict
from tactile_studio.storage.session import Session
from tactile_studio.storage.trial_checks import check_problems


class ContactShare:
    """A checker of the test's own that reads the trial's frames: a trial the sensor
    was not touched in looks like 'nothing', so any prompted gesture is flagged; a
    touched trial (10% of its frames) looks like its prompt. It stands for a model (the
    real ones are tested in test_trial_check_model.py); tested here: the runner's side."""

    def __init__(self, gestures: list[str], unknown: str) -> None:
        self.known = frozenset(g for g in gestures if g != unknown)  # not scored
        self.labels = [*sorted(self.known), "nothing"]
        self.calls = 0

    def describe(self) -> dict[str, Any]:
        return {"model": "contact-share", "version": "1", "top_k": 1, "threshold": 0.5}

    def check(self, layout, raw, baseline, rate_hz, prompted) -> TrialVerdict | None:  # noqa: ANN001
        self.calls += 1
        if prompted not in self.known:
            return None
        share = float((np.asarray(raw) < 0.985 * baseline).any(axis=1).mean())
        touched = 0.9 if share >= 0.1 else 0.1
        probs = np.full(len(self.labels), 0.0)
        probs[self.labels.index(prompted)] = touched
        probs[-1] = 1.0 - touched
        return verdict(self.labels, probs, prompted, top_k=1, threshold=0.5)


def test_a_flagged_verdict_reaches_trial_prompt_event_and_file(tmp_path: Path) -> None:
    protocol = mini_protocol(3)
    order = block_orders(protocol, "P01", 0)[0]
    checker = ContactShare(protocol.gesture_names, unknown=order[-1])  # the block's last
    assert isinstance(checker, TrialChecker)
    rig = make_rig(tmp_path, protocol, hold_flagged=True, trial_check=checker)
    r = rig.runner
    ended: list[dict] = []
    r.add_listener(lambda e: ended.append(e) if e["kind"] == "trial_ended" else None)
    try:
        start(rig)
        g0 = r.snapshot().remaining[0]
        t0 = do_trial(rig, g0, perform=False)
        assert "model_mismatch" in t0["flags"]
        assert t0["check"]["model"] == "contact-share" and t0["check"]["flagged"]
        assert t0["check"]["reason"].startswith("looks like nothing (")
        assert ended[-1]["flags"] == t0["flags"]
        assert t0["check"]["reason"] in ended[-1]["reason"]
        assert t0["check"]["reason"] in r.redo_prompt
        assert r.redo_last()
        t0_after = r.trials[0]
        assert t0_after["status"] == "redone" and t0_after["decision"] == "redo"
        t1 = do_trial(rig, g0)
        assert "model_mismatch" not in t1["flags"] and not t1["check"]["flagged"]
        # a flagged trial kept: Continue while the redo prompt asks
        g = r.snapshot().remaining[0]
        assert g in checker.known
        t2 = do_trial(rig, g, perform=False)
        assert "model_mismatch" in t2["flags"]
        assert r.proceed()
        kept = r.trials[-1]
        assert kept["decision"] == "keep" and kept["flags"] == t2["flags"]
    finally:
        rig.close()
    with Session(rig.session.path) as s:
        assert s.metadata["trial_check"]["model"] == "contact-share"
        assert s.metadata["trial_check"]["not_scored"] == [order[-1]]
        assert [t.get("decision") for t in s.trials[:1]] == ["redo"]
        assert s.trials[-1]["decision"] == "keep"
        assert all(not check_problems(t) for t in s.trials)


def test_unknown_gestures_are_not_scored(tmp_path: Path) -> None:
    protocol = mini_protocol(3)
    checker = ContactShare(protocol.gesture_names, unknown=protocol.gesture_names[0])
    rig = make_rig(tmp_path, protocol, trial_check=checker)
    r = rig.runner
    try:
        start(rig)
        seen = []
        for _ in range(3):
            g = r.snapshot().remaining[0]
            seen.append((g, do_trial(rig, g)))
    finally:
        rig.close()
    for g, t in seen:
        assert ("check" in t) == (g in checker.known)
