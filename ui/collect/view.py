"""From the runner's snapshot to what the collection screens show (wording only, no Qt).

The runner decides everything (states, which gestures are done, countdowns, hints);
this module only words it for the participant and formats rows of the trial log, so
the painting code and the console stay free of protocol logic.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from tactile_studio.protocol.flag_summary import trial_reason
from tactile_studio.storage.format.trials import TrialRecord
from tactile_studio.ui.collect.participant import Card, ParticipantView

_WAIT_TITLE = "Press the key of the gesture you will do next"
_WAIT_SUB = "Then start it at once and keep going until the beep."


def _note(g: Any, prompted: str | None, state: str) -> str:
    """Under a compact card's name in prompted order: next / now / upcoming ("" free)."""
    if prompted is None and not (state == "trial_recording" and g.current):
        return ""
    if g.done:
        return "done"
    if g.current:
        return "now"
    return "next" if g.name == prompted else "upcoming"


def _block_label(snap: Any) -> str:
    if snap.state in ("setup", "free_play"):
        return ""
    if snap.practice:
        return "Practice"
    if snap.blocks_total:
        return f"Block {snap.block_number} of {snap.blocks_total}"
    return ""


def _steps(seconds: float | None, per_s: int) -> float | None:
    """Countdowns in display steps, so an unchanged view is not repainted every tick."""
    return None if seconds is None else round(seconds * per_s) / per_s


def participant_view(snap: Any, protocol: Any) -> ParticipantView:
    """The participant screen for a runner snapshot (``protocol`` gives countdown totals)."""
    state = snap.state
    prompted = snap.prompted
    cards = [Card(g.key, g.name, g.definition, bool(g.done), bool(g.current), g.image,
                  _note(g, prompted, state)) for g in snap.gestures]
    v = ParticipantView(mode=state, block_label=_block_label(snap), cards=cards,
                        done_in_block=sum(c.done for c in cards), n_in_block=len(cards),
                        hint=snap.hint or "")
    title, sub = "", ""
    if state == "setup":
        title, sub = "Welcome", "The session will start in a moment."
        v.footer, v.hint = snap.protocol_title, ""  # setup hints are for the experimenter
    elif state == "free_play":
        title = "Free play"
        sub = "Touch the sensor any way you like to get to know it."
        v.countdown_s, v.countdown_total_s = (_steps(snap.free_play_remaining_s, 10),
                                              protocol.free_play_s)
    elif state == "block_start":
        title = "Practice" if snap.practice else f"Block {snap.block_number}"
        sub = "Get ready"
    elif state == "waiting_for_key" and prompted:
        v.mode = "waiting"
        g = next(g for g in snap.gestures if g.name == prompted)
        v.prompt = Card(g.key, g.name, g.definition, False, True, g.image)
        # the strip below the prompt: key, name and done/next/upcoming (the image and
        # the definition are on the large card)
        v.cards = [replace(c, active=c.name == prompted, image=None) for c in cards]
        title = f"Next: {g.name}"
        sub = f"Press {g.key.upper()} as you start it, then keep going until the beep."
    elif state == "waiting_for_key":
        v.mode = "waiting"
        title, sub = _WAIT_TITLE, _WAIT_SUB
    elif state == "trial_recording":
        v.mode = "recording"
        title, sub = snap.current_gesture or "", "Keep going until the beep"
        v.countdown_s, v.countdown_total_s = _steps(snap.trial_remaining_s, 20), protocol.trial_s
    elif state in ("trial_end", "trial_review"):
        v.mode = "trial_end" if state == "trial_end" else "review"
        title = f"\u2713 {snap.current_gesture}" if snap.current_gesture else "\u2713"
        sub = "Done. You can lift your hand." if state == "trial_end" else "Please wait a moment."
    elif state == "break":
        title = "Break"
        left = snap.break_remaining_s
        if left is not None and left > 0:
            sub = "Relax your hand. The session continues after the break."
            v.countdown_s, v.countdown_total_s = _steps(left, 10), protocol.break_min_s
        else:
            sub = "Whenever you are ready, the session continues."
    elif state == "paused":
        title, sub = "Paused", "Please wait for the experimenter."
    elif state == "finished":
        title, sub = "Finished \u2014 thank you!", "You can take your hand off the sensor."
    elif state == "aborted":
        title, sub = "Session ended", "Thank you."
    v.title, v.subtitle = title, sub
    if state in ("paused", "break", "finished", "aborted", "setup", "free_play"):
        v.cards = []
    return v


_PAUSED_IN = {"free_play": "during free play", "block_start": "at the start of a block",
              "waiting_for_key": "while waiting for the participant's key",
              "trial_review": "while reviewing the last trial", "break": "during the break"}


def state_label(snap: Any) -> str:
    """One line for the experimenter: state and where the session is."""
    names = {"setup": "Ready to start", "free_play": "Free play", "block_start": "Block start",
             "waiting_for_key": "Waiting for the participant's key",
             "trial_recording": "Recording", "trial_end": "Trial end (beep)",
             "trial_review": "Review the last trial", "break": "Break",
             "paused": "Paused", "finished": "Finished", "aborted": "Aborted"}
    text = names.get(snap.state, snap.state)
    prompted = snap.prompted
    nxt = f"{prompted} ({snap.prompted_key.upper()})" if prompted else ""
    if snap.state == "waiting_for_key" and nxt:
        text = f"Waiting for the participant: next is {nxt}"
    elif snap.state == "waiting_for_key" and snap.order == "free":
        text = "Waiting for the participant's key (free order)"
    if snap.state == "trial_recording" and snap.current_gesture:
        text += f": {snap.current_gesture}"
        if nxt:
            text += f" \u00b7 then {nxt}"
    if snap.state == "paused" and snap.paused_state:
        text += f" {_PAUSED_IN.get(snap.paused_state, '')}".rstrip()
        text += " — Resume (Ctrl+P) to go on"
    if snap.state == "trial_review" and snap.can_continue:
        text = "Flagged trial: Redo (Ctrl+Z) or Keep (Ctrl+K / Continue)"
    if snap.state == "break" and snap.can_continue:
        text += " \u2014 minimum over, Continue when ready"
    return text


def format_eta(seconds: float | None) -> str:
    if seconds is None or seconds != seconds:
        return "\u2013"
    s = int(round(max(0.0, seconds)))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


def progress_text(snap: Any) -> str:
    """Trials, block (1-based; "practice" before block 1) and ETA, for the console."""
    where = ("practice" if snap.practice
             else f"block {snap.block_number} of {snap.blocks_total}")
    return (f"{snap.trials_done} of {snap.trials_total} trials \u00b7 {where} \u00b7 "
            f"{snap.order} order \u00b7 ETA {format_eta(snap.eta_s)}")


def trial_row(trial: dict[str, Any]) -> tuple[str, str, str, str, str]:
    """Cells of one trial-log row: number (1-based, as blocks), block, gesture,
    status, flags."""
    t = TrialRecord.from_dict(trial)
    status = t.status.value
    why = [t.reason] if t.reason else []  # an ok trial's says which discarded one it replaces
    if t.collected_again:
        why.append("collected again")
    if why:
        status += f" ({'; '.join(why)})"
    return (str(t.index + 1), "practice" if t.block == -1 else str(t.block + 1), t.gesture, status,
            trial_reason(t))
