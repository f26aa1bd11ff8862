"""The collection runner: a Qt-free state machine over the device stream.

It is driven by ``tick()`` (a GUI timer, or the headless loop) and by input methods
(``key``, ``redo_last``, ``discard``, ``pause``...; in :mod:`.runner_inputs`). Trials are
sample-accurate: a key (the prompted gesture's; with the protocol's ``order = "free"``
any gesture of the block not done yet) starts a trial at the newest engine frame (or at
an explicit frame), and the trial ends exactly ``round(trial_s * nominal_rate)`` frames later,
counted on the engine's stream, never on a clock. The injected clock (:mod:`.clock`) only
times free play, the beep and breaks. Which gestures are left in which block is kept by
:class:`~tactile_studio.protocol.block_plan.BlockPlan`. Every finished trial is written
to the session file and flushed before the next one can start, so a crash never loses a
completed trial. API: docs/runner-api.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from tactile_studio.devices.frame_stream import FrameStream, hold_frames
from tactile_studio.errors import UserError
from tactile_studio.protocol.background_check import (
    PERSONALISE_WAIT_S,
    WAIT_S,
    BackgroundCheck,
)
from tactile_studio.protocol.block_plan import BlockPlan
from tactile_studio.protocol.clock import Clock, StreamClock
from tactile_studio.protocol.progress import build_snapshot
from tactile_studio.protocol.quality import describe, quality_settings
from tactile_studio.protocol.runner_events import (
    Beep,
    BlockStarted,
    CheckPersonalised,
    Refused,
    RunnerEvent,
    RunnerListener,
    StateChanged,
    TrialEnded,
    TrialStarted,
    TrialUpdated,
)
from tactile_studio.protocol.runner_inputs import RunnerInputs
from tactile_studio.protocol.snapshot import GestureView, RunnerSnapshot, State, participant_message
from tactile_studio.protocol.trial_check import MISMATCH_FLAG, TrialChecker, TrialVerdict
from tactile_studio.protocol.trial_record import TrialMeasure, measure_trial
from tactile_studio.storage.format.protocol_file import CollectionProtocol
from tactile_studio.storage.format.trials import TrialRecord, TrialStatus, records
from tactile_studio.storage.recording.recorder import Recorder


@dataclass(frozen=True)
class RunnerOptions:
    """How a collection runs, apart from what it collects: the ``beeper`` (None: silent)
    and ``clock`` (None: the monotonic clock), whether trials follow each other without
    a key (``auto_continue``), whether a flagged trial waits for the redo answer
    (``hold_flagged``), the model check of each finished trial (``trial_check``, None:
    off) and whether the first block's trials personalise it (``personalise_check``)."""

    beeper: Any = None
    clock: Clock | None = None
    auto_continue: bool = True
    hold_flagged: bool = False
    trial_check: TrialChecker | None = None
    personalise_check: bool = False


