"""A virtual participant: presses the keys and performs the gestures on the simulator.

It follows the participant screen like a person would: with the protocol's
``order = "prompted"`` it does each prompted gesture in turn (the block's stored order,
a redone gesture first); with ``order = "free"`` it does the block's remaining gestures
in the protocol file's order, like a participant who always goes the same way round (the
habit prompted order exists to break). It presses each gesture's key as it starts it.
Everything it does is keyed by frame index and drawn from generators seeded by
(participant, seed), never by wall-clock time: it schedules each performance on the
simulated sensor at a planned frame ahead of the stream and presses the key with that
frame (``runner.key(k, at_frame=X)``), so with the simulator at any finite speed the
same seed gives the same trials at the same file rows with the same frames.

The personal style (where on the sensor, how hard, how fast) is the simulator's
``style_seed``, derived from the participant id, so two virtual participants differ
the way two people do.

Its mistakes (for testing the trial checks, issue 46) are the simulated sensor's settings
``mistakes``, ``light`` and ``off_centre``: the share of trials where it performs another
gesture of the protocol than the prompted one, performs far too lightly, or off the
sensor's centre. With any of them set, every trial records what it ``performed``:
"Twist", "Wide Pinch; light", "Poke; off centre".

In the console's pilot mode (``plan_ahead=False``) the experimenter drives the session
(Start, Continue, pauses, redo) in real time: the participant plans nothing ahead; it
reacts to what the screen prompts now, as a person would, and a plan the session moved
past (a pause, a redo) is made again.
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

import numpy as np

from tactile_studio.protocol.trial_runner import State, TrialRunner

# Protocol gestures the simulator has no model for, mapped to a similar one:
# (simulator gesture or None for no touch, intensity factor, speed factor).
SIM_EQUIVALENT: dict[str, tuple[str | None, float, float]] = {
    "poke": ("Poke", 1.0, 1.0), "pinch": ("Wide Pinch", 1.1, 1.2),
    "wide pinch": ("Wide Pinch", 1.0, 1.0), "grab": ("Wide Pinch", 1.4, 1.3),
    "squeeze": ("Wide Pinch", 1.3, 0.8), "pat": ("Heavy Pat", 0.6, 1.1),
    "heavy pat": ("Heavy Pat", 1.0, 1.0), "hit": ("Heavy Pat", 1.6, 1.4),
    "slap": ("Heavy Pat", 1.4, 1.6), "tap": ("Poke", 0.7, 2.0), "twist": ("Twist", 1.0, 1.0),
    "rub": ("Back & Forth Rub", 1.0, 1.0), "back & forth rub": ("Back & Forth Rub", 1.0, 1.0),
    "massage": ("Isometric Rub", 1.2, 0.8), "isometric rub": ("Isometric Rub", 1.0, 1.0),
    "stroke": ("Circular Stroke", 0.8, 0.9), "circular stroke": ("Circular Stroke", 1.0, 1.0),
    "press": ("Constant Touch", 1.5, 1.0), "constant": ("Constant Touch", 1.0, 1.0),
    "constant touch": ("Constant Touch", 1.0, 1.0), "scratch": ("Tickle", 1.2, 1.5),
    "tickle": ("Tickle", 1.0, 1.0), "no touch": (None, 0.0, 1.0),
}
LIGHT_FACTOR = 0.05   # a "too light" trial: this share of the person's usual force
OFF_CENTRE_MM = 40.0  # an off-centre trial: this far from their spot along x and y
_FALLBACK = ("Poke", "Wide Pinch", "Heavy Pat", "Twist", "Back & Forth Rub", "Isometric Rub",
             "Circular Stroke", "Constant Touch", "Tickle")


def style_seed(participant: str, seed: int = 0) -> int:
    """The participant's personal style, the same on every run and machine."""
    digest = hashlib.sha256(f"style|{participant}|{int(seed)}".encode()).digest()
    return int.from_bytes(digest[:4], "little") & 0x7FFFFFFF


def sim_gesture(name: str) -> tuple[str | None, float, float]:
    key = " ".join(name.lower().split())
    if key in SIM_EQUIVALENT:
        return SIM_EQUIVALENT[key]
    h = int.from_bytes(hashlib.sha256(key.encode()).digest()[:2], "little")
    return _FALLBACK[h % len(_FALLBACK)], 1.0, 1.0


