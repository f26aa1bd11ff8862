"""Breaks, pauses, free play and resume: the runner's clock-driven logic, with a manual
clock (exact countdowns) on the real engine, simulated sensor and session file."""

from __future__ import annotations

from pathlib import Path

import pytest
from collect_fixtures import (
    ManualClock,
    do_trial,
    drive,
    make_rig,
    mini_protocol,
    perform_soon,
    start,
)

from tactile_studio.errors import UserError
from tactile_studio.storage.format.session_file import SessionFile


def _finish_block(rig) -> None:
    for g in list(rig.runner.snapshot().remaining):
        do_trial(rig, g)


def test_break_after_every_k_blocks_with_minimum(tmp_path: Path) -> None:
    clock = ManualClock()
    protocol = mini_protocol(n_gestures=2, blocks=4, break_every=2, break_min_s=30.0)
    rig = make_rig(tmp_path, protocol, clock=clock, auto_continue=False)
    r = rig.runner
    try:
        start(rig)
        seen_breaks = []
        for block in range(4):
            assert r.snapshot().block_number == block + 1
            _finish_block(rig)
            if r.state == "break":
                seen_breaks.append(block + 1)
                snap = r.snapshot()
                assert snap.break_remaining_s == 30.0 and not snap.can_continue
                assert not r.key(r.protocol.gestures[0].key)
                assert "break" in r.snapshot().hint
                clock.advance(20.0)
                r.tick()
                assert r.state == "break" and r.snapshot().break_remaining_s == pytest.approx(10.0)
                assert not r.proceed() and "10 s" in r.snapshot().hint
                clock.advance(10.0)
                r.tick()
                # waits for the experimenter
                assert r.state == "break" and r.snapshot().can_continue
                assert r.proceed()
                drive(rig, lambda: r.state == "waiting_for_key")
        assert seen_breaks == [2]  # after block 2; none after the last block
        assert r.state == "finished"
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        kinds = [e["kind"] for e in s.events]
        assert kinds.count("break_start") == 1 and kinds.count("break_end") == 1
        assert [t["block"] for t in s.journal.trials] == [0, 0, 1, 1, 2, 2, 3, 3]


def test_auto_continue_after_the_minimum(tmp_path: Path) -> None:
    clock = ManualClock()
    protocol = mini_protocol(n_gestures=2, blocks=2, break_every=1, break_min_s=5.0)
    rig = make_rig(tmp_path, protocol, clock=clock)
    r = rig.runner
    try:
        start(rig)
        _finish_block(rig)
        assert r.state == "break"
        eta_in_break = r.snapshot().eta_s
        assert eta_in_break >= 5.0
        clock.advance(5.0)
        drive(rig, lambda: r.state == "waiting_for_key")
        assert r.snapshot().block_number == 2
    finally:
        rig.close()


def test_pause_freezes_countdowns_and_blocks_keys(tmp_path: Path) -> None:
    clock = ManualClock()
    protocol = mini_protocol(n_gestures=2, blocks=2, break_every=1, break_min_s=10.0,
                             free_play_s=8.0)
    rig = make_rig(tmp_path, protocol, clock=clock)
    r = rig.runner
    try:
        r.start()
        drive(rig, lambda: r.state == "free_play")
        clock.advance(3.0)
        assert r.pause() and r.state == "paused"
        clock.advance(100.0)
        r.tick()
        snap = r.snapshot()
        assert snap.state == "paused" and snap.paused_state == "free_play"
        assert snap.free_play_remaining_s == pytest.approx(5.0)
        assert not r.key("p") and r.snapshot().hint == "paused"
        assert r.resume() and r.state == "free_play"
        assert r.snapshot().free_play_remaining_s == pytest.approx(5.0)
        assert r.proceed()  # the experimenter ends free play early
        drive(rig, lambda: r.state == "waiting_for_key")
        # a pause asked for during a trial takes effect when the trial ends
        g = r.snapshot().remaining[0]
        frame = perform_soon(rig, g)
        assert r.key(r.protocol.gesture_by_name(g).key, at_frame=frame)
        assert r.pause() and r.state == "trial_recording"
        drive(rig, lambda: len(r.trials) == 1)
        clock.advance(1.0)  # the beep's length passes
        drive(rig, lambda: r.state == "paused")
        assert len(r.trials) == 1 and r.trials[0]["status"] == "ok"
        assert r.snapshot().paused_state == "waiting_for_key"
        assert r.resume() and r.state == "waiting_for_key"
        do_trial(rig, r.snapshot().remaining[0])
        assert r.state == "break"
        clock.advance(4.0)
        r.pause()
        clock.advance(50.0)
        r.resume()
        r.tick()
        assert r.state == "break" and r.snapshot().break_remaining_s == pytest.approx(6.0)
        assert not r.resume() and "not paused" in r.snapshot().hint
    finally:
        rig.close()
    with SessionFile(rig.session.path) as s:
        kinds = [e["kind"] for e in s.events]
        assert kinds.count("pause") == 3 and kinds.count("resume") == 3