class TrialRunner(RunnerInputs):
    """Runs one participant through a protocol's blocks (see the module docstring)."""

    def __init__(self, protocol: CollectionProtocol, engine: FrameStream, recorder: Recorder,
                 participant: str, orders: list[list[str]], *, practice: list[str] | None = None,
                 previous_trials: list[dict[str, Any]] | None = None,
                 options: RunnerOptions = RunnerOptions()) -> None:
        beeper, clock, trial_check = options.beeper, options.clock, options.trial_check
        auto_continue, hold_flagged = options.auto_continue, options.hold_flagged
        personalise_check = options.personalise_check
        self.protocol, self.engine, self.recorder = protocol, engine, recorder
        self.participant = participant
        self.orders = [list(o) for o in orders]
        self.clock: Clock = clock or time.monotonic
        self.auto_continue, self.hold_flagged = auto_continue, hold_flagged
        self._beeper = beeper
        # the model check of each finished trial (protocol/trial_check.py), None: off;
        # a BackgroundCheck scores off this thread: (trial index, its future, since) of
        # each trial whose verdict has not joined it yet, oldest first
        self.trial_check = trial_check
        self._pending: list[tuple[int, Any, float]] = []
        # personalise the check with the first block's trials when it ends (a checker
        # with ``personalise``): their frames, kept until then, by trial index
        can = (trial_check.can_personalise if isinstance(trial_check, BackgroundCheck)
               else hasattr(trial_check, "personalise"))
        self._shots: dict[int, tuple[Any, Any, str]] | None = (
            {} if personalise_check and can else None)
        # a BackgroundCheck's personalisation underway
        self._personalising: Future[int] | None = None
        self._shots_block: int | None = None
        # a check that adapts to the participant (``adapts``): their trials' frames by
        # index, all of them handed to it when a block ends; its adaptations underway
        adapts = bool(getattr(trial_check, "adapts", False))
        self._own: dict[int, tuple[Any, Any, str]] | None = {} if adapts else None
        self._adapting: list[Future[tuple[int, str]]] = []
        self._adapted_on = 0
        self.rate = float(engine.nominal_rate_hz)
        self.trial_frames = max(1, round(protocol.trial_s * self.rate))
        self.quality = quality_settings(protocol)
        self._plan = BlockPlan(self.orders, list(practice or []), len(protocol.gestures),
                               protocol.break_every)
        self.records: list[TrialRecord] = []
        self.notes: list[str] = []
        self.state = State.SETUP
        self.hint = ""
        self._redo_for: int | None = None  # the flagged trial the redo prompt asks about
        self.beeps = 0
        self.free_play_s = protocol.free_play_s
        self._listeners: list[RunnerListener] = []
        self._start_requested = False
        self._current: dict[str, Any] | None = None
        self._release_hold: Callable[[], None] = lambda: None
        self._keys_from: int | None = None   # held for a key naming a frame from here on
        self._tick_frame = engine.frames
        self._at = 0  # the stream frame the runner is at: its events go there
        self._start_at: int | None = None   # the frame start() named (a virtual participant)
        self._phase_from = 0             # the frame free play or a break began
        self._lead = 2 * self.trial_frames
        self._hold(lambda: self._tick_frame, self._lead)
        self._phase_until = 0.0          # free play end / beep end / break minimum end
        self._paused_from: str | None = None
        self._paused_at = 0.0
        self._pause_pending = self._break_pending = False
        self._min_start = 0
        self._trial_starts: list[float] = []
        # (block, gesture) collected again after a discard -> the new trial's reason
        self._again_for: dict[tuple[int, str], str] = {}
        self._restore(previous_trials or [])

    # ---- restoring a resumed session ---------------------------------------------------
    def _restore(self, trials: list[dict[str, Any]]) -> None:
        if not trials:
            return
        self.records = records(trials)
        self.free_play_s = 0.0  # the participant already had it
        self._plan.restore(self.records)

    @property
    def trials(self) -> list[dict[str, Any]]:
        """The trials so far in the file's form (copies: changing them changes nothing)."""
        return [t.to_dict() for t in self.records]

    # ---- listeners ---------------------------------------------------------------------
    def add_listener(self, fn: RunnerListener) -> None:
        """Call ``fn(event)`` for every event (protocol/runner_events.py)."""
        self._listeners.append(fn)

    def _emit(self, event: RunnerEvent) -> None:
        for fn in list(self._listeners):
            fn(event)

    def _set_state(self, state: str) -> None:
        if state != self.state:
            self.state = state
            self._hold_for(state)
            self._emit(StateChanged(state))

    def _refuse(self, hint: str) -> bool:
        self.hint = hint
        self._emit(Refused(hint))
        return False

    def _log(self, kind: str, **detail: Any) -> None:
        """A runner event at the stream frame the runner is at (a trial's end, the tick
        that ended a timed phase), never where the recorder happens to be writing: a
        stream that runs ahead of the runner (the simulator at speed 0) or a recorder
        that lags behind it would put the event among the wrong trials."""
        self.recorder.add_event_at(max(self._at, self._min_start), kind, **detail)

    def _reach(self, frame: int) -> None:
        """The runner has acted at stream frame ``frame`` (a tick, an input)."""
        self._at = max(self._at, int(frame))

    def _newest(self, frames: int) -> int:
        """The newest frame of a stream that has delivered ``frames``: where a key
        pressed now starts its trial."""
        return max(0, frames - 1)

    # ---- block bookkeeping ---------------------------------------------------------------
    @property
    def block(self) -> int:
        return self._plan.block

    def break_after(self, block: int) -> bool:
        """True if a scheduled break follows the completion of ``block`` (0-based)."""
        return self._plan.break_after(block)

    def upcoming(self, n: int = 2) -> list[tuple[int, str]]:
        """The next ``n`` (block, gesture) pairs in the planned order, the running trial
        excluded (what a virtual participant plans its performances from)."""
        skip = self._current["gesture"] if self._current else None
        return self._plan.upcoming(n, skip)

    # ---- time ----------------------------------------------------------------------------
    def tick(self) -> None:
        """Advance whatever is due now; cheap, call it often."""
        self._tick_frame = self.engine.frames
        self.take_verdict()
        self._take_personalised()
        self._take_adapted()
        s = self.state
        if s == State.SETUP:
            if self._start_requested:
                if self.engine.baseline is None:
                    self.hint = "waiting for the sensor baseline..."
                else:
                    self.hint = ""
                    self._start_session()
        elif s == State.FREE_PLAY:
            if self._phase_over(self.free_play_s):
                self._reach(self._phase_end(self.free_play_s))
                self._after_free_play()
        elif s == State.BLOCK_START:
            self._set_state(State.WAITING)
        elif s == State.RECORDING:
            self._check_recording()
        elif s == State.TRIAL_END:
            if self._phase_over(self.protocol.beep_s):
                self._set_state(State.REVIEW)
                if not self._held():
                    self._after_trial()
        elif s == State.REVIEW:
            if not self._held():
                self._after_trial()
        elif s == State.BREAK:
            if self.auto_continue and self._phase_over(self.protocol.break_min_s):
                self._reach(self._phase_end(self.protocol.break_min_s))
                self._end_break()

    def _held(self) -> bool:
        if not self.hold_flagged:
            return False
        if self._pending and self.clock() - self._pending[-1][2] < self.trial_check.wait_s:
            return True  # its verdict is on its way: the next key waits for it
        return bool(self.records and self.records[-1].flagged)

    # ---- transitions ---------------------------------------------------------------------
    def _start_session(self) -> None:
        self._reach(self._newest(self._tick_frame) if self._start_at is None
                    else self._start_at)
        self._log("session_start", blocks=len(self.orders), trial_frames=self.trial_frames)
        if not self._plan.remaining():
            self._finish()
        elif self.free_play_s > 0:
            self._phase_until = self.clock() + self.free_play_s
            self._phase_from = max(self._at, self._min_start)
            self._log("free_play", seconds=self.free_play_s)
            self._set_state(State.FREE_PLAY)
        else:
            self._enter_block()

    def _phase_over(self, seconds: float) -> bool:
        """A timed phase of ``seconds`` is over. On the stream's own clock it is counted in
        frames from its first, as trials are: the chunk a StreamClock reads can hold frames
        this tick has not counted (or begin before the phase did), so its seconds alone
        ended free play 34 frames early under load, and the events moved with the load."""
        if isinstance(self.clock, StreamClock):
            return self._newest(self._tick_frame) >= self._phase_from + round(seconds * self.rate)
        return self.clock() >= self._phase_until

    def _phase_end(self, seconds: float) -> int:
        """The frame a timed phase of ``seconds`` ended, seen at this tick: its length
        in stream frames from its start, never later than the tick (a stream that ran
        ahead of the runner does not delay it; a slow clock does not advance it)."""
        return min(self._newest(self._tick_frame),
                   self._phase_from + round(seconds * self.rate))

    def _after_free_play(self) -> None:
        self._enter_block()

    def _enter_block(self) -> None:
        if self._shots is not None and self._shots_block is not None \
                and self.block > self._shots_block:
            self._personalise_check()
        if self._own:
            self._adapt_check()
        self._log("block_start", block=self.block)
        self._emit(BlockStarted(self.block))
        self._set_state(State.BLOCK_START)

    def _begin_trial(self, gesture: str, key: str, start: int,
                     performed: str | None = None) -> None:
        self.hint = ""
        self._redo_for = None
        self._current = {
            "gesture": gesture, "key": key, "block": self.block, "start": start,
            "performed": performed,
            "end": start + self.trial_frames, "dropped0": self.recorder.dropped,
            "event_cursor": self.engine.event_count,
        }
        # a stream that waits for its readers pauses just after the trial until a tick
        # ends it: run on, it could be past the beep's end before the beep began
        self._hold(lambda: start, self._lead)
        self._trial_starts.append(self.clock())
        self._set_state(State.RECORDING)
        self._emit(TrialStarted(gesture, key, start))
        self._check_recording()

    def _check_recording(self) -> None:
        cur = self._current
        assert cur is not None
        if self.engine.frames >= cur["end"]:
            self._end_trial()
        elif not self.engine.running:
            self._drop_current()
            self._log("trial_dropped", gesture=cur["gesture"], reason="sensor stopped")
            self._refuse("the sensor stopped during the trial; it was not recorded")
            self._set_state(State.WAITING)

    def _end_trial(self) -> None:
        cur, self._current = self._current, None
        assert cur is not None
        self._beep()
        n = self.trial_frames
        self.recorder.catch_up()  # the trial's rows into the file, and its losses counted
        m = measure_trial(self.engine, cur["start"], n, self.rate, self.quality,
                          cur["event_cursor"], self.recorder.dropped - cur["dropped0"],
                          self.protocol.gesture_by_name(cur["gesture"]).force)
        end = cur["end"]
        self._hold(lambda: end, keys_from=end)  # the next key may name any frame from here
        practice = cur["block"] < 0
        row0 = self.recorder.row_of(cur["start"])  # now that the recorder is past it
        again = self._again_for.pop((cur["block"], cur["gesture"]), None)
        later = not practice and self._checks_later(m)
        check = None if practice or later else self._model_check(m, cur["gesture"])
        flags = [*m.flags, MISMATCH_FLAG] if check and check["flagged"] else m.flags
        record = TrialRecord(
            index=self._next_index(), block=cur["block"], gesture=cur["gesture"],
            key=cur["key"], start_sample=row0, end_sample=row0 + n,
            start_time=m.start_time, end_time=m.end_time,
            status=TrialStatus.DISCARDED if practice else TrialStatus.OK,
            reason="practice" if practice else again, flags=tuple(flags), check=check,
            performed=cur.get("performed"))
        self._plan.mark_done(cur["gesture"])
        self._min_start = cur["end"]
        # the beep's phase counted from the trial's end: the stream may have run up to a
        # ring past it while the check scored the trial (a speed-0 simulator under load),
        # and from its newest frame the beep could never end (a stream held at the ring)
        self._phase_from = end
        self._phase_until = self.clock() + self.protocol.beep_s
        self._set_state(State.TRIAL_END)
        self._write_trial(record)
        if later:
            self._pending.append((record.index, self.trial_check.submit(
                self.engine.layout, m.raw, self.engine.baseline, self.rate, cur["gesture"]),
                self.clock()))
        if practice or m.raw is None or (self._shots is None and self._own is None):
            return
        # one copy of the frames for both uses (the check computes a trial's features once)
        kept = (m.raw.copy(), self.engine.baseline, record.gesture)
        if self._shots is not None and self._shots_block in (None, record.block):
            self._shots_block = record.block  # the first block this run collects
            self._shots[record.index] = kept
        if self._own is not None:
            self._own[record.index] = kept

    def _model_check(self, m: TrialMeasure, prompted: str) -> dict[str, Any] | None:
        """The trial's stored ``check`` by the model check (None: no check, no baseline,
        or a gesture the model does not know). It runs here, at the tick that ends the
        trial (the GUI's timer or the headless loop, never the acquisition thread), so
        its verdict is on the trial the moment the trial is written."""
        if self.trial_check is None or m.raw is None or self.engine.baseline is None:
            return None
        v = self.trial_check.check(self.engine.layout, m.raw, self.engine.baseline,
                                   self.rate, prompted)
        return None if v is None else v.stored(str(self.trial_check.describe()["model"]))

    def _checks_later(self, m: TrialMeasure) -> bool:
        return (isinstance(self.trial_check, BackgroundCheck) and m.raw is not None
                and self.engine.baseline is not None)

    def take_verdict(self, wait_s: float = 0.0) -> None:
        """A BackgroundCheck's verdict joins its trial (``check``, ``model_mismatch``) at
        the first tick after the model answered (``wait_s``: wait that long for it, as the
        session ends); the redo prompt asks about it while it is still the last trial."""
        while self._pending:
            index, future, _since = self._pending[0]
            if not future.done() and wait_s <= 0:
                return
            try:
                v, model = future.result(timeout=wait_s or None)
            except TimeoutError:
                return
            finally:
                if future.done():
                    self._pending.pop(0)
            self._join_verdict(index, v, model)

    def _join_verdict(self, index: int, v: TrialVerdict | None, model: str) -> None:
        trial = next((t for t in self.records if t.index == index), None)
        if v is None or trial is None:
            return
        changes: dict[str, Any] = {"check": v.stored(model)}
        if v.flagged:
            changes["flags"] = [*trial.flags, MISMATCH_FLAG]
        new = self._update_trial(trial, **changes)
        if (new.flagged and self._current is None and self.records[-1].index == index
                and self.state not in State.DONE):
            self._redo_for = index

    def _personalise_check(self) -> None:
        """Fit the check to this participant with their first block's usable trials
        (research decision 5: the few-shot route); a failure is an event and a hint, the
        session goes on with the check as it was."""
        shots, self._shots = self._shots or {}, None
        usable = [shots[t.index] for t in self.records if t.index in shots and t.ok]
        # it takes seconds: a stream that waits for its readers must not run a ring ahead
        # meanwhile (the next trial's frames would be gone before its key names them)
        if isinstance(self.trial_check, BackgroundCheck):  # the console: off the GUI thread
            self._personalising = self.trial_check.personalise_later(
                self.engine.layout, usable, self.rate)
            return
        self._hold(lambda: self._tick_frame, self._lead)
        try:
            n = self.trial_check.personalise(self.engine.layout, usable, self.rate)
        except UserError as exc:
            self._personalised(exc)
        else:
            self._personalised(n)

    def _adapt_check(self) -> None:
        """Adapt the check to this participant: their statistics from all their usable
        trials of the blocks done (whole blocks: every gesture about as often); it reads
        their next trials with them (learn/deploy/trial_check.py)."""
        own, check = self._own or {}, self.trial_check
        assert check is not None  # only a check that adapts keeps their trials
        usable = [own[t.index] for t in self.records
                  if t.index in own and t.ok and t.block < self.block]
        if len(usable) <= self._adapted_on:
            return
        self._adapted_on = len(usable)
        if isinstance(check, BackgroundCheck):  # the console: off the GUI thread
            self._adapting.append(check.adapt_later(self.engine.layout, usable, self.rate))
            return
        self._hold(lambda: self._tick_frame, self._lead)
        n = getattr(check, "adapt")(self.engine.layout, usable, self.rate)
        self._adapted(n, str(check.describe()["model"]))

    def _take_adapted(self, wait_s: float = 0.0) -> None:
        """A BackgroundCheck's adaptations, once done, go on record (``wait_s``: wait
        that long for them, as the session ends)."""
        while self._adapting and (wait_s > 0 or self._adapting[0].done()):
            try:
                n, model = self._adapting[0].result(timeout=wait_s or None)
            except TimeoutError:
                return
            self._adapting.pop(0)
            self._adapted(n, model)

    def _adapted(self, trials: int, model: str) -> None:
        """The check's adaptation on record (none when the trials were too few or too
        alike to take statistics from: it reads them as before)."""
        if trials:
            self._log("trial_check_adapted", trials=trials, model=model)

    def _take_personalised(self, wait_s: float = 0.0) -> None:
        """A BackgroundCheck's personalisation, once done, goes on record (``wait_s``: wait
        that long for it, as the session ends)."""
        future = self._personalising
        if future is None or (not future.done() and wait_s <= 0):
            return
        try:
            outcome: int | UserError = future.result(timeout=wait_s or None)
        except TimeoutError:
            return
        except UserError as exc:
            outcome = exc
        self._personalising = None
        self._personalised(outcome)

    def _personalised(self, outcome: int | UserError) -> None:
        """The check's personalisation on record: an event, or a hint when it failed (the
        session goes on with the check as it was)."""
        if isinstance(outcome, UserError):
            self._log("trial_check_personalised", trials=0, error=str(outcome))
            self._refuse(f"the check could not be personalised: {outcome}")
            return
        model = str(self.trial_check.describe()["model"])
        self._log("trial_check_personalised", trials=outcome, model=model)
        self._emit(CheckPersonalised(outcome, model))

    def _drop_current(self) -> None:
        """Forget the running trial and let the stream go on without it."""
        self._current = None
        self._hold(None)

    # ---- holding a stream that waits for its readers ------------------------------------
    # A device that runs as fast as its readers (the simulator at speed 0) is held to the
    # runner's pace (``hold_frames``; a real-time device is never slowed). A key names the
    # frame its trial began, which may have passed (the virtual participant presses with
    # the frame its touch began); the quality check reads a trial's frames when it ends;
    # free play, the beep and breaks last stream time, counted at the ticks. So: a trial
    # holds from its start and pauses the stream just after its end until a tick ends it;
    # waiting for a key holds from where a key may begin; the timed phases let the
    # stream run a little ahead of the last tick.

    def _hold_for(self, state: str) -> None:
        if state in (*State.KEY_STATES, State.TRIAL_END):
            if self._keys_from is None:
                w = self.engine.frames
                self._hold(lambda: w, keys_from=w)
        elif state in State.DONE:
            self._hold(None)
        elif state != State.RECORDING:
            self._hold(lambda: self._tick_frame, self._lead)

    def _hold(self, cursor: Callable[[], int] | None, lead: int | None = None,
              keys_from: int | None = None) -> None:
        """Hold the stream from ``cursor()`` on, ``lead`` frames at most ahead of it
        (None: the ring); ``cursor`` None lets go."""
        self._release_hold()
        self._keys_from = keys_from
        self._release_hold = (lambda: None) if cursor is None else \
            hold_frames(self.engine, cursor, lead)

    def _next_index(self) -> int:
        return max((t.index for t in self.records), default=-1) + 1

    def _write_trial(self, record: TrialRecord) -> None:
        """Into the file (flushed) before anything else happens: a crash keeps it."""
        rec = self.recorder.add_trial(record)
        self.records.append(rec)
        self._redo_for = rec.index if rec.flagged else None
        self._emit(TrialEnded(rec, tuple(rec.flags),
                              describe(list(rec.flags), rec.check)))

    def _after_trial(self) -> None:
        if self._plan.remaining():
            nxt = State.WAITING
            if self._break_pending:
                self._break_pending = False
                self._enter_break(scheduled=False)
                nxt = State.BREAK
        elif self._plan.is_last_round():
            self._finish()
            return
        elif self._break_pending or self.break_after(self.block):
            self._break_pending = False
            self._enter_break(scheduled=self.break_after(self.block))
            nxt = State.BREAK
        else:
            self._plan.advance()
            self._enter_block()
            nxt = State.BLOCK_START
        if nxt == State.WAITING:
            self._set_state(State.WAITING)
        if self._pause_pending:
            self._pause_pending = False
            self._enter_pause(self.state)

    def _enter_break(self, scheduled: bool) -> None:
        if scheduled:
            self._plan.take_break(self.block)
        self._phase_until = self.clock() + self.protocol.break_min_s
        self._phase_from = max(self._at, self._min_start)
        self._log("break_start", after_block=self.block, scheduled=scheduled,
                  min_s=self.protocol.break_min_s)
        self.recorder.flush()
        self._set_state(State.BREAK)

    def _end_break(self) -> None:
        self._log("break_end")
        if not self._plan.remaining():
            if self._plan.is_last_round():
                self._finish()
                return
            self._plan.advance()
        self._enter_block()

    def _enter_pause(self, state: str) -> None:
        self._paused_from = state
        self._paused_at = self.clock()
        self._log("pause", state=state)
        self.hint = ""
        self._set_state(State.PAUSED)

    def _finish(self) -> None:
        # the personalisation and the last trials' verdicts are in the file
        self._take_personalised(wait_s=PERSONALISE_WAIT_S)
        self._take_adapted(wait_s=PERSONALISE_WAIT_S)
        self.take_verdict(wait_s=WAIT_S)
        self._log("session_end", trials=len(self.records))
        self._end_file_here()
        self.recorder.flush()
        self._set_state(State.FINISHED)

    def _end_file_here(self) -> None:
        """The file ends with the session (finished or aborted) at the frame the runner
        is at, whatever the stream's pace: a simulator at speed 0, let go once the session
        is over, had written ten minutes of idle after an interrupted session's last
        trial before the file closed (and a resume kept them)."""
        end_at = getattr(self.recorder, "end_at", None)
        if end_at is not None:
            end_at(max(self._at, self._min_start) + 1)

    def _beep(self) -> None:
        hz, length = self.protocol.beep_hz, self.protocol.beep_s
        self.beeps += 1
        if self._beeper is not None:
            play = getattr(self._beeper, "play", self._beeper)
            play(hz, length)
        self._emit(Beep(hz, length))

    def _update_trial(self, trial: TrialRecord, **changes: Any) -> TrialRecord:
        new = trial.with_changes(**changes)
        self.records[self.records.index(trial)] = new
        self.recorder.update_trial(trial.index, **changes)
        self._emit(TrialUpdated(new))
        return new

    @property
    def redo_prompt(self) -> str:
        """"Trial 4 (Stroke): no contact - redo?" while the last flagged trial awaits a
        decision: gone once it is redone, discarded or kept (Continue), when the next
        trial starts, and when the session is over (nothing can be redone there)."""
        if self._redo_for is None or self.state in State.DONE:
            return ""
        t = next((t for t in self.records if t.index == self._redo_for), None)
        if t is None or not t.flagged:
            return ""
        return f"Trial {t.index + 1} ({t.gesture}): {describe(list(t.flags), t.check)} - redo?"

    # ---- the snapshot --------------------------------------------------------------------
    def snapshot(self) -> RunnerSnapshot:
        """Everything the participant screen and the experimenter console show."""
        return build_snapshot(self)

    # read-only views used by build_snapshot
    @property
    def current_trial(self) -> dict[str, Any] | None:
        return self._current

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
    def at_frame(self) -> int:
        """The stream frame the runner has acted at (its last start, pause, resume, end
        of a phase or of a trial): a key may not name a frame before it."""
        return max(self._at, self._min_start)

    @property
    def phase_until(self) -> float:
        return self._phase_until

    @property
    def trial_starts(self) -> list[float]:
        return self._trial_starts

    @property
    def round_gestures(self) -> list[str]:
        return list(self._plan.gestures)

    def round_done(self) -> set[str]:
        return set(self._plan.done[self._plan.index])

    def round_remaining(self) -> list[str]:
        """The current round's gestures not done yet, in the order they are prompted."""
        return self._plan.remaining()

    def rounds_ahead(self) -> list[tuple[int, list[str]]]:
        """(block, remaining gestures) of the current round and every later one."""
        return self._plan.rounds_ahead()

    @property
    def practice(self) -> bool:
        return self.block < 0


__all__ = ["Clock", "TrialRunner", "GestureView", "RunnerSnapshot", "State", "StreamClock",
           "participant_message"]
