"""The collection runner's inputs: the participant's key and the experimenter's verbs.

Each verb either acts and returns True, or refuses with a one-line hint (``runner.hint``
and a "hint" event) and returns False; none raises for a wrong moment. The state
transitions they trigger live in :mod:`tactile_studio.protocol.trial_runner`.
"""

from __future__ import annotations

from tactile_studio.protocol.background_check import WAIT_S
from tactile_studio.protocol.runner_events import NoteAdded
from tactile_studio.protocol.snapshot import State
from tactile_studio.storage.format.trials import TrialStatus


class RunnerInputs:
    """Input methods of :class:`~tactile_studio.protocol.trial_runner.TrialRunner`.

    A mixin: it uses the runner's state (``state``, ``trials``, ``_plan``...) and its
    transitions (``_begin_trial``, ``_after_trial``, ``_enter_break``...).
    """

    def start(self, at_frame: int | None = None) -> bool:
        """Leave setup: free play, practice, then block 1 (once the baseline is ready).
        ``at_frame``: the stream frame the session starts at (a virtual participant's
        plan; default the newest frame at the tick that starts it)."""
        if self.state != State.SETUP:
            return self._refuse("the session has already started")
        self._start_requested = True
        self._start_at = None if at_frame is None else int(at_frame)
        self.tick()
        return True

    def key(self, k: str, at_frame: int | None = None, performed: str | None = None) -> bool:
        """The participant's key. With the protocol's ``order = "prompted"`` (default)
        only the prompted gesture's key starts a trial; with ``"free"`` the key of any
        gesture of the block not done yet does. ``performed``: what a virtual participant
        actually performs (its mistakes), stored on the trial."""
        if self.state not in State.KEY_STATES:
            return self._refuse(self._why_no_key())
        if self.state == State.REVIEW:
            if self._held():
                return self._refuse("the experimenter is checking the last trial")
            self._after_trial()  # a pending pause or break, or the next block, comes first
            if self.state not in State.KEY_STATES:
                return self._refuse(self._why_no_key())
        prompted = self.protocol.order == "prompted"
        gesture = self.protocol.gesture_by_key(k) if isinstance(k, str) and len(k) == 1 else None
        if gesture is None:
            then = f". {self.next_prompt()}" if prompted else ""
            return self._refuse(f"'{k}' is not a gesture key{then}")
        if prompted and gesture.name != self._plan.prompted:
            if self._plan.is_done(gesture.name):
                return self._refuse(f"{gesture.name} is already done in this block. "
                                    f"{self.next_prompt()}")
            return self._refuse(self.next_prompt())
        if gesture.name not in self._plan.gestures:
            return self._refuse(f"{gesture.name} ({gesture.key}) "
                                "is not part of this practice round")
        if self._plan.is_done(gesture.name):
            left = ", ".join(f"{g} ({self.protocol.gesture_by_name(g).key})"
                             for g in self._plan.remaining())
            return self._refuse(f"{gesture.name} ({gesture.key}) is already done in this block; "
                                f"remaining: {left}")
        newest = self.engine.frames - 1
        if newest < 0:
            return self._refuse("no data from the sensor yet")
        start = newest if at_frame is None else int(at_frame)
        if start > newest or start < self._min_start:
            raise ValueError(f"trial start frame {start} outside {self._min_start}..{newest}")
        self._begin_trial(gesture.name, gesture.key, start, performed)
        return True

    def next_prompt(self) -> str:
        """The refusal's second half: "Next is Twist \u2013 press T" ("" if none is due)."""
        name = self._plan.prompted
        if name is None:
            return ""
        return f"Next is {name} \u2013 press {self.protocol.gesture_by_name(name).key.upper()}"

    def proceed(self) -> bool:
        """The experimenter's Continue: ends free play, ends a break after its minimum,
        accepts a held flagged trial, or starts the session."""
        if self.state == State.SETUP:
            return self.start()
        if self.state == State.FREE_PLAY:
            self._reach(self._newest(self.engine.frames))
            self._after_free_play()
            return True
        if self.state == State.BREAK:
            left = self._phase_until - self.clock()
            if left > 0:
                return self._refuse(f"the break has {left:.0f} s of its minimum left")
            self._reach(self._newest(self.engine.frames))
            self._end_break()
            return True
        if self.state == State.REVIEW:
            if self._redo_for is not None:
                self.keep_flagged()  # the experimenter kept the flagged trial
            self._after_trial()
            return True
        return self._refuse(f"nothing to continue in state {self.state}")

    def redo_last(self, reason: str | None = None) -> bool:
        """Mark the last trial redone and put its gesture back into its block."""
        if self.state in (State.SETUP, State.FREE_PLAY, State.RECORDING, State.ABORTED):
            return self._refuse("no finished trial to redo now")
        if not self.records:
            return self._refuse("no trial to redo yet")
        last = self.records[-1]
        if last.status == TrialStatus.REDONE:
            return self._refuse(f"trial {last.index + 1} is already marked redone")
        if last.collected_again:
            return self._refuse(f"trial {last.index + 1} was discarded and its gesture is "
                                "already being collected again")
        if last.status == TrialStatus.DISCARDED:  # it stays discarded on record
            self._update_trial(last, collected_again=True)
            self._again_for[(last.block, last.gesture)] = (
                f"collected again for trial {last.index + 1}")
        else:
            decided = {"decision": "redo"} if last.flagged else {}
            self._update_trial(last, status=TrialStatus.REDONE, reason=reason or None,
                               **decided)
        self._plan.reopen(last.block, last.gesture)
        self.hint = f"redo: {last.gesture} ({last.key})"
        if self.protocol.order == "prompted":  # the redone gesture is prompted next
            self.hint = f"Please redo it. {self.next_prompt()}"
        if self.state in (State.BLOCK_START, State.WAITING, State.REVIEW, State.FINISHED):
            self._set_state(State.WAITING)
        elif self.state == State.PAUSED and self._paused_from in (State.BLOCK_START, State.REVIEW):
            self._paused_from = State.WAITING
        return True

    def keep_flagged(self) -> bool:
        """The experimenter's Keep on the flagged trial the redo prompt asks about: its
        flags stay on record with ``decision: keep``, the prompt goes."""
        index, self._redo_for = self._redo_for, None
        trial = next((t for t in self.records if t.index == index), None)
        if trial is None or not trial.flagged:
            return self._refuse("no flagged trial waits for a decision")
        self._update_trial(trial, decision="keep")
        return True

    def can_collect_again(self, index: int) -> bool:
        """True if trial ``index`` (0-based) is a usable trial of the block being
        collected, so a discard can put its gesture back at the end of this block."""
        trial = next((t for t in self.records if t.index == index), None)
        return (trial is not None and trial.ok and not trial.practice
                and trial.block == self.block and self.state not in State.DONE)

    def discard(self, index: int, reason: str, again: bool = False) -> bool:
        """Mark trial ``index`` (0-based) discarded with ``reason``.

        Without ``again`` its gesture is not collected again (the block stays one
        trial short). With ``again`` (only for a trial of the current block, see
        :meth:`can_collect_again`) the trial is still ``discarded`` with its reason, and
        marked ``collected_again`` (a later trial replaces it, so it does not count as
        done); the gesture is prompted once more after the block's other gestures, the
        new trial's reason names the one it replaces and a ``discard`` event records the
        choice."""
        if not reason or not reason.strip():
            return self._refuse("give a reason to discard a trial")
        trial = next((t for t in self.records if t.index == index), None)
        if trial is None:
            return self._refuse(f"no trial {index + 1}")
        if not trial.ok:
            return self._refuse(f"trial {index + 1} is already {trial.status}")
        if again and not self.can_collect_again(index):
            return self._refuse(f"trial {index + 1} is not in the block being collected: "
                                "it cannot be collected again")
        reason = reason.strip()
        self._log("discard", trial=index, reason=reason, again=bool(again))
        if not again:
            self._update_trial(trial, status=TrialStatus.DISCARDED, reason=reason)
            return True
        self._update_trial(trial, status=TrialStatus.DISCARDED, reason=reason,
                           collected_again=True)
        self._plan.collect_again(trial.gesture)
        self._again_for[(trial.block, trial.gesture)] = f"collected again for trial {index + 1}"
        return True

    def pause(self) -> bool:
        if self.state in State.DONE or self.state in (State.PAUSED, State.SETUP):
            return self._refuse(f"cannot pause in state {self.state}")
        if self.state in (State.RECORDING, State.TRIAL_END):
            self._pause_pending = True
            self.hint = "pausing after this trial"
            return True
        self._reach(self._newest(self.engine.frames))
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
        self._phase_from += round(paused_for * self.rate)  # a timed phase is longer by it
        self._reach(self._newest(self.engine.frames))
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
        self._reach(self._newest(self.engine.frames))
        self._enter_break(scheduled=False)
        return True

    def add_note(self, text: str) -> bool:
        text = " ".join(str(text).split())
        if not text:
            return self._refuse("empty note")
        self.notes.append(text)
        last = self.records[-1].index if self.records else None
        self.recorder.add_note(text, after_trial=last)
        self._emit(NoteAdded(text))
        return True

    def abort(self) -> bool:
        """Stop the session; a running trial is dropped, finished ones stay in the file."""
        if self.state in State.DONE:
            return self._refuse(f"the session is already {self.state}")
        self._reach(self._newest(self.engine.frames))
        if self._current is not None:
            self._log("trial_dropped", gesture=self._current["gesture"], reason="aborted")
            self._drop_current()
        self.take_verdict(wait_s=WAIT_S)  # the last trial's verdict is in the file
        self._log("abort", trials=len(self.records))
        self._end_file_here()
        self.recorder.flush()
        self._set_state(State.ABORTED)
        return True

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
