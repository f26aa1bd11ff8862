"""The runner on the real stream: real engine, real simulated sensor, real session file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from collect_fixtures import (
    do_trial,
    drive,
    make_rig,
    mini_protocol,
    perform_soon,
    run_virtual_participant,
    start,
)

from tactile_studio.cli import main
from tactile_studio.protocol.runner_events import TrialStarted
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.session_file import SessionFile


def test_virtual_participant_two_blocks(tmp_path: Path) -> None:
    protocol = load_protocol("shear9").with_overrides(blocks=2, free_play_s=1.0)
    rig = make_rig(tmp_path, protocol, "P07", speed=60.0)
    run_virtual_participant(rig, "P07")
    snap = rig.runner.snapshot()
    assert snap.trials_done == snap.trials_total == 18 and snap.progress == 1.0
    assert rig.beeps.asked == [(protocol.beep_hz, protocol.beep_s)] * 18
    n = round(protocol.trial_s * rig.device.nominal_rate_hz)
    with SessionFile(rig.session.path) as s:
        trials = s.journal.trials
        order = s.metadata["block_order"]
        assert s.metadata["participant"] == "P07" and s.metadata["source"] == "collect"
        assert s.metadata["gestures"] == protocol.gesture_names
        assert s.metadata["trial_order"] == "prompted"
        assert s.closed_cleanly
        assert [t["status"] for t in trials] == ["ok"] * 18
        assert [t["index"] for t in trials] == list(range(18))
        for b in (0, 1):
            done = [t["gesture"] for t in trials if t["block"] == b]
            assert sorted(done) == sorted(protocol.gesture_names)  # a permutation
            assert done == order[b]  # in the order shown
        for t in trials:
            assert t["end_sample"] - t["start_sample"] == n
            seq = s.column("seq", t["start_sample"], t["end_sample"])
            assert np.array_equal(np.diff(seq), np.ones(n - 1))  # every frame, in the file
            dt = s.column("device_time", t["start_sample"], t["end_sample"])
            assert t["start_time"] == round(float(dt[0]), 6)
            assert abs(t["end_time"] - t["start_time"] - protocol.trial_s) < 1e-6
            # the sensor really performed that gesture during the trial
            assert rig.device.gesture_at(int(seq[n // 2])) == t["gesture"]
            assert "no_contact" not in t["flags"]
        starts = [t["start_sample"] for t in trials]
        assert starts == sorted(starts) and all(
            b["start_sample"] >= a["end_sample"] for a, b in zip(trials, trials[1:]))


def test_a_session_as_fast_as_possible_keeps_every_trial_in_a_small_ring(tmp_path: Path) -> None:
    """At speed 0 the simulator runs as fast as its readers. The recorder holds it, but
    it keeps up at once; the trial's quality check reads the trial's frames from the
    ring only when the trial ends, so it holds the stream too: with a ring of 1.5
    trials, no trial loses frames however far the stream could have run."""
    protocol = mini_protocol(n_gestures=4, blocks=2, free_play_s=0.0)
    rig = make_rig(tmp_path, protocol, "P05", speed=0.0, capacity=128)
    n = round(protocol.trial_s * rig.device.nominal_rate_hz)
    assert n < 128 < 2 * n
    run_virtual_participant(rig, "P05")
    with SessionFile(rig.session.path) as s:
        assert len(s.journal.trials) == 8
        for t in s.journal.trials:
            assert t["status"] == "ok" and "dropped_frames" not in t["flags"], t
            seq = s.column("seq", t["start_sample"], t["end_sample"])
            assert np.array_equal(np.diff(seq), np.ones(n - 1))


def test_a_closed_session_lets_go_of_a_stream_that_waits_for_it(tmp_path: Path) -> None:
    """Waiting for a key, the runner holds a stream that waits for its readers a ring
    ahead of where a key may begin; closing the session mid-way must let it go (the
    engine belongs to the caller, who may keep streaming from it)."""
    protocol = mini_protocol(n_gestures=3, blocks=1, free_play_s=0.0)
    rig = make_rig(tmp_path, protocol, "P06", speed=0.0, capacity=128)
    try:
        start(rig)
        at_close = rig.engine.frames
        rig.session.close()
        assert rig.runner.state == "aborted"
        drive(rig, lambda: rig.engine.frames > at_close + 10 * 128)
    finally:
        rig.close()


def test_an_aborted_session_ends_its_file_where_it_was_aborted(tmp_path: Path) -> None:
    """An interrupted session's file ends at the frame of its abort, as a finished one
    ends with it: at speed 0 the simulator, let go once the session is over, runs on as
    fast as it can, and those frames were written until the file closed (ten minutes of
    idle after an interrupted collection's last trial, kept by a resume)."""
    protocol = mini_protocol(n_gestures=3, blocks=1, free_play_s=0.0)
    rig = make_rig(tmp_path, protocol, "P08", speed=0.0, capacity=128)
    try:
        start(rig)
        assert rig.runner.abort()
        at_abort = rig.engine.frames
        drive(rig, lambda: rig.engine.frames > at_abort + 10 * 128)  # the stream runs on
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        abort = [e for e in s.events if e["kind"] == "abort"]
        assert len(abort) == 1 and s.n_frames == abort[0]["frame"] + 1 <= at_abort


def test_virtual_participant_in_free_order_keeps_its_habit(tmp_path: Path) -> None:
    protocol = mini_protocol(n_gestures=4, blocks=2, order="free")
    rig = make_rig(tmp_path, protocol, "P03", speed=60.0)
    run_virtual_participant(rig, "P03")
    names = protocol.gesture_names
    with SessionFile(rig.session.path) as s:
        order = s.metadata["block_order"]
        assert s.metadata["trial_order"] == "free"
        assert any(o != names for o in order)  # so the habit differs from the prompts
        for b in (0, 1):  # free order: the protocol's order, whatever the block's was
            assert [t["gesture"] for t in s.journal.trials if t["block"] == b] == names
        for t in s.journal.trials:
            seq = s.column("seq", t["start_sample"], t["end_sample"])
            assert rig.device.gesture_at(int(seq[len(seq) // 2])) == t["gesture"]


@pytest.mark.parametrize("order", ["prompted", "free"])
def test_refused_keys_leave_a_visible_hint(tmp_path: Path, order: str) -> None:
    rig = make_rig(tmp_path, mini_protocol(order=order))
    r = rig.runner
    try:
        assert not r.key("p") and "not started" in r.snapshot().hint
        start(rig)
        first = r.snapshot().remaining[0]
        key = r.protocol.gesture_by_name(first).key
        do_trial(rig, first)
        snap = r.snapshot()
        assert [g.done for g in snap.gestures].count(True) == 1
        assert not r.key(key)
        hint = r.snapshot().hint
        nxt = r.snapshot().remaining[0]
        if order == "free":
            assert f"{first} ({key}) is already done in this block" in hint
            assert all(g in hint for g in r.snapshot().remaining)
        else:  # the refusal names the prompted gesture and its key
            nkey = r.protocol.gesture_by_name(nxt).key.upper()
            assert hint == (f"{first} is already done in this block. "
                            f"Next is {nxt} \u2013 press {nkey}")
        assert r.state == "waiting_for_key" and len(r.trials) == 1
        assert not r.key("z") and "'z' is not a gesture key" in r.snapshot().hint
        assert ("Next is" in r.snapshot().hint) == (order == "prompted")
        assert not r.key("Shift") and "not a gesture key" in r.snapshot().hint
        assert r.key(r.protocol.gesture_by_name(nxt).key.upper())  # case-insensitive
        assert r.snapshot().hint == "" and r.state == "trial_recording"
        assert not r.key(key) and "a trial is running" in r.snapshot().hint
    finally:
        rig.close()


def test_prompted_order_is_enforced_block_by_block(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol(n_gestures=3, blocks=2))
    r = rig.runner
    try:
        start(rig)
        orders = r.orders
        for b, order in enumerate(orders):
            for i, g in enumerate(order):
                snap = r.snapshot()
                assert snap.prompted == g and snap.remaining[0] == g
                assert [v.name for v in snap.gestures if v.prompted] == [g]
                k = r.protocol.gesture_by_name(g).key
                assert f"next is {g} \u2013 press {k.upper()}" in snap.message
                for other in order[i + 1:]:  # an upcoming gesture's key is refused
                    assert not r.key(r.protocol.gesture_by_name(other).key)
                    assert r.snapshot().hint == f"Next is {g} \u2013 press {k.upper()}"
                    assert r.state in ("block_start", "waiting_for_key")  # no trial began
                assert do_trial(rig, g)["gesture"] == g  # the prompted key starts it
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        assert s.metadata["trial_order"] == "prompted"
        assert s.metadata["protocol_spec"]["order"] == "prompted"
        for b in (0, 1):
            assert [t["gesture"] for t in s.journal.trials if t["block"] == b] == orders[b]


def test_free_order_takes_any_remaining_gesture(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol(n_gestures=3, blocks=1, order="free"))
    r = rig.runner
    try:
        start(rig)
        order = r.orders[0]
        assert r.snapshot().prompted is None
        assert not any(v.prompted for v in r.snapshot().gestures)
        assert "press the key of a gesture" in r.snapshot().message
        for g in reversed(order):  # against the stored order: every key is taken
            assert do_trial(rig, g)["gesture"] == g
        assert r.state == "finished"
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        assert s.metadata["trial_order"] == "free"
        assert [t["gesture"] for t in s.journal.trials] == order[::-1]


def test_redo_puts_the_gesture_back_and_reopens_a_finished_block(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol(n_gestures=2))
    r = rig.runner
    try:
        start(rig)
        g0 = r.snapshot().remaining[0]
        t0 = do_trial(rig, g0)
        assert r.redo_last("participant hesitated")
        assert r.snapshot().remaining[0] == g0 and "redo" in r.snapshot().hint
        assert r.snapshot().prompted == g0 and f"Next is {g0}" in r.snapshot().hint
        t1 = do_trial(rig, g0)
        assert t1["index"] == t0["index"] + 1 and t1["gesture"] == g0
        g1 = r.snapshot().remaining[0]
        do_trial(rig, g1)  # completes block 1; the runner moves on to block 2
        assert r.snapshot().block_number == 2
        assert r.redo_last()  # the last trial belongs to block 1: reopen it for g1
        snap = r.snapshot()
        assert (snap.block_number, snap.remaining, snap.prompted) == (1, (g1,), g1)
        b2_first = r.orders[1][0]
        assert not r.key(r.protocol.gesture_by_name(g0).key)
        assert r.snapshot().hint.endswith(f"Next is {g1} \u2013 press "
                                          f"{r.protocol.gesture_by_name(g1).key.upper()}")
        redo = do_trial(rig, g1)
        assert redo["block"] == 0
        assert r.snapshot().block_number == 2 and r.snapshot().prompted == b2_first
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        status = [(t["gesture"], t["status"], t["reason"]) for t in s.journal.trials]
    assert status[0] == (g0, "redone", "participant hesitated")
    assert status[1] == (g0, "ok", None)
    assert status[2][:2] == (g1, "redone") and status[3][:2] == (g1, "ok")


def test_discard_needs_a_reason_and_is_not_collected_again(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol())
    r = rig.runner
    try:
        start(rig)
        g0 = r.snapshot().remaining[0]
        t0 = do_trial(rig, g0)
        assert not r.discard(t0["index"], "  ") and "reason" in r.snapshot().hint
        assert not r.discard(99, "x") and "no trial 100" in r.snapshot().hint  # 1-based
        prompted = r.snapshot().prompted
        assert prompted == r.orders[0][1]
        assert r.discard(t0["index"], "participant sneezed")
        assert r.snapshot().prompted == prompted  # a discard does not change the prompt
        assert not r.discard(t0["index"], "again") and "already discarded" in r.snapshot().hint
        assert g0 not in r.snapshot().remaining
        assert r.snapshot().trials[0]["status"] == "discarded"
        assert r.add_note("sensor re-taped after trial 0")
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        assert s.journal.trials[0]["status"] == "discarded"
        assert s.journal.trials[0]["reason"] == "participant sneezed"
        assert "re-taped" in s.metadata["notes"]
        assert any(e["kind"] == "note" for e in s.events)


def test_flagged_trial_prompts_a_redo_and_can_hold(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol(), hold_flagged=True)
    r = rig.runner
    try:
        start(rig)
        g0 = r.snapshot().remaining[0]
        t0 = do_trial(rig, g0, perform=False)  # key pressed, nobody touched the sensor
        assert "no_contact" in t0["flags"] and t0["status"] == "ok"
        snap = r.snapshot()
        assert snap.state == "trial_review" and snap.can_continue
        assert f"Trial {t0['index'] + 1} ({g0}): no contact" in snap.redo_prompt  # 1-based
        g1 = snap.remaining[0]
        assert not r.key(r.protocol.gesture_by_name(g1).key)
        assert "checking" in r.snapshot().hint
        assert r.redo_last("no contact")
        assert r.state == "waiting_for_key" and r.snapshot().redo_prompt == ""
        t1 = do_trial(rig, g0)
        assert t1["flags"] == [] and r.state == "waiting_for_key"
    finally:
        rig.close()


def test_stuck_channel_and_off_centre_flags_reach_the_file(tmp_path: Path) -> None:
    # easy: the recalibrated people sometimes pat hard enough that the skin's slow
    # relaxation still loads the centre when the corner press starts, 0.8 s later
    rig = make_rig(tmp_path, mini_protocol(), sim={"fault": "stuck_channel",
                                                   "difficulty": "easy"})
    r = rig.runner
    try:
        start(rig)
        t0 = do_trial(rig, r.snapshot().remaining[0])
        assert "stuck_channel" in t0["flags"]
        frame = perform_soon(rig, press=(4.0, 4.0, 20.0))  # in the corner
        g = r.snapshot().remaining[0]
        assert r.key(r.protocol.gesture_by_name(g).key, at_frame=frame)
        drive(rig, lambda: len(r.trials) == 2)
        assert "off_centre" in r.trials[-1]["flags"]
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        assert "stuck_channel" in s.journal.trials[0]["flags"]
        assert "off_centre" in s.journal.trials[1]["flags"]


def test_practice_then_blocks_and_other_gesture_sets(tmp_path: Path) -> None:
    protocol = load_protocol("haart7").with_overrides(blocks=1, free_play_s=0.0,
                                                       practice_trials=2, trial_s=1.0)
    rig = make_rig(tmp_path, protocol, "P11", speed=80.0)
    seen_practice = []
    rig.runner.add_listener(lambda e: seen_practice.append(rig.runner.snapshot().practice)
                            if isinstance(e, TrialStarted) else None)
    run_virtual_participant(rig, "P11", seed=2)
    trials = rig.runner.trials
    assert seen_practice == [True, True] + [False] * 7
    assert [(t["block"], t["status"], t["reason"]) for t in trials[:2]] == \
        [(-1, "discarded", "practice")] * 2
    real = trials[2:]
    assert sorted(t["gesture"] for t in real) == sorted(protocol.gesture_names)
    for t in real:  # "no touch" is performed as nothing at all: exactly that one is flagged
        assert ("no_contact" in t["flags"]) == (t["gesture"] == "no touch"), t
    assert rig.runner.snapshot().trials_done == 7


def test_a_discarded_trial_collected_again_in_the_break_after_its_block(tmp_path: Path) -> None:
    """Discard-and-collect-again while the break after the block runs: the block is
    reopened for that gesture once the break ends, the next block follows, and the file
    passes its checks (the conftest runs `check` on it)."""
    protocol = mini_protocol(n_gestures=2, blocks=2, break_every=1, break_min_s=0.0)
    rig = make_rig(tmp_path, protocol, auto_continue=True)
    r = rig.runner
    try:
        start(rig)
        order = list(r.orders[0])
        first = do_trial(rig, order[0])
        do_trial(rig, order[1])
        drive(rig, lambda: r.state in ("break", "waiting_for_key"))
        assert r.can_collect_again(first["index"]) and r.block == 0
        assert r.discard(first["index"], "started late", again=True)
        drive(rig, lambda: r.state == "waiting_for_key")
        assert r.block == 0 and r.snapshot().prompted == order[0]  # block 1, once more
        again = do_trial(rig, order[0])
        assert again["block"] == 0 and again["reason"] == "collected again for trial 1"
        drive(rig, lambda: r.state == "waiting_for_key" and r.block == 1)
        assert not r.can_collect_again(first["index"])  # block 1 is over now
        assert not r.discard(again["index"], "x", again=True)
        assert "not in the block being collected" in r.snapshot().hint
        for g in r.orders[1]:
            do_trial(rig, g)
        drive(rig, lambda: r.state == "finished")
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        statuses = [(t["block"], t["gesture"], t["status"]) for t in s.journal.trials]
    assert statuses.count((0, order[0], "discarded")) == 1  # on record, with its reason
    assert statuses.count((0, order[0], "ok")) == 1 and len(statuses) == 5


def test_a_trial_discarded_and_collected_again_stays_discarded_on_record(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 47 item 9: "collect again" stored the discarded trial as *redone*, so
    `info` counted 0 discarded. It stays discarded with its reason, marked collected
    again; a session closed before the new trial collects the gesture on resume."""
    rig = make_rig(tmp_path, mini_protocol(n_gestures=2, blocks=1))
    r = rig.runner
    try:
        start(rig)
        order = list(r.orders[0])
        first = do_trial(rig, order[0])
        assert r.discard(first["index"], "started late", again=True)
        t = r.snapshot().trials[0]
        assert (t["status"], t["reason"], t["collected_again"]) == \
            ("discarded", "started late", True)
        assert r.snapshot().trials_done == 0  # replaced by a trial still to come
        assert not r.redo_last() and "already being collected again" in r.snapshot().hint
    finally:
        rig.close()  # closed before the new trial: the resume must collect it
    rig = make_rig(tmp_path, None, resume=rig.session.path)
    r = rig.runner
    try:
        assert r.snapshot().trials_done == 0
        start(rig)
        assert r.snapshot().prompted == order[0]
        for g in order:
            do_trial(rig, g)
        drive(rig, lambda: r.state == "finished")
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        trials = s.journal.trials
    assert [(t["gesture"], t["status"]) for t in trials] == \
        [(order[0], "discarded"), (order[0], "ok"), (order[1], "ok")]
    capsys.readouterr()
    assert main(["info", str(rig.session.path)]) == 0
    out = capsys.readouterr().out
    total = next(line for line in out.splitlines() if line.startswith("total"))
    assert total.split()[1:4] == ["2", "0", "1"]  # ok, redone, discarded


def test_the_redo_prompt_goes_with_its_trial_and_at_the_end(tmp_path: Path) -> None:
    """Issue 47 item 10: the amber "Trial N ... redo?" stayed after trial N was
    discarded, and on the Finished screen (where nothing can be redone)."""
    rig = make_rig(tmp_path, mini_protocol(n_gestures=2, blocks=1))
    r = rig.runner
    try:
        start(rig)
        order = list(r.orders[0])
        t0 = do_trial(rig, order[0], perform=False)  # nobody touched: flagged
        assert r.snapshot().redo_prompt.startswith(f"Trial {t0['index'] + 1} ")
        assert r.discard(t0["index"], "no contact")
        assert r.snapshot().redo_prompt == ""
        t1 = do_trial(rig, order[1], perform=False)  # the last trial, flagged again
        drive(rig, lambda: r.state == "finished")
        assert "no_contact" in t1["flags"] and r.snapshot().redo_prompt == ""
    finally:
        rig.close()
