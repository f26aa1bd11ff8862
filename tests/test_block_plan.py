"""BlockPlan: the runner's per-round bookkeeping (pure data, no device; budget < 1 s)."""

from __future__ import annotations

from tactile_studio.protocol.block_plan import BlockPlan

ORDERS = [["a", "b", "c"], ["c", "a", "b"], ["b", "c", "a"]]


def test_practice_rounds_come_first_and_are_cut_to_the_gesture_count():
    plan = BlockPlan(ORDERS, ["a", "b", "c", "a"], per_round=3, break_every=0)
    assert [b for b, _ in plan.rounds] == [-1, -1, 0, 1, 2]
    assert plan.rounds[1][1] == ["a"] and plan.block == -1
    plan.mark_done("a")
    assert plan.remaining() == ["b", "c"] and plan.is_done("a") and not plan.is_done("b")


def test_upcoming_follows_the_order_across_rounds_and_skips_the_running_gesture():
    plan = BlockPlan(ORDERS, [], per_round=3, break_every=0)
    plan.mark_done("a")
    assert plan.upcoming(3, skip="b") == [(0, "c"), (1, "c"), (1, "a")]
    assert len(plan.upcoming(1 << 30)) == 8


def test_reopen_returns_to_the_latest_round_holding_the_gesture():
    plan = BlockPlan(ORDERS, [], per_round=3, break_every=0)
    for g in ORDERS[0]:
        plan.mark_done(g)
    plan.advance()
    plan.mark_done("c")
    plan.reopen(0, "b")
    assert plan.index == 0 and plan.remaining() == ["b"]
    assert plan.remaining(1) == ["a", "b"]  # the later block keeps its progress


def test_scheduled_breaks_skip_the_last_block_and_happen_once():
    plan = BlockPlan(ORDERS, [], per_round=3, break_every=1)
    assert [plan.break_after(b) for b in (-1, 0, 1, 2)] == [False, True, True, False]
    plan.take_break(0)
    assert not plan.break_after(0) and plan.break_after(1)
    assert not BlockPlan(ORDERS, [], per_round=3, break_every=0).break_after(0)


def test_restore_skips_practice_ignores_redone_trials_and_counts_past_breaks():
    plan = BlockPlan(ORDERS, ["a", "b"], per_round=3, break_every=1)
    trials = [{"block": 0, "gesture": g, "status": "ok"} for g in "abc"]
    trials += [{"block": 1, "gesture": "c", "status": "redone"},
               {"block": 1, "gesture": "a", "status": "discarded"}]
    plan.restore(trials)
    assert plan.block == 1 and plan.remaining() == ["c", "b"]
    assert plan.remaining(0) == [] and plan.breaks_taken == {0}
    assert not plan.is_last_round()


def test_the_prompted_gesture_is_the_first_left_and_a_redone_one_comes_first():
    plan = BlockPlan(ORDERS, [], per_round=3, break_every=0)
    assert plan.prompted == "a"
    plan.mark_done("a")
    assert plan.prompted == "b"
    # a resumed file from free order may have gaps: the first one left is prompted
    gappy = BlockPlan(ORDERS, [], per_round=3, break_every=0)
    gappy.restore([{"block": 0, "gesture": "b", "status": "ok"}])
    assert gappy.prompted == "a" and gappy.remaining() == ["a", "c"]
    gappy.mark_done("a")
    gappy.mark_done("c")
    gappy.reopen(0, "c")  # redo of the last trial (c): prompted before nothing else
    assert gappy.prompted == "c"
    gappy.mark_done("c")
    assert gappy.prompted is None and gappy.redo_first == {}
    full = BlockPlan(ORDERS, [], per_round=3, break_every=0)
    full.mark_done("a")
    full.mark_done("c")  # free order: a, c done, b left
    full.reopen(0, "c")
    assert full.remaining() == ["c", "b"] and full.prompted == "c"
    assert [r for _, r in full.rounds_ahead()][:2] == [["c", "b"], ["c", "a", "b"]]
