"""A full shear9 session (52 blocks, 468 trials) headless with a virtual participant,
as fast as the simulator goes: wall time, trials per second, file size, and how far the
key presses lag the stream (what the runner's at_frame handling absorbs), and how long
the tick that ends a trial takes (the recorder catches up with the trial's frames and
writes and flushes the trial on the runner's thread)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.protocol.collect import CollectionSettings, open_collection
from tactile_studio.protocol.runner_events import TrialStarted
from tactile_studio.protocol.trial_runner import State, StreamClock
from tactile_studio.protocol.virtual import VirtualParticipant
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.session_file import SessionFile


def run(speed: float, blocks: int | None = None) -> None:
    protocol = load_protocol("shear9")
    if blocks:
        protocol = protocol.with_overrides(blocks=blocks)
    with tempfile.TemporaryDirectory() as tmp:
        device = SimulatedSensor(speed=speed, gesture="idle")
        engine = open_stream(device, capacity=1 << 18 if speed == 0 else 1 << 16)
        session = open_collection(CollectionSettings(protocol, "P01", Path(tmp)), engine,
                                  clock=StreamClock(engine))
        vp = VirtualParticipant(session.runner, device, "P01")
        vp.prepare()
        lags: list[int] = []
        saves: list[float] = []
        session.runner.add_listener(
            lambda e: lags.append(engine.frames - e.start_frame)
            if isinstance(e, TrialStarted) else None)
        t0 = time.perf_counter()
        engine.start()
        while session.runner.state not in State.DONE:
            before = (session.runner.state, len(session.runner.trials))
            t = time.perf_counter()
            session.runner.tick()
            if len(session.runner.records) > before[1]:
                saves.append(time.perf_counter() - t)
            n, t = len(session.runner.records), time.perf_counter()
            acted = vp.step()  # a late key press can end its trial at once
            if len(session.runner.records) > n:
                saves.append(time.perf_counter() - t)
            if not acted and (session.runner.state, len(session.runner.trials)) == before:
                time.sleep(0.002)
        wall = time.perf_counter() - t0
        session.close()
        streamed = engine.frames  # at speed 0 the simulator runs ahead of the runner
        engine.stop()
        with SessionFile(session.path) as s:
            n, trials, frames = len(s.trials), s.trials, s.n_frames
        size = session.path.stat().st_size / 1e6
        ok = sum(t["status"] == "ok" for t in trials)
        flagged = sum(bool(t["flags"]) for t in trials)
        print(f"speed {speed:g}: {n} trials ({ok} ok, {flagged} flagged) in {wall:.1f} s wall, "
              f"{frames} frames in the file ({frames / 43.0 / 60:.1f} min of sensor time; "
              f"{streamed} generated, the simulator running ahead), {size:.1f} MB; "
              f"key-press lag behind the stream: median {sorted(lags)[len(lags) // 2]} "
              f"frames, max {max(lags)}; replanned {vp.replanned}; trial-ending call "
              f"median {1e3 * sorted(saves)[len(saves) // 2]:.1f} ms, max "
              f"{1e3 * max(saves):.1f} ms over {len(saves)}")


def main() -> None:
    run(0.0)          # the whole 52-block protocol, as fast as possible
    run(20.0, blocks=4)


if __name__ == "__main__":
    main()
