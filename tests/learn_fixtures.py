"""Session files from virtual participants, made directly with the simulator.

Each participant is one session file: 1 s of idle (its mean is the recorded baseline),
then ``blocks`` blocks of the gestures in a shuffled order, each trial ``trial_s`` long
with a short idle gap, written with SessionWriter + add_trial exactly as the collection
runner writes them. Participants differ by the simulator's per-participant style.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np

from tactile_studio.protocol.virtual import sim_gesture
from tactile_studio.sensor.layout import get_layout
from tactile_studio.simulate import GESTURE_NAMES, SensorSimulator, SimConfig
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.session_writer import SessionWriter


def trial_record(i: int, gesture: str, start: int, stop: int, rate: float = 43.0,
                 block: int = 0, status: str = "ok") -> dict:
    return {"index": i, "block": block, "gesture": gesture, "key": gesture_key(gesture),
            "start_sample": start, "end_sample": stop, "start_time": start / rate,
            "end_time": stop / rate, "status": status, "reason": None, "flags": []}


def gesture_key(gesture: str) -> str:
    """The key a participant presses for ``gesture``: its key in the shipped shear9 or
    cost14 protocol (so a fixture exported as ShearSense CSV imports with its names), else
    the name's first letter."""
    return _shipped_keys().get(gesture, gesture[:1].lower())


@cache
def _shipped_keys() -> dict[str, str]:
    keys = {g.name: g.key for g in load_protocol("cost14").gestures}
    keys.update({g.name: g.key for g in load_protocol("shear9").gestures})
    return keys


def write_participant(path: Path, participant: str, style_seed: int, gestures=GESTURE_NAMES,
                      blocks: int = 3, trial_s: float = 2.0, gap_s: float = 0.4,
                      rate: float = 43.0, sensor_seed: int = 7,
                      extra_trials: list[dict] | None = None, difficulty: str = "easy",
                      condition: str = "FLAT", repeats: int = 1, order: int = 0,
                      **sim: object) -> Path:
    """One session of ``blocks`` x ``gestures`` trials by one virtual participant
    (``difficulty`` easy by default: tests that need clearly separable data rely on it).
    ``repeats`` > 1: each trial is that many back-to-back performances of ``trial_s``, like
    the real recordings' ~12 s performances of a gesture repeated. ``order``: another
    gesture order (a second session of the same person). ``gestures`` may name protocol
    gestures the simulator has no model of (cost14's "tap", "slap"): they are performed
    as the virtual participant performs them, a similar model at its own intensity and
    speed (``protocol.virtual.sim_gesture``), and recorded under their own name."""
    simulator = SensorSimulator(SimConfig(rate=rate, seed=sensor_seed, gesture="idle",
                                          style_seed=style_seed, difficulty=difficulty,
                                          surface=condition.lower(), **sim))
    rng = np.random.default_rng([style_seed, 11] + ([order] if order else []))
    lead, trial_n, gap_n = int(rate), round(trial_s * rate), round(gap_s * rate)
    span = trial_n * repeats
    plan, frame = [], lead
    for b in range(blocks):
        for g in rng.permutation(len(gestures)):
            for r in range(repeats):
                model, intensity, speed = _performed_as(gestures[g])
                simulator.perform(model, trial_s, intensity, speed, at_frame=frame + r * trial_n)
            plan.append((b, gestures[g], frame))
            frame += span + gap_n
    raw = simulator.step(frame)
    t = np.arange(frame) / rate
    meta = {"participant": participant, "protocol": "test-protocol", "condition": condition,
            "gestures": list(gestures), "source": "test:simulator"}
    # a participant's file may be written again (a test that changes the data)
    with SessionWriter(path, simulator.layout, {"name": "simulated"}, meta,
                       overwrite=True) as w:
        w.append_frames(raw, t, 1.7e9 + t)
        w.add_baseline(raw[:lead].mean(axis=0), frame=0)
        for i, (b, g, start) in enumerate(plan):
            w.add_trial(trial_record(i, g, start, start + span, rate, b))
        for extra in extra_trials or []:
            w.add_trial(extra)
    return path


