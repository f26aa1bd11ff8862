"""TrialRecord and TrialStatus: the file's trial dicts round-trip unchanged, older or
imported records (missing fields, extra columns) read, and progress counts one way."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tactile_studio.storage.format.trials import (
    TrialRecord,
    TrialStatus,
    label_order,
    records,
    trials_done,
)

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


def test_usable_and_uid_are_the_records() -> None:
    ok = TrialRecord.from_dict({"index": 7, "block": 0, "gesture": "Poke", "start_sample": 0,
                                "end_sample": 5})  # an older record: no status means ok
    assert ok.usable and ok.uid("P01/a.h5") == "P01/a.h5#7"
    assert ok.with_changes(flags=["no_contact"]).usable  # flags do not take it out
    assert not ok.with_changes(status="redone").usable
    assert not ok.with_changes(status="discarded").usable
    assert not TrialRecord.from_dict({**FULL, "status": "ok", "gesture": None}).usable
    assert TrialRecord.from_dict({**FULL, "gesture": None}).gesture == ""


def test_the_label_order_is_the_protocols_then_the_others_sorted() -> None:
    metas = [{"gestures": ["Twist", {"name": "Poke"}, "", None]}, {"gestures": ["Stroke"]},
             {}]
    seen = ["Zap", "Poke", "Abc", "Stroke"]
    assert label_order(metas, seen) == ["Twist", "Poke", "Stroke", "Abc", "Zap"]
    # a dataset's classes: only gestures some trial names
    assert label_order(metas, seen, keep_unseen=False) == ["Poke", "Stroke", "Abc", "Zap"]
    assert label_order([], []) == []


def test_usable_is_not_recoded_outside_the_record() -> None:
    """The rule "a usable trial" (status ok, a gesture) lives in TrialRecord.usable/.ok:
    no module reads a trial's status with the file's default again."""
    root = Path(__file__).resolve().parents[1]
    recoded = re.compile(r"""\.get\(\s*["']status["']\s*,\s*(["']ok["']|TrialStatus\.OK)""")
    found = [f"{p.relative_to(root)}:{n}"
             for pkg in ("tactile_studio", "ui", "plugins") for p in (root / pkg).rglob("*.py")
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if recoded.search(line)]
    assert found == []
