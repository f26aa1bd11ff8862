"""Building the runner's snapshot: countdowns, progress and the ETA."""

from __future__ import annotations

from collections.abc import Callable
from statistics import median
from typing import Any, Protocol

from tactile_studio.devices.frame_stream import FrameStream
from tactile_studio.protocol.snapshot import GestureView, RunnerSnapshot, State, participant_message
from tactile_studio.storage.format.protocol_file import CollectionProtocol
from tactile_studio.storage.format.trials import TrialRecord, trials_done


class RunnerView(Protocol):
    """What a snapshot is built from: the runner's read-only side (the runner satisfies
    it; this module never imports the runner, so they do not depend on each other)."""

    protocol: CollectionProtocol
    engine: FrameStream
    clock: Callable[[], float]
    state: str
    participant: str
    orders: list[list[str]]
    records: list[TrialRecord]
    notes: list[str]
    hint: str
    redo_prompt: str
    beeps: int
    rate: float
    trial_frames: int

    @property
    def block(self) -> int: ...
    @property
    def practice(self) -> bool: ...
    @property
    def current_trial(self) -> dict[str, Any] | None: ...
    @property
    def paused_state(self) -> str | None: ...
    @property
    def paused_at(self) -> float: ...
    @property
    def held(self) -> bool: ...
    @property
    def phase_until(self) -> float: ...
    @property
    def trial_starts(self) -> list[float]: ...
    @property
    def round_gestures(self) -> list[str]: ...
    def round_done(self) -> set[str]: ...
    def round_remaining(self) -> list[str]: ...
    def break_after(self, block: int) -> bool: ...

DEFAULT_OVERHEAD_S = 2.5  # key, beep and reading the next gesture, before any is measured


def seconds_per_trial(runner: RunnerView) -> float:
    """Median time between recent trial starts (the participant's pace), else a guess."""
    starts = runner.trial_starts[-21:]
    steps = [b - a for a, b in zip(starts, starts[1:]) if b > a]
    steps = [s for s in steps if s < 10 * (runner.protocol.trial_s + DEFAULT_OVERHEAD_S)]
    return median(steps) if steps else runner.protocol.trial_s + DEFAULT_OVERHEAD_S


def build_snapshot(r: RunnerView) -> RunnerSnapshot:
    p = r.protocol
    now = r.clock()
    state = r.state
    cur = r.current_trial
    shown_state = r.paused_state if state == State.PAUSED and r.paused_state else state
    trial_left = trial_fraction = None
    current = None
    if cur is not None:
        current = cur["gesture"]
        left = max(0, cur["end"] - r.engine.frames)
        trial_left = left / r.rate
        trial_fraction = 1.0 - left / r.trial_frames
    elif state in (State.TRIAL_END, State.REVIEW) and r.records:
        current = r.records[-1].gesture
    phase_left = max(0.0, r.phase_until - (r.paused_at if state == State.PAUSED else now))
    free_left = phase_left if shown_state == State.FREE_PLAY else None
    break_left = phase_left if shown_state == State.BREAK else None
    can_continue = (state == State.FREE_PLAY or state == State.SETUP
                    or (state == State.BREAK and phase_left <= 0)
                    or r.held)
    done = r.round_done()
    remaining = tuple(r.round_remaining())
    prompted = None
    if p.order == "prompted" and state not in State.DONE and state != State.SETUP:
        running = cur["gesture"] if cur is not None else None
        prompted = next((n for n in remaining if n != running), None)
    gestures = tuple(
        GestureView(g.name, g.key, g.definition, p.image_file(g), g.name in done,
                    g.name == current, g.name == prompted)
        for g in (p.gesture_by_name(n) for n in r.round_gestures))
    total = sum(len(o) for o in r.orders)
    done_n = trials_done(r.records)
    breaks_left = sum(1 for b in range(max(r.block, 0), len(r.orders)) if r.break_after(b))
    eta = (total - done_n) * seconds_per_trial(r) + breaks_left * p.break_min_s
    if shown_state in (State.FREE_PLAY, State.BREAK):
        eta += phase_left
    if state in State.DONE:
        eta = 0.0
    prompted_key = p.gesture_by_name(prompted).key if prompted else None
    fields = {"practice": r.practice, "block_number": r.block + 1,
              "blocks_total": len(r.orders), "current_gesture": current,
              "prompted": prompted, "prompted_key": prompted_key}
    trials = tuple(t.to_dict() for t in r.records)
    return RunnerSnapshot(
        state=state, paused_state=r.paused_state, participant=r.participant,
        protocol=p.name, protocol_title=p.title, block=r.block,
        block_number=max(r.block + 1, 0), blocks_total=len(r.orders), practice=r.practice,
        gestures=gestures, remaining=remaining, current_gesture=current,
        trial_remaining_s=trial_left, trial_fraction=trial_fraction,
        free_play_remaining_s=free_left, break_remaining_s=break_left,
        can_continue=can_continue, hint=r.hint,
        message=participant_message(state, fields), redo_prompt=r.redo_prompt,
        trials=trials, last_trial=trials[-1] if trials else None,
        trials_done=done_n, trials_total=total,
        progress=done_n / total if total else 1.0, eta_s=round(eta, 1),
        notes=tuple(r.notes), beeps=r.beeps, order=p.order, prompted=prompted,
        prompted_key=prompted_key)
