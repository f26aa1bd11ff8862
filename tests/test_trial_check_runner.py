"""The runner's model check (issue 46): each finished trial is scored by the session's
TrialChecker; a flagged verdict adds ``model_mismatch`` with its reason to the trial, the
redo prompt and the trial-ended event; Redo and Keep are stored as the decision."""

from __future__ import annotations

import time
from pathlib import Path

from check_fixtures import ContactShare
from collect_fixtures import do_trial, make_rig, mini_protocol, start

from tactile_studio.protocol.randomise import block_orders
from tactile_studio.protocol.runner_events import TrialEnded
from tactile_studio.protocol.trial_check import TrialChecker
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.trial_checks import check_problems


def test_a_flagged_verdict_reaches_trial_prompt_event_and_file(tmp_path: Path) -> None:
    protocol = mini_protocol(3)
    order = block_orders(protocol, "P01", 0)[0]
    checker = ContactShare(protocol.gesture_names, unknown=order[-1])  # the block's last
    assert isinstance(checker, TrialChecker)
    rig = make_rig(tmp_path, protocol, hold_flagged=True, trial_check=checker)
    r = rig.runner
    ended: list[TrialEnded] = []
    r.add_listener(lambda e: ended.append(e) if isinstance(e, TrialEnded) else None)
    try:
        start(rig)
        g0 = r.snapshot().remaining[0]
        t0 = do_trial(rig, g0, perform=False)
        assert "model_mismatch" in t0["flags"]
        assert t0["check"]["model"] == "contact-share" and t0["check"]["flagged"]
        assert t0["check"]["reason"].startswith("looks like nothing (")
        assert list(ended[-1].flags) == t0["flags"]
        assert t0["check"]["reason"] in ended[-1].reason
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
    with SessionFile(rig.session.path) as s:
        assert s.metadata["trial_check"]["model"] == "contact-share"
        assert s.metadata["trial_check"]["not_scored"] == [order[-1]]
        assert [t.decision for t in s.trials[:1]] == ["redo"]
        assert s.trials[-1].decision == "keep"
        assert all(not check_problems(t) for t in s.journal.trials)  # the file's form


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


class _RingFiller(ContactShare):
    """A check that takes as long as the stream needs to run a whole ring past the
    trial's end (a slow model while a speed-0 simulator runs ahead)."""

    def __init__(self, gestures: list[str], rig_box: list) -> None:
        super().__init__(gestures, unknown="")
        self.rig_box = rig_box
        self.filled = False

    def check(self, layout, raw, baseline, rate_hz, prompted):  # noqa: ANN001
        rig = self.rig_box[0]
        end = rig.runner._keys_from  # the trial's end: the stream is held a ring past it
        target = end + rig.engine.ring.capacity - 2  # beep frames past it: none
        for _ in range(30000):  # the simulator at speed 0 fills it in well under a second
            if rig.engine.frames >= target:
                self.filled = True
                break
            time.sleep(0.002)
        return super().check(layout, raw, baseline, rate_hz, prompted)


def test_a_check_slow_enough_for_the_stream_to_fill_the_ring_does_not_stop_the_session(
        tmp_path: Path) -> None:
    """The beep after a trial was timed from the newest frame once the check was done: a
    stream that had run a ring ahead meanwhile was held there, so the beep never ended
    and the session stopped (seen headless under load). It is timed from the trial's end."""
    protocol = mini_protocol(2)
    box: list = []
    checker = _RingFiller(protocol.gesture_names, box)
    rig = make_rig(tmp_path, protocol, speed=0.0, capacity=1 << 12, trial_check=checker)
    box.append(rig)
    try:
        start(rig)
        do_trial(rig, rig.runner.snapshot().remaining[0])  # stuck in trial_end before
        assert checker.filled and rig.runner.state != "trial_end"
    finally:
        rig.close()