class VirtualParticipant:
    """Drives ``runner`` and the simulated ``device`` (a SimulatedSensor) together.

    Call :meth:`prepare` before the engine starts, then :meth:`step` after every
    ``runner.tick()``. It starts the runner itself once the baseline is in.
    """

    def __init__(self, runner: TrialRunner, device: Any, participant: str,
                 seed: int = 0, plan_ahead: bool = True) -> None:
        self.runner, self.device = runner, device
        self.plan_ahead = plan_ahead
        self.participant, self.seed = participant, int(seed)
        self.style = style_seed(participant, seed)
        self.rate = runner.rate
        self.n = runner.trial_frames
        self.start_frame = runner.engine.baseline_frames + round(0.5 * self.rate)
        self._beep_frames = math.ceil(runner.protocol.beep_s * self.rate) + 1
        # (block, gesture, key frame, what it performs) in order
        self._plans: list[tuple[int, str, int, str | None]] = []
        self._free_until = 0  # frame where its current free-play touch ends (not planned ahead)
        self._count = 0
        self.replanned = 0  # plans that had to move because the stream overtook them

    def _rng(self, *key: int) -> np.random.Generator:
        return np.random.default_rng([self.style, self.seed & 0x7FFFFFFF, *key])

    def prepare(self) -> None:
        """Quiet background, this participant's style, free-play touches, and every
        remaining trial planned on the stream (so the plan never races the stream)."""
        self.device.set_gesture("idle")  # from the next frame on
        self.device.set_style(self.style)
        if not self.plan_ahead:
            return  # it reacts to the screen as it goes (step)
        self.start_frame = max(self.start_frame, self.device.next_frame + round(0.5 * self.rate))
        r = self.runner
        fp_frames = round(r.free_play_s * self.rate)
        rng = self._rng(0xF4EE)
        f = self.start_frame + round(0.3 * self.rate)
        while fp_frames and f + self.n < self.start_frame + fp_frames:
            self._touch_any(rng, f)  # the stream already past it (prepared late): skipped
            f += self.n + round(rng.uniform(0.3, 0.8) * self.rate)
        frame = self.start_frame + fp_frames + round(1.0 * self.rate)
        prev: int | None = None
        for block, gestures in r.rounds_ahead():
            for gesture in self._own_order(gestures):
                if prev is not None and block != prev and r.break_after(prev):
                    frame += round((r.protocol.break_min_s + 2.0) * self.rate)
                frame = self._plan(block, gesture, frame + self._gap())
                frame += self.n + self._beep_frames
                prev = block

    def _own_order(self, gestures: list[str]) -> list[str]:
        """The order it does a round's remaining gestures in (see the module docstring)."""
        if self.runner.protocol.order == "prompted":
            return list(gestures)
        rank = {name: i for i, name in enumerate(self.runner.protocol.gesture_names)}
        return sorted(gestures, key=rank.__getitem__)

    def _next(self) -> tuple[int, str] | None:
        """The (block, gesture) it does next: the first of the next round with any left."""
        for block, gestures in self.runner.rounds_ahead():
            if gestures:
                return block, self._own_order(gestures)[0]
        return None

    def _gap(self) -> int:
        """Frames from the previous beep to the next key press: reading and reacting."""
        return round(self._rng(0x6A9, self._count).uniform(0.4, 1.1) * self.rate)

    def _mistake(self, gesture: str) -> tuple[str, str | None, float, tuple[float, float]]:
        """(the gesture it performs, ``performed`` as stored (None: no mistakes are set),
        intensity factor, shift in mm): the simulator's ``mistakes`` / ``light`` /
        ``off_centre`` shares of trials done wrong, drawn apart from the performance's own
        draws (so a session without mistakes is the same as before they existed)."""
        settings = getattr(self.device, "settings", None) or {}
        shares = [float(settings.get(k) or 0.0) for k in ("mistakes", "light", "off_centre")]
        if not any(shares):
            return gesture, None, 1.0, (0.0, 0.0)
        rng = self._rng(0x3157AE, self._count)
        draws = rng.random(3)
        done, how, factor, shift = gesture, [], 1.0, (0.0, 0.0)
        if draws[0] < shares[0]:
            own = sim_gesture(gesture)[0]
            others = [g for g in self.runner.protocol.gesture_names
                      if g != gesture and sim_gesture(g)[0] not in (own, None)]
            if others:
                done = others[int(rng.integers(len(others)))]
        if draws[1] < shares[1]:
            factor = LIGHT_FACTOR
            how.append("light")
        if draws[2] < shares[2]:
            sx, sy = rng.choice([-1.0, 1.0], size=2)
            shift = (float(sx) * OFF_CENTRE_MM, float(sy) * OFF_CENTRE_MM)
            how.append("off centre")
        return done, "; ".join([done, *how]), factor, shift

    def _plan(self, block: int, gesture: str, frame: int) -> int:
        """Schedule ``gesture`` on the simulator at ``frame`` (moved later if the stream
        already passed it) and remember it for the key press."""
        done, performed, factor, shift = self._mistake(gesture)
        rng = self._rng(0x7E1A, self._count)
        self._count += 1
        sim, inten, speed = sim_gesture(done)
        inten *= factor * float(rng.uniform(0.85, 1.15))
        speed *= float(rng.uniform(0.9, 1.1))
        lead = int(rng.integers(-2, 3))  # the hand lands a little before or after the key
        for _ in range(100):
            earliest = self.device.next_frame + 2 - min(lead, 0)
            if frame < earliest:
                frame = earliest + round(0.2 * self.rate)
                self.replanned += 1
            try:
                if sim is not None:
                    how = {"shift_mm": shift} if shift != (0.0, 0.0) else {}
                    self.device.perform(sim, self.n / self.rate, inten, speed,
                                        at_frame=frame + lead, **how)
                break
            except ValueError:  # the stream overtook us between the check and the call
                continue
        self._plans.append((block, gesture, frame, performed))
        return frame

    def _touch_any(self, rng: np.random.Generator, frame: int) -> bool:
        """A free-play touch: one of the protocol's gestures at ``frame``; False when the
        stream has passed it."""
        names = self.runner.protocol.gesture_names
        sim, inten, speed = sim_gesture(names[int(rng.integers(len(names)))])
        if sim is None:
            return True
        try:
            self.device.perform(sim, self.n / self.rate, inten, speed, at_frame=frame)
        except ValueError:
            return False
        return True

    def step(self) -> bool:
        """Act if it is time; True if a key was pressed (or the session started)."""
        r = self.runner
        if r.state == State.SETUP and self.plan_ahead:
            # started once its start frame is in: the runner's clock then reads it
            if r.engine.frames > self.start_frame and r.engine.baseline is not None:
                return r.start(at_frame=self.start_frame)
            return False
        if r.state == State.FREE_PLAY and not self.plan_ahead:
            return self._free_play()
        if r.state not in State.KEY_STATES or r.held:
            return False
        nxt = self._next()
        if nxt is None:
            return False
        if not self.plan_ahead:  # a plan the session moved past (a pause, a redo, another
            # prompt) is dropped: its touch happened unlabelled, as a person's would
            self._plans = [p for p in self._plans if p[:2] == nxt and p[2] >= r.at_frame]
        block, gesture = nxt
        i = next((i for i, p in enumerate(self._plans) if p[:2] == (block, gesture)), None)
        if i is None:  # off the plan (a redo; in a pilot, every trial): do it now
            self._plan(block, gesture, self.device.next_frame + self._gap())
            i = len(self._plans) - 1
        frame, performed = self._plans[i][2:]
        if r.engine.frames - 1 < frame:
            return False  # not there yet
        del self._plans[i]
        return r.key(r.protocol.gesture_by_name(gesture).key, at_frame=frame,
                     performed=performed)

    def _free_play(self) -> bool:
        """Not planned ahead (the console's pilot): a touch now and then in free play."""
        self._plans.clear()
        if self.device.next_frame >= self._free_until:
            rng = self._rng(0xF4EE, self._count)
            self._count += 1
            start = self.device.next_frame + round(rng.uniform(0.3, 0.8) * self.rate)
            if self._touch_any(rng, start):
                self._free_until = start + self.n
        return False
