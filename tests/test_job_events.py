"""The typed job events: every kind crosses a process boundary (pickle) and a JSON-ish
wire dict and comes back equal; a reader meeting an unknown kind or field fails loudly."""

import math
import multiprocessing as mp
import pickle

import pytest

from tactile_studio.learn.experiments import job_events as je

EXAMPLES = [
    je.Progress(0.25, "reading data"),
    je.Epoch.of(0, 1, 3, "P02", {"epoch": 2, "train_loss": 0.5, "train_acc": 0.75,
                                 "val_loss": 0.6, "val_acc": 0.7, "seconds": 1.5,
                                 "lr": 0.001}),
    je.Fold(round=0, fold=1, n_folds=3, fold_name="P02", accuracy=0.8, trial_accuracy=0.9,
            cut=True, resumed=False),
    je.Plan(total=12, done=2),
    je.Task(id="cnn1d-all-r0-P01", model="cnn1d", channels="all", done=3, total=12,
            accuracy=0.8, seconds=2.5, row={"model": "cnn1d", "channels": "all"}),
    je.Done(out="/tmp/run", accuracy=0.8, headline="80.0%", shots="",
            curve=[{"k": 1, "accuracy": 0.5, "trial_accuracy": 0.6}]),
    je.Done(out="/tmp/sweep", rows=[{"model": "rf", "trial_accuracy": 0.7}]),
    je.Cancelled("sweep cancelled: 3 of 12 tasks finished", rows=[{"model": "rf"}]),
    je.Failed("no trials with status ok"),
]


@pytest.mark.parametrize("event", EXAMPLES, ids=lambda e: type(e).__name__)
def test_every_event_round_trips(event):
    wire = je.to_wire(event)
    assert wire["type"] == event.type and isinstance(wire, dict)
    assert je.from_wire(wire) == event
    assert pickle.loads(pickle.dumps(event)) == event
    assert je.from_wire(event) is event


def test_events_cross_a_spawned_process_queue():
    q = mp.get_context("spawn").Queue()
    for e in EXAMPLES:
        q.put(e)
    assert [q.get(timeout=10) for _ in EXAMPLES] == EXAMPLES


def test_epoch_keeps_a_learners_extra_fields_and_picks_its_accuracy():
    e = EXAMPLES[1]
    assert e.epoch == 2 and e.extra == {"lr": 0.001} and e.accuracy == 0.7
    no_val = je.Epoch.of(0, 0, 3, "P01", {"epoch": 1, "train_acc": 0.6, "val_acc": math.nan})
    assert no_val.accuracy == 0.6


def test_final_events_and_unknown_wire_data():
    assert [je.is_final(e) for e in EXAMPLES] == [False] * 5 + [True] * 4
    assert [type(e).type for e in EXAMPLES[-3:]] == ["done", "cancelled", "error"]
    with pytest.raises(ValueError, match="not a job event"):
        je.from_wire({"type": "bogus"})
    with pytest.raises(TypeError):
        je.from_wire({"type": "plan", "total": 1, "done": 0, "typo": 3})
