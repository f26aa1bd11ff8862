"""Engine ingest with recording AND the LSL outlets on (raw or decoded), with a real LSL
inlet taking every frame on this machine.

Goal (issue 12): at least 5,000 frames/s without drops. Figures: the paced 5 kHz
simulated stream (frames written, recorder drops, LSL frames sent/received, lost), and
the unpaced maximum. Discovery stays on the loopback (liblsl config set in-process).
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from pathlib import Path

LOOPBACK_CFG = """[ports]
IPv6 = disable
[multicast]
ResolveScope = machine
MachineAddresses = {127.0.0.1}
AddressesOverride = {127.0.0.1}
[lab]
SessionID = tactile-studio-bench
[log]
level = -3
"""


def _inlet_counter(source_id: str, counts: dict, stop: threading.Event) -> None:
    import pylsl

    found = pylsl.resolve_bypred(f"source_id='{source_id}'", 1, 10.0)
    if not found:
        return
    inlet = pylsl.StreamInlet(found[0], max_buflen=60)
    inlet.open_stream(10.0)
    counts["connected"] = True
    buf = None
    while not stop.is_set() or inlet.samples_available():
        if buf is None:
            import numpy as np
            buf = np.empty((8192, inlet.channel_count),
                           dtype=np.int32 if inlet.channel_format == pylsl.cf_int32
                           else np.float32)
        _, stamps = inlet.pull_chunk(timeout=0.05, max_samples=8192, dest_obj=buf)
        counts["received"] += len(stamps)
        if stop.is_set() and not len(stamps):
            break


def run(settings: dict, seconds: float, decoded: bool) -> dict:
    from tactile_studio.acquisition.open_stream import open_stream
    from tactile_studio.storage.format.session_file import SessionFile
    from tactile_studio.storage.recording.recorder import Recorder
    from tactile_studio.streams.lsl_outlet import LslStreamer

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.h5"
        engine = open_stream("simulated", settings, capacity=1 << 17)
        recorder = Recorder(engine, path).start()
        lsl = LslStreamer(engine, decoded=decoded, name=f"bench-{os.getpid()}").start()
        counts, stop = {"received": 0, "connected": False}, threading.Event()
        reader = threading.Thread(target=_inlet_counter, args=(lsl.source_id, counts, stop),
                                  daemon=True)
        reader.start()
        deadline = time.monotonic() + 10
        while not counts["connected"] and time.monotonic() < deadline:
            time.sleep(0.02)
        engine.start()
        engine.wait_frames(1)
        f0, t0 = engine.frames, time.perf_counter()
        time.sleep(seconds)
        f1, t1 = engine.frames, time.perf_counter()
        engine.stop()
        deadline = time.monotonic() + 10
        while counts["received"] < engine.frames and time.monotonic() < deadline:
            time.sleep(0.02)  # the outlet thread pushes the rest, the inlet takes it
        lsl.stop()
        stop.set()
        reader.join(10)
        recorder.stop()
        with SessionFile(path) as s:
            written = s.n_frames
        return {"ingest_fps": (f1 - f0) / (t1 - t0), "frames": engine.frames,
                "written": written, "recorder_dropped": recorder.dropped,
                "gaps": engine.gaps, "lsl_sent": lsl.frames_sent, "lsl_lost": lsl.lost,
                "received": counts["received"], "markers": lsl.markers_sent}


def _line(label: str, r: dict) -> str:
    return (f"{label}: {r['ingest_fps']:,.0f} frames/s ingest; written {r['written']:,} of "
            f"{r['frames']:,}, recorder dropped {r['recorder_dropped']}, gaps {r['gaps']}; LSL "
            f"sent {r['lsl_sent']:,}, lost {r['lsl_lost']}, inlet received {r['received']:,}")


def main() -> None:
    import pylsl

    pylsl.set_config_content(LOOPBACK_CFG)  # before liblsl's first use: loopback only
    for decoded in (False, True):
        kind = "decoded" if decoded else "raw"
        r = run({"rate": 5000, "speed": 1}, 5.0, decoded)
        print(_line(f"paced 5 kHz + recording + LSL {kind}", r), flush=True)
    r = run({"rate": 5000, "speed": 0}, 5.0, False)
    print(_line("unpaced + recording + LSL raw", r), flush=True)


if __name__ == "__main__":
    main()
