"""The console's side of the trial check: a flagged trial stands out in the log with its
reason, an amber banner offers Redo and Keep (buttons and keys), each block ends with a
one-line summary per gesture, the participant screen never shows a flag, and the page
does not move as flags come and go.

Real engine (the simulator, 8x real time), real session file, real widgets (pytest-qt,
offscreen). A trial is flagged the way a participant gets it wrong without a model: the
key pressed, nothing touched (``no_contact``).
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
from console_helpers import fill_setup
from PySide6.QtCore import QRect, Qt
from PySide6.QtWidgets import QWidget
from test_ui_collect import (
    WAIT_MS,
    do_trial,
    env,  # noqa: F401 (the fixture)
    make_console,
    open_mini,
    snap,
)
from test_ui_collect_keys import press

from tactile_studio.protocol.flag_summary import block_summary, trial_reason
from tactile_studio.protocol.snapshot import State
from tactile_studio.protocol.trial_check import verdict
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.ui.collect.console import CollectConsole
from tactile_studio.ui.collect.log import FLAGGED_BG
from tactile_studio.ui.collect.qc_setup import QcChoice

FLAG_WORDS = ("flag", "no contact", "redo", "looks like", "keep")


def places(console: CollectConsole) -> dict[str, QRect]:
    """Where the experimenter's eyes and hands go, in window coordinates (the trials box
    as a whole: the block summary takes its room from the table inside it)."""
    widgets: dict[str, QWidget] = {"heatmap": console.heatmap, "mirror": console.mirror,
                                   "trials box": console.log.parentWidget(),
                                   "state": console.state,
                                   **{f"button {k}": b for k, b in console.buttons.items()}}
    out = {name: QRect(w.mapTo(console, w.rect().topLeft()), w.size())
           for name, w in widgets.items()}
    top = console.log.mapTo(console, console.log.rect().topLeft())
    out["log top"] = QRect(top.x(), top.y(), console.log.width(), 0)
    return out


def participant_text(console: CollectConsole) -> str:
    """Everything the participant screen says, lower case."""
    v = console.participant.view
    cards = [c for c in (*v.cards, v.prompt) if c is not None]
    words = [v.title, v.subtitle, v.hint, v.footer, v.block_label,
             *(f"{c.name} {c.definition} {c.note}" for c in cards)]
    return " ".join(str(w or "") for w in words).lower()


def first_prompted(console: CollectConsole):
    s = snap(console)
    return next(g for g in s.gestures if g.name == s.prompted)


def test_a_flagged_trial_is_redone_or_kept_from_the_banner_and_summed_up_per_block(
        qtbot, env):  # noqa: F811
    proto, out = env
    console = make_console(qtbot)
    open_mini(qtbot, console, proto, out, blocks=2)
    qtbot.waitUntil(lambda: console.hint_label.isHidden(), timeout=WAIT_MS)
    before = places(console)
    assert not console.redo_banner.isVisible()
    g = first_prompted(console)

    # 1. nothing touched: flagged and held; the banner says why, the log highlights it
    trial = do_trial(qtbot, console, g.name, g.key, perform=False, accept_flagged=False)
    assert trial["flags"] == ["no_contact"]
    assert snap(console).state == State.REVIEW and console.redo_banner.isVisible()
    assert console.redo_banner.text() == f"Trial 1 ({g.name}): no contact - redo?"
    assert console.log.item(0, 4).text() == "no contact"
    assert console.log.item(0, 4).background().color() == FLAGGED_BG
    assert places(console) == before  # the banner took its reserved room, nothing moved
    text = participant_text(console)
    assert not [w for w in FLAG_WORDS if w in text], text  # the participant sees no flag
    assert console.mirror.view == console.participant.view

    # 2. the banner's Redo: the gesture is collected again in this block
    qtbot.mouseClick(console.redo_banner.redo, Qt.MouseButton.LeftButton)
    s = snap(console)
    assert s.trials[0]["status"] == "redone" and s.prompted == g.name
    assert s.trials[0]["decision"] == "redo"
    assert not console.redo_banner.isVisible() and console.log.flagged_rows() == []
    assert places(console) == before

    # 3. flagged again; Keep (Ctrl+K): the trial stays, with its flag, and the block goes on
    do_trial(qtbot, console, g.name, g.key, perform=False, accept_flagged=False)
    assert console.redo_banner.isVisible() and "Trial 2" in console.redo_banner.text()
    press(qtbot, console, Qt.Key.Key_K)
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    kept = snap(console).trials[1]
    assert kept["status"] == "ok" and kept["flags"] == ["no_contact"]
    assert kept["decision"] == "keep"
    assert not console.redo_banner.isVisible() and console.log.flagged_rows() == [1]
    assert places(console) == before
    assert console.block_summary.isHidden()  # block 1 is not over yet

    # 4. the block's other gestures, performed: then its summary, one line per gesture
    for other in [x for x in snap(console).gestures if not x.done]:
        assert do_trial(qtbot, console, other.name, other.key)["flags"] == []
    qtbot.waitUntil(lambda: snap(console).state == State.BREAK, timeout=WAIT_MS)
    console.tick()
    assert console.block_summary.isVisible()
    assert console.block_summary.text() == f"After block 1: {g.name}: 2 of 2 no contact"
    assert not [w for w in FLAG_WORDS if w in participant_text(console)]
    assert places(console) == before
    path = console.session.path
    console.close()
    with SessionFile(path) as sess:
        trials = sess.journal.trials
    assert [t["status"] for t in trials[:2]] == ["redone", "ok"]
    assert trials[1]["flags"] == ["no_contact"]
    assert [t.get("decision") for t in trials[:2]] == ["redo", "keep"]


def test_block_summary_counts_every_performance_and_names_what_a_model_saw():
    def t(i: int, block: int, gesture: str, flags: tuple = (), **extra) -> dict:
        return {"index": i, "block": block, "gesture": gesture, "status": "ok",
                "flags": list(flags), **extra}
    wide = {"model": "m", "p_prompted": 0.07, "rank": 4, "flagged": True,
            "top": [["Wide Pinch", 0.61], ["Poke", 0.2], ["Tickle", 0.1]],
            "reason": "looks like Wide Pinch (0.61); Twist 0.07"}
    trials = [t(0, -1, "Twist", ("no_contact",)),  # practice: left out
              t(1, 0, "Twist", ("model_mismatch",), check=wide),
              t(2, 0, "Poke"),
              t(3, 1, "Twist", ("model_mismatch", "off_centre"), check=wide),
              t(4, 1, "Poke"), t(5, 1, "Twist"), t(6, 2, "Twist", ("no_contact",))]
    trials[3]["status"] = "redone"  # a redo is one more performance, still counted
    assert block_summary(trials, 0) == ["Twist: 1 of 1 looks like Wide Pinch"]
    assert block_summary(trials, 1) == [
        "Twist: 2 of 3 look like Wide Pinch, 1 of 3 contact off the sensor centre"]
    assert block_summary(trials[2:3], 0) == []
    assert trial_reason(trials[3]) == ("looks like Wide Pinch (0.61); Twist 0.07, "
                                       "contact off the sensor centre")
    assert trial_reason(trials[2]) == ""


class SlowModel:
    """A TrialChecker of the test's own that answers only when the test lets it (as a
    model that takes its time): every trial 'looks like nothing'. ``timed_out`` says
    whether it had to give up waiting (it was asked on the thread that should let it go)."""

    def __init__(self, gestures: list[str]) -> None:
        self.known = frozenset(gestures)
        self.go = threading.Event()
        self.asked = threading.Event()
        self.timed_out = False

    def describe(self) -> dict:
        return {"model": "slow", "version": "1", "top_k": 1, "threshold": 0.5}

    def check(self, layout, raw, baseline, rate_hz, prompted):  # noqa: ANN001, ANN201
        self.asked.set()
        self.timed_out = not self.go.wait(timeout=5)
        labels = [*sorted(self.known), "nothing"]
        probs = np.full(len(labels), 0.0)
        probs[labels.index(prompted)], probs[-1] = 0.1, 0.9
        return verdict(labels, probs, prompted, top_k=1, threshold=0.5)


def test_the_console_stays_live_while_the_model_thinks(qtbot, env):  # noqa: F811
    proto, out = env
    console = make_console(qtbot)
    s = console.setup
    fill_setup(qtbot, console, proto, out, "P03", blocks=1)
    model = SlowModel(console.setup.current_protocol().gesture_names)
    assert console.start_session(replace(s.choice(), qc=QcChoice(ready=model)))
    qtbot.mouseClick(console.buttons["primary"], Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    g = first_prompted(console)
    console.engine.device.perform(g.name, duration_s=1.0)
    qtbot.keyClick(console.participant, g.key)
    qtbot.waitUntil(lambda: len(snap(console).trials) == 1 and model.asked.is_set(),
                    timeout=WAIT_MS)
    # the model is thinking: the trial is on record, the console goes on ticking, and the
    # held session takes no key until the verdict is in
    ticks = console._ticks
    qtbot.waitUntil(lambda: console._ticks > ticks + 3, timeout=WAIT_MS)
    assert "model_mismatch" not in snap(console).trials[0]["flags"]
    assert snap(console).state == State.REVIEW
    nxt = next(x for x in snap(console).gestures if not x.done)
    qtbot.keyClick(console.participant, nxt.key)
    assert len(snap(console).trials) == 1 and console.runner.held
    model.go.set()
    qtbot.waitUntil(lambda: console.redo_banner.isVisible(), timeout=WAIT_MS)
    assert not model.timed_out
    assert console.redo_banner.text() == \
        f"Trial 1 ({g.name}): looks like nothing (0.90); {g.name} 0.10 - redo?"
    assert console.log.item(0, 4).text() == f"looks like nothing (0.90); {g.name} 0.10"
    trial = snap(console).trials[0]
    assert trial["check"]["model"] == "slow" and "model_mismatch" in trial["flags"]
    qtbot.mouseClick(console.redo_banner.keep, Qt.MouseButton.LeftButton)
    assert snap(console).trials[0]["decision"] == "keep"
    path = console.session.path
    console.close()
    with SessionFile(path) as sess:
        stored = sess.journal.trials[0]
    assert stored["check"]["flagged"] and stored["decision"] == "keep"
