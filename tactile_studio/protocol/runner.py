"""The collection runner: a Qt-free state machine over the device stream.

It is driven by ``tick()`` (a GUI timer, or the headless loop) and by input methods
(``key``, ``redo_last``, ``discard``, ``pause``...). Trials are sample-accurate: a key
starts a trial at the newest engine frame (or at an explicit frame), and the trial ends
exactly ``round(trial_s * nominal_rate)`` frames later, counted on the engine's stream,
never on a clock. The injected clock only times free play, the beep and breaks.
Every finished trial is written to the session file and flushed before the next one
can start, so a crash never loses a completed trial. API: docs/runner-api.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.protocol.progress import build_snapshot
from tactile_studio.protocol.protocol_file import Protocol
from tactile_studio.protocol.quality import QualitySettings, describe
from tactile_studio.protocol.snapshot import GestureView, RunnerSnapshot, State, participant_message
from tactile_studio.protocol.trial_record import measure_trial

Clock = Callable[[], float]
WRITE_TIMEOUT_S = 5.0  # if the recorder stalls this long, write the trial anyway (flagged)


class StreamClock:
    """Seconds of device time at the newest frame: breaks and free play then run at the
    stream's speed (a simulator ten times faster than real time makes them ten times
    shorter in wall time)."""

    def __init__(self, engine: AcquisitionEngine) -> None:
        self.engine = engine
        self._last = 0.0

    def __call__(self) -> float:
        chunk = self.engine.latest()
        if chunk is not None:
            self._last = max(self._last, float(chunk.device_time[0]))
        return self._last


class CollectionRunner:
    """Runs one participant through a protocol's blocks (see the module docstring)."""

    def __init__(self, protocol: Protocol, engine: AcquisitionEngine, recorder: Any,
                 participant: str, orders: list[list[str]], *, practice: list[str] | None = None,
                 beeper: Any = None, clock: Clock | None = None, auto_continue: bool = True,
                 hold_flagged: bool = False, previous_trials: list[dict[str, Any]] | None = None
                 ) -> None:
        self.protocol, self.engine, self.recorder = protocol, engine, recorder
        self.writer = recorder.writer
        self.participant = participant
        self.orders = [list(o) for o in orders]
        self.clock: Clock = clock or time.monotonic
        self.auto_continue, self.hold_flagged = auto_continue, hold_flagged
        self._beeper = beeper
        self.rate = float(engine.device.nominal_rate_hz)
        self.trial_frames = max(1, round(protocol.trial_s * self.rate))
        self.quality = QualitySettings(min_contact_fraction=protocol.min_contact_fraction,
                                       centre_fraction=protocol.centre_fraction)
        n = len(protocol.gestures)
        practice = list(practice or [])
        self._rounds: list[tuple[int, list[str]]] = [
            (-1, practice[i:i + n]) for i in range(0, len(practice), n)]
        self._rounds += [(b, order) for b, order in enumerate(self.orders)]
        self._done: list[set[str]] = [set() for _ in self._rounds]
        self._round = 0
        self.trials: list[dict[str, Any]] = []
        self.notes: list[str] = []
        self.state = State.SETUP
        self.hint = ""
        self.redo_prompt = ""
        self.beeps = 0
        self.free_play_s = protocol.free_play_s
        self._listeners: list[Callable[[dict[str, Any]], None]] = []
        self._start_requested = False
        self._current: dict[str, Any] | None = None
        self._pending: dict[str, Any] | None = None
        self._pending_since = 0.0
        self._phase_until = 0.0          # free play end / beep end / break minimum end
        self._paused_from: str | None = None
        self._paused_at = 0.0
        self._pause_pending = self._break_pending = False
        self._breaks_taken: set[int] = set()
        self._min_start = 0
        self._trial_starts: list[float] = []
        self._restore(previous_trials or [])

    # ---- restoring a resumed session ---------------------------------------------------
    def _restore(self, trials: list[dict[str, Any]]) -> None:
        if not trials:
            return
        self.trials = [dict(t) for t in trials]
        self.free_play_s = 0.0  # the participant already had it
        round_of = {b: i for i, (b, _) in enumerate(self._rounds) if b >= 0}
        for i, (b, gestures) in enumerate(self._rounds):
            if b < 0:
                self._done[i] = set(gestures)  # practice is not repeated on resume
        for t in self.trials:
            if t.get("status") != "redone" and int(t["block"]) in round_of:
                self._done[round_of[int(t["block"])]].add(t["gesture"])
        self._round = next((i for i in range(len(self._rounds)) if self._remaining(i)),
                           len(self._rounds) - 1)
        self._breaks_taken = {b for b, _ in self._rounds if 0 <= b < self._rounds[self._round][0]}

    # ---- listeners ---------------------------------------------------------------------
    def add_listener(self, fn: Callable[[dict[str, Any]], None]) -> None:
        self._listeners.append(fn)

    def _emit(self, kind: str, **data: Any) -> None:
        event = {"kind": kind, **data}
        for fn in list(self._listeners):
            fn(event)

    def _set_state(self, state: str) -> None:
        if state != self.state:
            self.state = state
            self._emit("state", state=state)

    def _refuse(self, hint: str) -> bool:
        self.hint = hint
        self._emit("hint", text=hint)
        return False

    def _log(self, kind: str, **detail: Any) -> None:
        self.writer.add_event(kind, **detail)

    # ---- block bookkeeping ---------------------------------------------------------------
    @property
    def block(self) -> int:
        return self._rounds[self._round][0]

    def _remaining(self, i: int | None = None) -> list[str]:
        i = self._round if i is None else i
        return [g for g in self._rounds[i][1] if g not in self._done[i]]

    def break_after(self, block: int) -> bool:
        """True if a scheduled break follows the completion of ``block`` (0-based)."""
        k = self.protocol.break_every
        return (k > 0 and block >= 0 and (block + 1) % k == 0 and block + 1 < len(self.orders)
                and block not in self._breaks_taken)

    def upcoming(self, n: int = 2) -> list[tuple[int, str]]:
        """The next ``n`` (block, gesture) pairs in the planned order, the running trial
        excluded (what a virtual participant plans its performances from)."""
        out: list[tuple[int, str]] = []
        skip = self._current["gesture"] if self._current else None
        for i in range(self._round, len(self._rounds)):
            for g in self._remaining(i):
                if i == self._round and g == skip:
                    continue
                out.append((self._rounds[i][0], g))
                if len(out) >= n:
                    return out
        return out

    # ---- inputs --------------------------------------------------------------------------
    def start(self) -> bool:
        """Leave setup: free play, practice, then block 1 (once the baseline is ready)."""
        if self.state != State.SETUP:
            return self._refuse("the session has already started")
        self._start_requested = True
        self.tick()
        return True

    def key(self, k: str, at_frame: int | None = None) -> bool:
        """The participant's key. Starts a trial of a remaining gesture of the block."""
        if self.state not in State.KEY_STATES:
            return self._refuse(self._why_no_key())
        if self.state == State.REVIEW:
            if self._held():
                return self._refuse("the experimenter is checking the last trial")
            self._after_trial()  # a pending pause or break, or the next block, comes first
            if self.state not in State.KEY_STATES:
                return self._refuse(self._why_no_key())
        gesture = self.protocol.gesture_by_key(k) if isinstance(k, str) and len(k) == 1 else None
        if gesture is None:
            return self._refuse(f"'{k}' is not a gesture key")
        if gesture.name not in self._rounds[self._round][1]:
            return self._refuse(f"{gesture.name} ({gesture.key}) is not part of this practice round")
        if gesture.name in self._done[self._round]:
            left = ", ".join(f"{g} ({self.protocol.gesture_by_name(g).key})"
                             for g in self._remaining())
            return self._refuse(f"{gesture.name} ({gesture.key}) is already done in this block; "
                                f"remaining: {left}")
        newest = self.engine.frames - 1
        if newest < 0:
            return self._refuse("no data from the sensor yet")
        start = newest if at_frame is None else int(at_frame)
        if start > newest or start < self._min_start:
            raise ValueError(f"trial start frame {start} outside {self._min_start}..{newest}")
        self._begin_trial(gesture.name, gesture.key, start)
        return True

    def proceed(self) -> bool:
        """The experimenter's Continue: ends free play, ends a break after its minimum,
        accepts a held flagged trial, or starts the session."""
        if self.state == State.SETUP:
            return self.start()
        if self.state == State.FREE_PLAY:
            self._after_free_play()
            return True
        if self.state == State.BREAK:
            left = self._phase_until - self.clock()
            if left > 0:
                return self._refuse(f"the break has {left:.0f} s of its minimum left")
            self._end_break()
            return True
        if self.state == State.REVIEW:
            self._after_trial()
            return True
        return self._refuse(f"nothing to continue in state {self.state}")

    def redo_last(self, reason: str | None = None) -> bool:
        """Mark the last trial redone and put its gesture back into its block."""
        if self.state in (State.SETUP, State.FREE_PLAY, State.RECORDING, State.ABORTED):
            return self._refuse("no finished trial to redo now")
        if self._pending is not None:
            return self._refuse("wait until the trial is saved")
        if not self.trials:
            return self._refuse("no trial to redo yet")
        last = self.trials[-1]
        if last["status"] == "redone":
            return self._refuse(f"trial {last['index']} is already marked redone")
        self._update_trial(last, status="redone", reason=reason or None)
        i = next(i for i in range(min(self._round, len(self._rounds) - 1), -1, -1)
                 if self._rounds[i][0] == last["block"] and last["gesture"] in self._done[i])
        self._done[i].discard(last["gesture"])
        self._round = i
        self.redo_prompt = ""
        self.hint = f"redo: {last['gesture']} ({last['key']})"
        if self.state in (State.BLOCK_START, State.WAITING, State.REVIEW, State.FINISHED):
            self._set_state(State.WAITING)
        elif self.state == State.PAUSED and self._paused_from in (State.BLOCK_START, State.REVIEW):
            self._paused_from = State.WAITING
        return True

    def discard(self, index: int, reason: str) -> bool:
        """Mark trial ``index`` discarded with ``reason``; it is not collected again."""
        if not reason or not reason.strip():
            return self._refuse("give a reason to discard a trial")
        trial = next((t for t in self.trials if t["index"] == index), None)
        if trial is None:
            return self._refuse(f"no trial {index}")
        if trial["status"] != "ok":
            return self._refuse(f"trial {index} is already {trial['status']}")
        self._update_trial(trial, status="discarded", reason=reason.strip())
        return True

    def pause(self) -> bool:
        if self.state in State.DONE or self.state in (State.PAUSED, State.SETUP):
            return self._refuse(f"cannot pause in state {self.state}")
        if self.state in (State.RECORDING, State.TRIAL_END):
            self._pause_pending = True
            self.hint = "pausing after this trial"
            return True
        self._enter_pause(self.state)
        return True

    def resume(self) -> bool:
        if self.state != State.PAUSED:
            if self._pause_pending:
                self._pause_pending = False
                return True
            return self._refuse("not paused")
        paused_for = self.clock() - self._paused_at
        self._phase_until += paused_for
        self._log("resume", paused_s=round(paused_for, 3))
        target, self._paused_from = self._paused_from or State.WAITING, None
        self.hint = ""
        self._set_state(target)
        return True

    def skip_to_break(self) -> bool:
        """Take a break now (after a running trial); the block goes on after it."""
        if self.state in (State.RECORDING, State.TRIAL_END):
            self._break_pending = True
            self.hint = "break after this trial"
            return True
        if self.state not in State.KEY_STATES:
            return self._refuse(f"cannot start a break in state {self.state}")
        self._enter_break(scheduled=False)
        return True

    def add_note(self, text: str) -> bool:
        text = " ".join(str(text).split())
        if not text:
            return self._refuse("empty note")
        self.notes.append(text)
        last = self.trials[-1]["index"] if self.trials else None
        self._log("note", text=text, after_trial=last)
        self.writer.update_metadata(notes="\n".join(self.notes))
        self.writer.flush()
        self._emit("note", text=text)
        return True

    def abort(self) -> bool:
        """Stop the session; a running trial is dropped, finished ones stay in the file."""
        if self.state in State.DONE:
            return self._refuse(f"the session is already {self.state}")
        if self._pending is not None:
            self._write_pending(force=True)
        if self._current is not None:
            self._log("trial_dropped", gesture=self._current["gesture"], reason="aborted")
            self._current = None
        self._log("abort", trials=len(self.trials))
        self.writer.flush()
        self._set_state(State.ABORTED)
        return True

    # ---- time ----------------------------------------------------------------------------
    def tick(self) -> None:
        """Advance whatever is due now; cheap, call it often."""
        s = self.state
        if s == State.SETUP:
            if self._start_requested:
                if self.engine.baseline is None:
                    self.hint = "waiting for the sensor baseline..."
                else:
                    self.hint = ""
                    self._start_session()
        elif s == State.FREE_PLAY:
            if self.clock() >= self._phase_until:
                self._after_free_play()
        elif s == State.BLOCK_START:
            self._set_state(State.WAITING)
        elif s == State.RECORDING:
            self._check_recording()
        elif s == State.TRIAL_END:
            if self._pending is not None:
                self._write_pending()
            if self._pending is None and self.clock() >= self._phase_until:
                self._set_state(State.REVIEW)
                if not self._held():
                    self._after_trial()
        elif s == State.REVIEW:
            if not self._held():
                self._after_trial()
        elif s == State.BREAK:
            if self.auto_continue and self.clock() >= self._phase_until:
                self._end_break()

    def _held(self) -> bool:
        return bool(self.hold_flagged and self.trials and self.trials[-1]["flags"]
                    and self.trials[-1]["status"] == "ok")

    def _why_no_key(self) -> str:
        return {
            State.SETUP: "the session has not started",
            State.FREE_PLAY: "free play: no keys needed yet",
            State.RECORDING: "a trial is running",
            State.TRIAL_END: "wait for the beep to finish",
            State.BREAK: "break: wait for the experimenter",
            State.PAUSED: "paused",
            State.FINISHED: "the session is complete",
            State.ABORTED: "the session was stopped",
        }.get(self.state, f"not now ({self.state})")

    # ---- transitions ---------------------------------------------------------------------
    def _start_session(self) -> None:
        self._log("session_start", blocks=len(self.orders), trial_frames=self.trial_frames)
        if not self._remaining():
            self._finish()
        elif self.free_play_s > 0:
            self._phase_until = self.clock() + self.free_play_s
            self._log("free_play", seconds=self.free_play_s)
            self._set_state(State.FREE_PLAY)
        else:
            self._enter_block()

    def _after_free_play(self) -> None:
        self._enter_block()

    def _enter_block(self) -> None:
        self._log("block_start", block=self.block)
        self._emit("block", block=self.block)
        self._set_state(State.BLOCK_START)

    def _begin_trial(self, gesture: str, key: str, start: int) -> None:
        self.hint = ""
        self.redo_prompt = ""
        self._current = {
            "gesture": gesture, "key": key, "block": self.block, "start": start,
            "end": start + self.trial_frames, "dropped0": self.recorder.dropped,
            "event_cursor": self.engine.event_count,
            "row0": start - self.recorder.start_frame - self.recorder.dropped,
        }
        self._trial_starts.append(self.clock())
        self._set_state(State.RECORDING)
        self._emit("trial_started", gesture=gesture, key=key, start_frame=start)
        self._check_recording()

    def _check_recording(self) -> None:
        cur = self._current
        assert cur is not None
        if self.engine.frames >= cur["end"]:
            self._end_trial()
        elif not self.engine.running:
            self._current = None
            self._log("trial_dropped", gesture=cur["gesture"], reason="sensor stopped")
            self._refuse("the sensor stopped during the trial; it was not recorded")
            self._set_state(State.WAITING)

    def _end_trial(self) -> None:
        cur, self._current = self._current, None
        assert cur is not None
        self._beep()
        n = self.trial_frames
        m = measure_trial(self.engine, cur["start"], n, self.rate, self.quality,
                          cur["event_cursor"], self.recorder.dropped - cur["dropped0"])
        practice = cur["block"] < 0
        self._pending = {
            "index": self._next_index(), "block": cur["block"], "gesture": cur["gesture"],
            "key": cur["key"], "start_sample": cur["row0"], "end_sample": cur["row0"] + n,
            "start_time": m.start_time, "end_time": m.end_time,
            "status": "discarded" if practice else "ok",
            "reason": "practice" if practice else None, "flags": m.flags,
        }
        self._pending_since = time.monotonic()  # wall time: the recorder runs on it
        self._done[self._round].add(cur["gesture"])
        self._min_start = cur["end"]
        self._phase_until = self.clock() + self.protocol.beep_s
        self._set_state(State.TRIAL_END)
        self._write_pending()

    def _next_index(self) -> int:
        return max((int(t["index"]) for t in self.trials), default=-1) + 1

    def _write_pending(self, force: bool = False) -> None:
        rec = self._pending
        assert rec is not None
        behind = self.writer.n_frames < rec["end_sample"]
        if behind and not force:
            if time.monotonic() - self._pending_since < WRITE_TIMEOUT_S:
                return  # the recorder has not written the trial's frames yet
        if behind and "dropped_frames" not in rec["flags"]:
            rec["flags"] = [*rec["flags"], "dropped_frames"]
        self.writer.add_trial(rec)
        self.writer.flush()
        self.trials.append(dict(rec))
        self._pending = None
        if rec["flags"] and rec["status"] == "ok":
            self.redo_prompt = (f"Trial {rec['index']} ({rec['gesture']}): "
                                f"{describe(rec['flags'])} - redo?")
        self._emit("trial_ended", trial=dict(rec))

    def _after_trial(self) -> None:
        if self._remaining():
            nxt = State.WAITING
            if self._break_pending:
                self._break_pending = False
                self._enter_break(scheduled=False)
                nxt = State.BREAK
        elif self._round + 1 >= len(self._rounds):
            self._finish()
            return
        elif self._break_pending or self.break_after(self.block):
            self._break_pending = False
            self._enter_break(scheduled=self.break_after(self.block))
            nxt = State.BREAK
        else:
            self._round += 1
            self._enter_block()
            nxt = State.BLOCK_START
        if nxt == State.WAITING:
            self._set_state(State.WAITING)
        if self._pause_pending:
            self._pause_pending = False
            self._enter_pause(self.state)

    def _enter_break(self, scheduled: bool) -> None:
        if scheduled:
            self._breaks_taken.add(self.block)
        self._phase_until = self.clock() + self.protocol.break_min_s
        self._log("break_start", after_block=self.block, scheduled=scheduled,
                  min_s=self.protocol.break_min_s)
        self.writer.flush()
        self._set_state(State.BREAK)

    def _end_break(self) -> None:
        self._log("break_end")
        if not self._remaining():
            if self._round + 1 >= len(self._rounds):
                self._finish()
                return
            self._round += 1
        self._enter_block()

    def _enter_pause(self, state: str) -> None:
        self._paused_from = state
        self._paused_at = self.clock()
        self._log("pause", state=state)
        self.hint = ""
        self._set_state(State.PAUSED)

    def _finish(self) -> None:
        self._log("session_end", trials=len(self.trials))
        self.writer.flush()
        self._set_state(State.FINISHED)

    def _beep(self) -> None:
        hz, length = self.protocol.beep_hz, self.protocol.beep_s
        self.beeps += 1
        if self._beeper is not None:
            play = getattr(self._beeper, "play", self._beeper)
            play(hz, length)
        self._emit("beep", frequency_hz=hz, length_s=length)

    def _update_trial(self, trial: dict[str, Any], **changes: Any) -> None:
        trial.update(changes)
        self.writer.update_trial(trial["index"], **changes)
        self.writer.flush()
        self._emit("trial_updated", trial=dict(trial))

    # ---- the snapshot --------------------------------------------------------------------
    def snapshot(self) -> RunnerSnapshot:
        """Everything the participant screen and the experimenter console show."""
        return build_snapshot(self)

    # read-only views used by build_snapshot
    @property
    def current_trial(self) -> dict[str, Any] | None:
        return self._current

    @property
    def pending_trial(self) -> dict[str, Any] | None:
        return self._pending

    @property
    def paused_state(self) -> str | None:
        return self._paused_from

    @property
    def paused_at(self) -> float:
        return self._paused_at

    @property
    def held(self) -> bool:
        """True while a flagged trial waits for the experimenter (``hold_flagged``)."""
        return self.state == State.REVIEW and self._held()

    @property
    def phase_until(self) -> float:
        return self._phase_until

    @property
    def trial_starts(self) -> list[float]:
        return self._trial_starts

    @property
    def round_gestures(self) -> list[str]:
        return list(self._rounds[self._round][1])

    def round_done(self) -> set[str]:
        return set(self._done[self._round])

    @property
    def practice(self) -> bool:
        return self.block < 0


__all__ = ["CollectionRunner", "GestureView", "RunnerSnapshot", "State", "StreamClock",
           "participant_message"]
