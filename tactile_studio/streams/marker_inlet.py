"""Markers from other programs (an experiment script, a stimulus PC) into the recording:
``record`` / ``collect`` ``--markers NAME``.

For each named LSL marker stream (string channels, found by name) an inlet is pulled in
one thread. A sample stamped ``ts`` on the sender's clock is put on this machine's LSL
clock with the inlet's ``time_correction()`` and on the host clock (the frames'
``host_time``) with the measured host->LSL offset (streams/clock.py):
``host = ts + correction - offset_s``. It becomes an engine event ``marker`` (``text``,
``stream``, ``lsl_time``, ``time_correction``, ``offset_s``, ``source: lsl``) at the frame
whose host time is nearest, so the recorder writes it at that row and the player and
exports show it. What the sender says is content: a sample of several channels keeps
each (``channels``; ``text`` joins them: foreign.marker_content), and is never read as
fields of our records. A marker stamped ahead of the newest frame waits for that frame.

A stream that disappears (its sender quit) is reported once: an engine event
``marker_stream_lost`` and ``on_problem(message)``. Each stream's start is an event
``marker_stream`` (name, source_id, hostname, time_correction, offset_s).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from tactile_studio.devices.engine_events import LslMarker, MarkerStreamLost, MarkerStreamOpened
from tactile_studio.devices.ring import nearest_frame
from tactile_studio.errors import DeviceNotFound
from tactile_studio.foreign import marker_content
from tactile_studio.streams.clock import measure_offset
from tactile_studio.streams.lsl_lib import load_pylsl
from tactile_studio.terminal import shown

FIND_TIMEOUT_S = 5.0
PULL_S = 0.05
WAIT_FOR_FRAME_S = 1.0   # a marker ahead of the frames gets the newest frame after this
# liblsl's channel_format codes (pylsl's cf_*)
FORMAT_NAMES = {1: "float32", 2: "double64", 4: "int32", 5: "int16", 6: "int8", 7: "int64"}


class MarkerInlets:
    """Inlets on the named marker streams, feeding ``engine`` events (module doc)."""

    def __init__(self, engine: Any, names: Sequence[str], find_timeout: float = FIND_TIMEOUT_S,
                 on_problem: Callable[[str], None] | None = None) -> None:
        self.pylsl = load_pylsl()
        self.engine = engine
        self.on_problem = on_problem or (lambda message: None)
        self.offset = measure_offset(self.pylsl.local_clock)
        self.inlets: list[tuple[str, Any, float]] = []
        self.received = 0
        self.lost: list[str] = []
        for name in dict.fromkeys(names):
            found = self.pylsl.resolve_byprop("name", name, 1, find_timeout)
            strings = [i for i in found if i.channel_format() == self.pylsl.cf_string]
            if found and not strings:
                fmt = FORMAT_NAMES.get(found[0].channel_format(), "numeric")
                raise DeviceNotFound(f"lsl: stream '{shown(name)}' was found but is a {fmt} "
                                     "stream, not a string (marker) stream: name the "
                                     "program's marker stream")
            if not strings:
                raise DeviceNotFound(f"lsl: marker stream '{shown(name)}' was not found "
                                     f"within {find_timeout:g} s (is the program that "
                                     "sends it running?)")
            inlet = self.pylsl.StreamInlet(strings[0], max_buflen=360, recover=False)
            try:
                inlet.open_stream(find_timeout)
                correction = float(inlet.time_correction(find_timeout))
            except Exception:  # noqa: BLE001 - pylsl's LostError / TimeoutError
                raise DeviceNotFound(f"lsl: marker stream '{shown(name)}' went away while "
                                     "connecting to it") from None
            info = strings[0]
            engine.add_event(MarkerStreamOpened(name, info.source_id(), info.hostname(),
                                                correction, self.offset.offset_s))
            self.inlets.append((name, inlet, correction))
        self._pending: list[tuple[float, LslMarker, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lsl-markers", daemon=True)
        self._thread.start()

    # ---- lifecycle (an outlet-like: LiveAcquisition.add_outlet stops it first) -------
    def stop(self) -> None:
        """Take what has arrived, place the waiting markers, stop."""
        self._stop.set()
        self._thread.join(5.0)
        self._pull_all()
        self._place(final=True)
        self.inlets = []

    def _run(self) -> None:
        while not self._stop.wait(PULL_S):
            self._pull_all()
            self._place()

    def _pull_all(self) -> None:
        for k, (name, inlet, correction) in enumerate(list(self.inlets)):
            if name in self.lost:
                continue
            try:
                samples, stamps = inlet.pull_chunk(timeout=0.0)
            except Exception:  # noqa: BLE001 - pylsl.LostError: the sender went away
                self._lost(name)
                continue
            if samples:  # liblsl refreshes its estimate every few seconds; ask it now
                try:
                    correction = float(inlet.time_correction(0.5))
                except Exception:  # noqa: BLE001 - gone meanwhile: the last estimate stands
                    pass
                self.inlets[k] = (name, inlet, correction)
            for sample, ts in zip(samples, stamps):
                lsl_time = float(ts) + correction
                content = marker_content(sample)
                channels = content.get("channels")
                marker = LslMarker(content["text"], name, lsl_time, correction,
                                   self.offset.offset_s,
                                   None if channels is None else tuple(channels))
                self._pending.append((self.offset.to_host(lsl_time), marker, time.monotonic()))
                self.received += 1

    def _lost(self, name: str) -> None:
        self.lost.append(name)
        self.engine.add_event(MarkerStreamLost(name))
        self.on_problem(f"lsl: marker stream '{shown(name)}' disappeared (its sender stopped); "
                        "later markers from it are not recorded")

    def _place(self, final: bool = False) -> None:
        """Markers whose frame has arrived (or waited long enough) -> engine events."""
        if not self._pending:
            return
        # every frame the ring keeps, read at once: a marker stamped before the first
        # frame goes to frame 0 however late it arrives (the newest 8192 frames, read
        # after the count, put one at frame 1, or at the window's first frame)
        start, t = self.engine.ring.host_times()
        keep = []
        for host, marker, arrived in sorted(self._pending, key=lambda p: p[0]):
            if not len(t):
                if final:
                    self.engine.add_event(marker, at=host)
                else:
                    keep.append((host, marker, arrived))
                continue
            ahead = host > t[-1]
            if ahead and not final and time.monotonic() - arrived < WAIT_FOR_FRAME_S:
                keep.append((host, marker, arrived))
                continue
            self.engine.add_event(marker, frame=start + nearest_frame(t, host), at=host)
        self._pending = keep

