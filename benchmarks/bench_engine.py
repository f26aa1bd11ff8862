"""Engine ingest rate of the simulated 6x6x5 source with recording on.

Goal: at least 5,000 frames/s without drops on 2 cores. Two figures: the maximum
sustained ingest (simulator unpaced), and a paced 5 kHz stream checked for drops. A third:
converting a session file with ``record --device replay --set speed=0`` (as fast as the
recorder writes), frames per second and every frame kept (the README's "a file of any
length" figure).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.recording.recorder import Recorder


def run(settings: dict, seconds: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.h5"
        engine = open_stream("simulated", settings, capacity=1 << 17)
        recorder = Recorder(engine, path).start()
        engine.start()
        engine.wait_frames(1)
        f0, t0 = engine.frames, time.perf_counter()
        time.sleep(seconds)
        f1, t1 = engine.frames, time.perf_counter()
        engine.stop()
        recorder.stop()
        with SessionFile(path) as s:
            written = s.n_frames
        return {"ingest_fps": (f1 - f0) / (t1 - t0), "frames": engine.frames,
                "written": written, "recorder_dropped": recorder.dropped,
                "seq_gaps": engine.gaps, "size_mb": path.stat().st_size / 1e6}


def replay_conversion(frames: int = 300_000) -> None:
    """``record --device replay --set path=SRC --set speed=0 --out DST``, timed."""
    import numpy as np

    from tactile_studio.cli import main as cli
    from tactile_studio.sensor.layout import SHEARSENSE_6X6
    from tactile_studio.storage import SessionWriter

    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "src.h5", Path(tmp) / "copy.h5"
        raw = np.random.default_rng(0).integers(20000, 36000, (frames, 180), dtype=np.uint16)
        t = np.arange(frames) / 43.0
        w = SessionWriter(src, SHEARSENSE_6X6, {"plugin": "bench"})
        w.append_frames(raw, 1.69e9 + t, t)
        w.close()
        t0 = time.perf_counter()
        code = cli(["record", "--device", "replay", "--set", f"path={src}", "--set",
                    "speed=0", "--seconds", "1e6", "--out", str(dst)])  # ends with the file
        wall = time.perf_counter() - t0
        with SessionFile(dst) as s:
            kept = s.n_frames
    print(f"replay at speed 0 into a new recording (record --device replay): {frames:,} "
          f"frames in {wall:.1f} s wall ({frames / wall:,.0f} frames/s), {kept:,} kept, "
          f"exit {code}")


def main() -> None:
    r = run({"rate": 5000, "speed": 0}, 5.0)
    print(f"unpaced simulated source + recording: {r['ingest_fps']:,.0f} frames/s ingest, "
          f"{r['written']:,} of {r['frames']:,} frames written, dropped {r['recorder_dropped']}, "
          f"gaps {r['seq_gaps']}, file {r['size_mb']:.1f} MB")
    r = run({"rate": 5000, "speed": 1}, 5.0)
    print(f"paced 5 kHz source + recording: {r['ingest_fps']:,.0f} frames/s, "
          f"written {r['written']:,} of {r['frames']:,}, dropped {r['recorder_dropped']}, "
          f"gaps {r['seq_gaps']}")
    replay_conversion()


if __name__ == "__main__":
    main()
