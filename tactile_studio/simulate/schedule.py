"""What is being performed at every frame: explicit trials over a background mode.

Everything is keyed by frame index, never by wall-clock time, so a run is a pure
function of the seed and of the (frame, command) pairs given to it: a virtual
participant driving the simulator ten times faster than real time, or in batches of any
size, gets exactly the same frames.

Two layers decide the gesture at a frame:

* explicit trials (``add_trial``: one gesture from a start frame for a number of frames);
  the latest-started trial covering a frame wins;
* otherwise the background mode that was set last before the frame: ``idle``, a
  gesture name (that gesture repeated in back-to-back trials), or ``auto`` (a demo:
  3 s idle, then blocks of the nine gestures in a shuffled order, 2 s each with idle
  gaps). The mode the sensor starts in also begins with 3 s of idle, so the engine's
  100-frame tare never sees a touch.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from tactile_studio.simulate.gestures import GESTURE_NAMES, IDLE, canonical_gesture

AUTO = "auto"
PRESS = "press"  # ground truth of a static press scheduled with SensorSimulator.press


@dataclass(frozen=True)
class Trial:
    """One performance: ``gesture`` from frame ``start`` for ``frames`` frames.

    ``key`` makes the trial's random draws unique and reproducible.
    """

    gesture: str
    start: int
    frames: int
    intensity: float
    speed: float
    style_seed: int
    key: tuple[int, ...]
    press: tuple[float, ...] | None = None  # (x, y, radius, load, shear_x, shear_y, ramp_s)
    shift_mm: tuple[float, float] = (0.0, 0.0)  # performed this far from where they touch

    @property
    def stop(self) -> int:
        return self.start + self.frames


@dataclass(frozen=True)
class Segment:
    """A background mode in force from frame ``start`` on."""

    start: int
    mode: str            # idle | auto | a gesture name
    style_seed: int
    intensity: float
    speed: float
    index: int           # position in the segment list (part of trial keys)


class Schedule:
    """The timeline of trials and background modes, at ``rate`` frames per second."""

    def __init__(self, rate: float, seed: int, trial_s: float = 2.0, gap_s: float = 1.5,
                 lead_s: float = 3.0) -> None:
        self.rate = float(rate)
        self.seed = int(seed)
        self.trial_frames = max(1, round(trial_s * rate))
        self.gap_frames = max(1, round(gap_s * rate))
        self.lead_frames = round(lead_s * rate)
        self.trials: list[Trial] = []
        self.segments: list[Segment] = []
        self._orders: dict[tuple[int, int], np.ndarray] = {}

    # ---- commands --------------------------------------------------------------------
    def set_mode(self, frame: int, mode: str, style_seed: int, intensity: float,
                 speed: float) -> Segment:
        mode = AUTO if str(mode).strip().lower() == AUTO else canonical_gesture(mode)
        if self.segments and frame < self.segments[-1].start:
            raise ValueError(f"frame {frame} is before the last mode change "
                             f"({self.segments[-1].start})")
        seg = Segment(int(frame), mode, int(style_seed), float(intensity), float(speed),
                      len(self.segments))
        self.segments.append(seg)
        return seg

    def add_trial(self, gesture: str, start: int, frames: int, intensity: float,
                  speed: float, style_seed: int,
                  press: tuple[float, ...] | None = None,
                  shift_mm: tuple[float, float] = (0.0, 0.0)) -> Trial:
        """Schedule a gesture (or, with ``press``, a static calibration press);
        ``shift_mm``: performed that far from the person's usual spot (off centre)."""
        name = PRESS if press is not None else canonical_gesture(gesture)
        trial = Trial(name, int(start), max(1, int(frames)), float(intensity), float(speed),
                      int(style_seed), (1, int(start), len(self.trials)), press,
                      (float(shift_mm[0]), float(shift_mm[1])))
        starts = [t.start for t in self.trials]
        self.trials.insert(bisect.bisect_right(starts, trial.start), trial)
        return trial

    # ---- queries ---------------------------------------------------------------------
    def trial_at(self, frame: int) -> Trial | None:
        """The trial being performed at ``frame`` (None when nothing is scheduled)."""
        for trial in reversed(self.trials):
            if trial.start <= frame < trial.stop:
                return trial
        return self._background(frame)

    def gesture_at(self, frame: int) -> str:
        trial = self.trial_at(frame)
        return trial.gesture if trial is not None else IDLE

    def pieces(self, start: int, stop: int) -> list[tuple[Trial | None, int, int]]:
        """Split frames [start, stop) into runs with one trial (or None) each."""
        out: list[tuple[Trial | None, int, int]] = []
        f = start
        while f < stop:
            trial = self.trial_at(f)
            nxt = min(stop, self._next_change(f, trial))
            out.append((trial, f, nxt))
            f = nxt
        return out

    # ---- internals -------------------------------------------------------------------
    def _segment_at(self, frame: int) -> Segment | None:
        starts = [s.start for s in self.segments]
        i = bisect.bisect_right(starts, frame) - 1
        return self.segments[i] if i >= 0 else None

    def _background(self, frame: int) -> Trial | None:
        seg = self._segment_at(frame)
        if seg is None or seg.mode == IDLE:
            return None
        origin = self._origin(seg)
        rel = frame - origin
        if rel < 0:
            return None
        if seg.mode != AUTO:
            j = rel // self.trial_frames
            return Trial(seg.mode, origin + j * self.trial_frames, self.trial_frames,
                         seg.intensity, seg.speed, seg.style_seed, (2, seg.index, j))
        cycle = self.trial_frames + self.gap_frames
        j = rel // cycle
        if rel - j * cycle >= self.trial_frames:
            return None
        order = self._block_order(seg.index, j // 9)
        return Trial(GESTURE_NAMES[int(order[j % 9])], origin + j * cycle, self.trial_frames,
                     seg.intensity, seg.speed, seg.style_seed, (3, seg.index, j))

    def _origin(self, seg: Segment) -> int:
        """First frame of a segment's first trial: the demo, and whatever mode the sensor
        starts in, begin with ``lead_s`` of idle so the engine's tare sees no touch."""
        lead = seg.mode == AUTO or seg.index == 0
        return seg.start + (self.lead_frames if lead else 0)

    def _block_order(self, segment: int, block: int) -> np.ndarray:
        """The shuffled gesture order of one demo block (a protocol-style random block)."""
        key = (segment, block)
        if key not in self._orders:
            if len(self._orders) > 256:
                self._orders.clear()
            rng = np.random.default_rng([self.seed, 0xA070, segment, block])
            self._orders[key] = rng.permutation(len(GESTURE_NAMES))
        return self._orders[key]

    def _next_change(self, frame: int, current: Trial | None) -> int:
        """The first frame after ``frame`` at which the active trial may change."""
        cands = [t.start for t in self.trials if t.start > frame]
        cands += [t.stop for t in self.trials if t.start <= frame < t.stop]
        cands += [s.start for s in self.segments if s.start > frame]
        if current is not None:
            cands.append(current.stop)
        seg = self._segment_at(frame)
        if seg is not None and seg.mode != IDLE and current is None:
            origin = self._origin(seg)
            if frame < origin:
                cands.append(origin)
            elif seg.mode == AUTO:
                cycle = self.trial_frames + self.gap_frames
                cands.append(origin + ((frame - origin) // cycle + 1) * cycle)
        later = [c for c in cands if c > frame]
        return min(later) if later else 1 << 62