def _performed_as(gesture: str) -> tuple[str, float | None, float | None]:
    """(simulator model, intensity, speed) for ``gesture`` (None: the simulator's own)."""
    if gesture in GESTURE_NAMES:
        return gesture, None, None
    model, intensity, speed = sim_gesture(gesture)
    if model is None:
        raise ValueError(f"{gesture!r} is no touch; a dataset needs touches")
    return model, intensity, speed


def make_dataset_folder(folder: Path, participants: int = 4, blocks: int = 3,
                        gestures=GESTURE_NAMES, trial_s: float = 2.0,
                        first_style: int = 101, conditions: tuple[str, ...] = (),
                        **kw: object) -> list[Path]:
    """``participants`` session files P01.. in ``folder`` (created); with ``conditions``
    (surfaces, e.g. FLAT and PILLOW) one session per participant and condition,
    P01_FLAT.h5 .., each of ``blocks`` blocks in its own gesture order."""
    folder.mkdir(parents=True, exist_ok=True)
    if not conditions:
        return [write_participant(folder / f"P{p + 1:02d}.h5", f"P{p + 1:02d}",
                                  first_style + p, gestures, blocks, trial_s, **kw)
                for p in range(participants)]
    return [write_participant(folder / f"P{p + 1:02d}_{c}.h5", f"P{p + 1:02d}",
                              first_style + p, gestures, blocks, trial_s, condition=c,
                              order=k, **kw)
            for p in range(participants) for k, c in enumerate(conditions)]


def make_virtual_population(folder: Path, population_seed: int, participants: int = 10,
                            blocks: int = 2, **kw: object) -> list[Path]:
    """Ten (``participants``) virtual people as ``collect --virtual-participant --seed S
    --set seed=S`` draws them (style from the participant id and order seed, one
    simulated sensor per population, the simulator's default difficulty):
    the sample issue 37's table compares with the real recordings."""
    from tactile_studio.protocol.virtual import style_seed
    from tactile_studio.simulate.population import DEFAULT_DIFFICULTY

    folder.mkdir(parents=True, exist_ok=True)
    kw = {"difficulty": DEFAULT_DIFFICULTY, "condition": "FLAT", **kw}
    return [write_participant(folder / f"P{p + 1:02d}.h5", f"P{p + 1:02d}",
                              style_seed(f"P{p + 1:02d}", population_seed), blocks=blocks,
                              sensor_seed=population_seed, **kw)
            for p in range(participants)]


def write_pressure_session(path: Path, participant: str, lengths: list[int],
                           layout_name: str = "cost-8x8", seed: int = 0) -> Path:
    """A pressure-only (CoST-like) session: trials of the given lengths, two gestures
    that differ in where and how hard they press."""
    layout = get_layout(layout_name)
    rng = np.random.default_rng(seed)
    rows, cols = layout.rows, layout.cols
    frames, trials, pos = [np.full((10, layout.n_channels), 100.0)], [], 10
    for i, n in enumerate(lengths):
        g = ("pat", "stroke")[i % 2]
        x = np.full((n, rows, cols), 100.0) + rng.normal(0, 2, (n, rows, cols))
        if g == "pat":
            x[:, 2:5, 2:5] += 300 * np.abs(np.sin(np.linspace(0, 6, n)))[:, None, None]
        else:
            col = (np.linspace(0, cols - 1, n)).astype(int)
            x[np.arange(n), 4, col] += 150
        frames.append(x.reshape(n, -1))
        trials.append(trial_record(i, g, pos, pos + n, 135.0))
        pos += n
    raw = np.concatenate(frames).astype(np.float32)
    t = np.arange(len(raw)) / 135.0
    meta = {"participant": participant, "gestures": ["pat", "stroke"], "source": "test"}
    with SessionWriter(path, layout, {"name": "test"}, meta) as w:
        w.append_frames(raw, t, t)
        w.add_baseline(np.full(layout.n_channels, 100.0), frame=0)
        for tr in trials:
            w.add_trial(tr)
    return path
