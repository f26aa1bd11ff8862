"""Helpers for the collection-runner tests: a real simulated sensor, engine and session
file, a manual clock for the countdown logic, and a loop that drives the runner."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.protocol.collect import (
    Collection,
    CollectionSettings,
    open_collection,
    resume_collection,
)
from tactile_studio.protocol.trial_runner import StreamClock
from tactile_studio.protocol.virtual import VirtualParticipant
from tactile_studio.storage.format.protocol_file import CollectionProtocol, load_protocol

TIMEOUT_S = 15.0  # a safety net for a hung loop, never a timing assertion


class ManualClock:
    """A clock that moves only when told: breaks and pauses become exact."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += seconds


@dataclass
class Beeps:
    asked: list[tuple[float, float]] = field(default_factory=list)

    def play(self, frequency_hz: float, length_s: float) -> None:
        self.asked.append((frequency_hz, length_s))


def mini_protocol(n_gestures: int = 3, **overrides: Any) -> CollectionProtocol:
    """shear9 cut down to a few gestures and short phases, to keep tests fast."""
    base = load_protocol("shear9")
    data = {"gestures": base.to_dict()["gestures"][:n_gestures], "blocks": 2,
            "free_play_s": 0.0, "break_every": 0, "break_min_s": 0.0, "beep_s": 0.05}
    data.update(overrides)
    return base.with_overrides(**data)


@dataclass
class Rig:
    session: Collection
    device: SimulatedSensor
    engine: AcquisitionEngine
    beeps: Beeps
    clock: Any

    @property
    def runner(self):  # noqa: ANN201
        return self.session.runner

    def close(self) -> None:
        self.session.close()
        self.engine.stop()


def make_rig(tmp_path: Path, protocol: CollectionProtocol, participant: str = "P01", *,
             speed: float = 40.0,
             clock: Any = None, resume: Path | None = None, seed: int = 0,
             capacity: int = 1 << 16, **options: Any) -> Rig:
    device = SimulatedSensor(speed=speed, gesture="idle", seed=seed,
                             **options.pop("sim", {}))
    engine = AcquisitionEngine(device, capacity=capacity)
    beeps = Beeps()
    clk = clock if clock is not None else StreamClock(engine)
    if resume is not None:
        session = resume_collection(resume, engine, beeper=beeps, clock=clk, **options)
    else:
        session = open_collection(CollectionSettings(protocol, participant, tmp_path, seed=seed,
                                                     **options), engine, beeper=beeps, clock=clk)
    engine.start()
    return Rig(session, device, engine, beeps, clk)


def drive(rig: Rig, until, vp: Any = None, timeout: float = TIMEOUT_S) -> None:
    """Tick (and let the virtual participant act) until ``until()`` is true."""
    deadline = time.monotonic() + timeout
    while not until():
        if time.monotonic() > deadline:
            raise AssertionError(f"runner stuck in {rig.runner.state}: {rig.runner.hint}")
        rig.runner.tick()
        if vp is not None:
            vp.step()
        time.sleep(0.002)


def run_virtual_participant(rig: Rig, participant: str, seed: int = 0) -> None:
    """A virtual participant does the whole session; the rig is closed after."""
    vp = VirtualParticipant(rig.runner, rig.device, participant, seed=seed)
    vp.prepare()  # the engine is already running: it plans from the device's next frame
    try:
        drive(rig, lambda: rig.runner.state == "finished", vp=vp)
    finally:
        rig.close()


def start(rig: Rig) -> None:
    """Start the runner once the baseline is in, and wait for the first key state."""
    rig.runner.start()
    drive(rig, lambda: rig.runner.state == "waiting_for_key")


def perform_soon(rig: Rig, gesture: str | None = None, press: tuple | None = None) -> int:
    """Schedule a gesture (or a static press) a little ahead of the running stream and
    wait until the stream has passed its first frame; returns that frame."""
    while True:
        frame = rig.device.next_frame + 20
        try:
            if gesture is not None:
                rig.device.perform(gesture, rig.runner.protocol.trial_s, at_frame=frame)
            if press is not None:
                with rig.device._lock:  # noqa: SLF001 - the plugin's lock guards its simulator
                    rig.device.simulator.press(*press, at_frame=frame)
            break
        except ValueError:  # the stream overtook us (a loaded machine): try further ahead
            continue
    drive(rig, lambda: rig.engine.frames > frame)
    return frame


def do_trial(rig: Rig, gesture: str, perform: bool = True) -> dict:
    """Perform ``gesture`` on the sensor, press its key as it starts, wait for the save."""
    r = rig.runner
    frame = perform_soon(rig, gesture if perform else None)
    n_before = len(r.trials)
    assert r.key(r.protocol.gesture_by_name(gesture).key, at_frame=frame), r.hint
    drive(rig, lambda: len(r.trials) > n_before)
    if isinstance(rig.clock, ManualClock):
        rig.clock.advance(r.protocol.beep_s)  # the beep plays out
    drive(rig, lambda: r.state != "trial_end")
    return r.trials[-1]
