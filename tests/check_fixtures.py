"""A trial checker of the tests' own, and a collection recorded with it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from collect_fixtures import do_trial, drive, make_rig, mini_protocol, start

from tactile_studio.protocol.randomise import block_orders
from tactile_studio.protocol.trial_check import TrialVerdict, verdict


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


def record_checked_session(folder: Path) -> Path:
    """A real collection (3 gestures, one block) checked by ContactShare: trial 1 not
    touched, flagged and redone (decision redo), its redo touched, one untouched trial
    flagged and kept (decision keep), the block's last gesture not scored."""
    protocol = mini_protocol(3, blocks=1)
    order = block_orders(protocol, "P01", 0)[0]
    rig = make_rig(folder, protocol, hold_flagged=True,
                   trial_check=ContactShare(protocol.gesture_names, unknown=order[-1]))
    r = rig.runner
    try:
        start(rig)
        do_trial(rig, order[0], perform=False)
        assert r.redo_last()
        do_trial(rig, order[0])
        # the untouched trial once the touch before it has let go (its recovery tail read
        # as contact when the next key came at the first free frame)
        settled = rig.engine.frames + round(rig.engine.nominal_rate_hz)
        drive(rig, lambda: rig.engine.frames > settled)
        untouched = do_trial(rig, order[1], perform=False)
        assert r.proceed(), untouched  # Keep
        do_trial(rig, order[2])
    finally:
        rig.close()
    return rig.session.path
