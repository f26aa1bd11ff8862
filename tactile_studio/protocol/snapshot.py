"""What the collection screens show: a frozen, cheap snapshot of the runner.

Screens read a :class:`RunnerSnapshot` after each ``tick()``; they never reach into the
runner's internals. See docs/runner-api.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any


class State(StrEnum):
    """The runner's states (strings, so screens can compare and print them)."""

    SETUP = "setup"
    FREE_PLAY = "free_play"
    BLOCK_START = "block_start"
    WAITING = "waiting_for_key"
    RECORDING = "trial_recording"
    TRIAL_END = "trial_end"
    REVIEW = "trial_review"
    BREAK = "break"
    PAUSED = "paused"
    FINISHED = "finished"
    ABORTED = "aborted"


# groups of states (set after the class: inside an Enum they would become members)
State.ALL = tuple(State)
State.KEY_STATES = (State.BLOCK_START, State.WAITING, State.REVIEW)  # a key may start a trial
State.DONE = (State.FINISHED, State.ABORTED)


@dataclass(frozen=True)
class GestureView:
    """One gesture of the current block as the participant screen lists it."""

    name: str
    key: str
    definition: str
    image: str | None
    done: bool
    current: bool  # being recorded now (or just recorded)
    prompted: bool = False  # the next gesture to do (order = "prompted" only)


@dataclass(frozen=True)
class RunnerSnapshot:
    state: str
    paused_state: str | None
    participant: str
    protocol: str
    protocol_title: str
    block: int
    block_number: int
    blocks_total: int
    practice: bool
    gestures: tuple[GestureView, ...]
    remaining: tuple[str, ...]
    current_gesture: str | None
    trial_remaining_s: float | None
    trial_fraction: float | None
    free_play_remaining_s: float | None
    break_remaining_s: float | None
    can_continue: bool
    hint: str
    message: str
    redo_prompt: str
    trials: tuple[dict[str, Any], ...]
    last_trial: dict[str, Any] | None
    trials_done: int
    trials_total: int
    progress: float
    eta_s: float
    notes: tuple[str, ...] = field(default_factory=tuple)
    beeps: int = 0
    order: str = "prompted"          # the protocol's order: "prompted" or "free"
    prompted: str | None = None      # the gesture whose key starts the next trial
    prompted_key: str | None = None


def participant_message(state: str, snap: dict[str, Any]) -> str:
    """The instruction line of the participant screen for ``state``."""
    if state == State.SETUP:
        return "Please wait: the session is about to start."
    if state == State.FREE_PLAY:
        return "Free play: touch the sensor any way you like."
    if state in (State.BLOCK_START, State.WAITING, State.REVIEW):
        what = ("Practice" if snap["practice"]
                else f"Block {snap['block_number']} of {snap['blocks_total']}")
        if snap.get("prompted"):
            return (f"{what}: next is {snap['prompted']} \u2013 press "
                    f"{snap['prompted_key'].upper()} as you start it.")
        return f"{what}: press the key of a gesture as you start it."
    if state == State.RECORDING:
        return f"Perform: {snap['current_gesture']}"
    if state == State.TRIAL_END:
        return "Done."
    if state == State.BREAK:
        return "Break: relax, the experimenter will continue."
    if state == State.PAUSED:
        return "Paused: please wait."
    if state == State.FINISHED:
        return "Thank you! The session is complete."
    return "The session has stopped."
