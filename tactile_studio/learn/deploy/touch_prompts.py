"""The prompts of a live personalisation (the live panel's "Calibrate to person…"):
"Perform <gesture> now" for every gesture of the run, K rounds, each answered by one
labelled window taken from the live stream once the touch is there; then the run's model
personalised with the answers and, with two or more rounds, its held-out check
(learn/deploy/personalise.py does both). Qt-free: the dialog drives it."""

from __future__ import annotations

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.deploy.personalise import (
    HeldOutCheck,
    LabelledTouches,
    Personalised,
    held_out_check,
    personalise,
)
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.sensor.decode import contact_taxels
from tactile_studio.sensor.layout import Layout


class TouchPrompts:
    """The prompts of a live personalisation: "Perform <gesture> now" for every gesture
    of the run, K rounds, each answered by one labelled window of the model's window
    length taken from the live stream once the touch is there.

    :meth:`poll` watches the engine from the prompt on: the first frame in contact
    (``contact_taxels``) is the touch's onset; the window starts a quarter window before
    it (the approach, as a trial's window holds it) and is taken once complete, if the
    sensor was touched in ``contact_share`` of it. Skip leaves a prompt unanswered; Redo
    takes the last answered prompt again. Qt-free: the live panel's dialog drives it."""

    def __init__(self, model: WindowModel, k: int, contact_share: float = 0.05) -> None:
        if k < 1:
            raise UserError("personalisation needs at least one touch per gesture")
        self.model, self.k, self.contact_share = model, int(k), contact_share
        self.prompts = [g for _ in range(self.k) for g in model.labels]
        self.answers: dict[int, tuple[np.ndarray, float]] = {}  # prompt -> (window, rate)
        self.pos = 0
        self._cursor: int | None = None  # first frame not yet looked at
        self._onset: int | None = None
        self._order: list[int] = []  # answered prompts, oldest first

    @property
    def done(self) -> bool:
        return self.pos >= len(self.prompts)

    @property
    def gesture(self) -> str | None:
        """The gesture the person is asked for now (None when every prompt is past)."""
        return None if self.done else self.prompts[self.pos]

    @property
    def round(self) -> int:
        """1-based: which of the K performances of the gesture is asked for."""
        return min(self.pos, len(self.prompts) - 1) // len(self.model.labels) + 1

    @property
    def touching(self) -> bool:
        """A touch has begun since the prompt (its window is not complete yet)."""
        return self._onset is not None

    def begin(self, engine) -> None:
        """The current prompt is shown now: only frames from now on answer it."""
        self._cursor, self._onset = engine.frames, None

    def skip(self, engine) -> None:
        self.pos += 1
        self.begin(engine)

    def redo(self, engine) -> None:
        """Ask again for the last answered prompt (its window is dropped)."""
        if self._order:
            self.pos = self._order.pop()
            self.answers.pop(self.pos, None)
        self.begin(engine)

    def poll(self, engine) -> bool:
        """Looks at the frames since the last call; True when the current prompt was
        answered (then the next prompt begins)."""
        base = engine.baseline
        if self.done or base is None:
            return False
        if self._cursor is None:
            self.begin(engine)
        rate = engine.device_rate_hz() or engine.nominal_rate_hz
        w = self.model.window_for(rate)
        if self._onset is None:
            chunk = engine.read_since(self._cursor)
            if not len(chunk):
                return False
            touching = contact_taxels(engine.layout, chunk.raw, base).any(axis=(1, 2))
            self._cursor = chunk.stop
            if not touching.any():
                return False
            self._onset = max(chunk.start + int(np.argmax(touching)) - w // 4, chunk.start)
        if engine.frames < self._onset + w:
            return False
        chunk = engine.read_since(self._onset, w)
        if len(chunk) < w:  # overwritten in the ring meanwhile: wait for another touch
            self._cursor, self._onset = engine.frames, None
            return False
        touching = contact_taxels(engine.layout, chunk.raw, base).any(axis=(1, 2))
        if touching.mean() < self.contact_share:  # a brush, not the gesture
            self._cursor, self._onset = chunk.stop, None
            return False
        span = float(chunk.device_time[-1] - chunk.device_time[0])
        self.answers[self.pos] = (self.model.decode(engine.layout, chunk.raw, base),
                                  (w - 1) / span if span > 0 else rate)
        self._order.append(self.pos)
        self.pos += 1
        self.begin(engine)
        return True

    def labelled(self) -> tuple[list[np.ndarray], list[str], float]:
        """(windows, their gestures, rate) of the answered prompts."""
        keys = sorted(self.answers)
        rates = [self.answers[i][1] for i in keys]
        return ([self.answers[i][0] for i in keys], [self.prompts[i] for i in keys],
                float(np.median(rates)) if rates else 0.0)

    def rounds(self) -> list[int]:
        """The round (0-based) of each answered prompt, in :meth:`labelled`'s order."""
        return [i // len(self.model.labels) for i in sorted(self.answers)]

    def personalise(self, layout: Layout, seed: int = 0, progress: ProgressFn = no_progress,
                    cancel: CancelToken | None = None) -> Personalised:
        """The run's model personalised with the answered prompts (no check: see
        :meth:`held_out_check`, which the dialog runs once the model is in use)."""
        windows, gestures, rate = self.labelled()
        return personalise(self.model, LabelledTouches(layout, windows, gestures, rate), seed,
                           progress=progress, cancel=cancel)

    def held_out_check(self, layout: Layout, seed: int = 0,
                       progress: ProgressFn = no_progress,
                       cancel: CancelToken | None = None) -> HeldOutCheck | None:
        """The answered prompts' held-out check (None with fewer than two rounds)."""
        windows, gestures, rate = self.labelled()
        touches = LabelledTouches(layout, windows, gestures, rate, self.rounds())
        return held_out_check(self.model, touches, seed, progress=progress, cancel=cancel)
