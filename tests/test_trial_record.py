"""TrialRecord and TrialStatus: the file's trial dicts round-trip unchanged, older or
imported records (missing fields, extra columns) read, and progress counts one way."""

from __future__ import annotations

import pytest

from tactile_studio.storage.trials import TrialRecord, TrialStatus, records, trials_done

FULL = {"index": 3, "block": 1, "gesture": "Twist", "key": "t", "start_sample": 120,
        "end_sample": 420, "start_time": 1.2, "end_time": 4.2, "status": "redone",
        "reason": "slipped", "flags": ["no_contact", "gap"]}


def test_a_file_record_round_trips_in_key_order() -> None:
    t = TrialRecord.from_dict(FULL)
    assert t.status is TrialStatus.REDONE and t.flags == ("no_contact", "gap")
    out = t.to_dict()
    assert out == FULL and list(out) == list(FULL)
    assert type(out["status"]) is str  # plain JSON in the journal


def test_imported_columns_are_kept_and_missing_fields_default() -> None:
    t = TrialRecord.from_dict({"index": 0, "block": 0, "gesture": "pat", "start_sample": 0,
                               "end_sample": 10, "variant": "normal"})
    assert t.ok and t.reason is None and t.flags == () and not t.flagged
    assert t.to_dict()["variant"] == "normal" and t.to_dict()["status"] == "ok"


def test_flagged_and_counted() -> None:
    ok = TrialRecord.from_dict({**FULL, "status": "ok"})
    assert ok.flagged and ok.counts
    assert not TrialRecord.from_dict(FULL).counts  # redone
    practice = TrialRecord.from_dict({**FULL, "block": -1, "status": "discarded"})
    assert practice.practice and not practice.counts and not practice.flagged
    assert ok.with_changes(status="discarded").status is TrialStatus.DISCARDED


def test_trials_done_counts_each_block_gesture_once() -> None:
    trials = [
        {**FULL, "index": 0, "block": -1, "gesture": "Poke", "status": "discarded"},
        {**FULL, "index": 1, "block": 0, "gesture": "Poke", "status": "redone"},
        {**FULL, "index": 2, "block": 0, "gesture": "Poke", "status": "ok"},
        {**FULL, "index": 3, "block": 0, "gesture": "Twist", "status": "discarded"},
        {**FULL, "index": 4, "block": 1, "gesture": "Poke", "status": "redone"},
    ]
    assert trials_done(trials) == 2
    assert trials_done(records(trials)) == 2
    assert trials_done(trials[:2]) == 0


def test_an_unknown_status_is_refused() -> None:
    with pytest.raises(ValueError):
        TrialRecord.from_dict({**FULL, "status": "maybe"})