def test_skip_to_break_then_the_block_goes_on(tmp_path: Path) -> None:
    clock = ManualClock()
    protocol = mini_protocol(n_gestures=3, blocks=2, break_every=0, break_min_s=2.0)
    rig = make_rig(tmp_path, protocol, clock=clock)
    r = rig.runner
    try:
        start(rig)
        assert r.pause() and r.state == "paused"  # pause/resume in waiting is harmless
        assert r.resume() and r.state == "waiting_for_key"
        do_trial(rig, r.snapshot().remaining[0])
        left = r.snapshot().remaining
        assert r.skip_to_break() and r.state == "break"
        assert r.snapshot().break_remaining_s == pytest.approx(2.0)
        clock.advance(2.0)
        drive(rig, lambda: r.state == "waiting_for_key")
        snap = r.snapshot()
        assert snap.block_number == 1 and snap.remaining == left
        assert r.skip_to_break() and r.state == "break"  # a break can be taken again
    finally:
        rig.close()


def test_abort_keeps_finished_trials_and_close_mid_block_resumes(tmp_path: Path) -> None:
    protocol = mini_protocol(n_gestures=3, blocks=2)
    rig = make_rig(tmp_path, protocol)
    r = rig.runner
    start(rig)
    order = r.orders
    done = [do_trial(rig, g)["gesture"] for g in order[0][:2]]
    assert done == order[0][:2]
    frame = perform_soon(rig)
    assert r.key(r.protocol.gesture_by_name(order[0][2]).key, at_frame=frame)
    rig.close()  # the window closes mid-trial: the running trial is dropped
    path = rig.session.path
    with SessionFile(path) as s:
        assert s.closed_cleanly and len(s.journal.trials) == 2
        n_old = s.n_frames
        old_trials = s.journal.trials
    rig2 = make_rig(tmp_path, protocol, resume=path)  # the same sensor (sim-0)
    r2 = rig2.runner
    try:
        assert rig2.session.backup.exists() and rig2.session.path == path
        assert r2.orders == order and r2.snapshot().trials_done == 2
        assert r2.free_play_s == 0
        r2.start()
        drive(rig2, lambda: r2.state == "waiting_for_key")
        assert r2.snapshot().remaining == (order[0][2],)
        assert r2.snapshot().prompted == order[0][2]  # the stored order goes on
        assert not r2.key(r2.protocol.gesture_by_name(order[0][0]).key)
        assert f"Next is {order[0][2]}" in r2.snapshot().hint
        for g in [order[0][2], *order[1]]:
            do_trial(rig2, g)
        assert r2.state == "finished"
    finally:
        rig2.close()
    with SessionFile(path) as s:
        assert s.journal.trials[:2] == old_trials
        assert [t["gesture"] for t in s.journal.trials] == order[0] + order[1]
        assert all(t["start_sample"] >= n_old for t in s.journal.trials[2:])
        assert s.n_frames > n_old
        assert any(e["kind"] == "resume" for e in s.events)
        assert s.metadata["resumes"] == 1
    with SessionFile(rig2.session.backup) as b:
        assert b.journal.trials == old_trials
    with pytest.raises(UserError, match="complete"):
        make_rig(tmp_path, protocol, resume=path)
