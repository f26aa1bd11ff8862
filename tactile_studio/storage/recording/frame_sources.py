"""Frame sources for the emulators: the simulated sensor, or a recorded file replayed.

A source is ``source(n) -> (n, channels) counts`` (see ``devices.serial_emulator``). They
live here, above devices and the simulator, because a file source reads session and
ShearSense files: the wire emulators themselves know nothing about files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tactile_studio.devices.serial_emulator import FrameSource, array_source
from tactile_studio.errors import UserError
from tactile_studio.simulate import SensorSimulator
from tactile_studio.storage.exchange.shearsense import read_shearsense_csv
from tactile_studio.storage.format.session_file import SessionFile


def simulated_source(seed: int = 0, rate: float = 44.0, block: int = 64) -> FrameSource:
    """The simulated ShearSense sensor (its demo gesture cycle) as a frame source.

    Frames are generated ``block`` at a time: the simulator is much faster in batches,
    and the result is the same (it is deterministic however its calls are sized)."""
    sim = SensorSimulator(rate=float(rate), seed=int(seed))
    buffer = np.empty((0, sim.layout.n_channels), dtype=np.int64)

    def source(n: int) -> np.ndarray:
        nonlocal buffer
        if len(buffer) < n:
            more = sim.step(max(block, n - len(buffer))).astype(np.int64)
            buffer = np.concatenate((buffer, more))
        out, buffer = buffer[:n], buffer[n:]
        return out

    return source


def load_source(spec: str, seed: int = 0, rate: float | None = None) -> tuple[FrameSource, float]:
    """``simulated`` or a file (session .h5 or ShearSense .csv) -> (source, rate in Hz).

    The rate defaults to 44 Hz for the simulator and to the file's own median rate.
    """
    if spec == "simulated":
        r = 44.0 if rate is None else float(rate)
        return simulated_source(seed, r), r
    path = Path(spec)
    if not path.is_file():
        raise UserError(f"emulator source {spec!r}: not 'simulated' and no such file")
    if path.suffix.lower() == ".csv":
        data = read_shearsense_csv(path)
        raw, times = data.raw, np.asarray(data.times, dtype=np.float64)
    else:
        with SessionFile(path) as s:
            raw, times = s.raw(), s.column("device_time")
    if rate is None:
        steps = np.diff(times)
        steps = steps[steps > 0]
        rate = float(1.0 / np.median(steps)) if steps.size else 44.0
    return array_source(raw), float(rate)
