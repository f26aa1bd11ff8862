"""Live inference: a finished run's model on the live engine's newest frames, in a worker
thread, with smoothing, top-3, measured latency, and prediction events while recording.

Every ``hop_s`` the worker takes the newest window (the run's typical trial length, or
its training window when it trained on windows of long trials) from
the engine's ring, decodes it with the engine's baseline and predicts (window_model.py).
Torch models fed sliding windows instead (unless adapting as they touch) get every new
frame pushed through
learn/deploy/streaming.py's StreamingPredictor (the CNN-Transformer's per-frame embeddings are
computed once and cached) and predict on its newest window.
The smoothed probabilities are the mean of the last ``smoothing`` predictions. Latency is
measured per prediction: from the newest frame's arrival on the host to the probabilities
being ready. A run trained with ``--adapt`` can adapt to the participant as they go
(``RunningCalibration``). When ``recording()`` is true, a change of the smoothed top gesture is
added
to the engine's events (kind ``prediction``), which the recorder writes to the session.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tactile_studio.devices.engine_events import Prediction
from tactile_studio.learn.deploy.window_model import PREDICTION_HOP_S, WindowModel
from tactile_studio.sensor.decode import contact_taxels


@dataclass
class LivePrediction:
    frame: int
    probs: np.ndarray
    smoothed: np.ndarray
    top3: list[tuple[str, float]]
    latency_ms: float
    compute_ms: float


class RunningCalibration:
    """Adapts a run trained with ``--adapt`` to whoever touches the sensor as they go: each
    window is predicted with the statistics of their last ``touches`` windows of contact,
    itself among them (rf/knn features standardised, a network's batch norm
    re-estimated): live's causal form of ``--adapt person``, nothing later is used.

    Replayed on virtual people (benchmarks/bench_calibration.py ``--running 9``, 20
    people) this lifts cnn1d, cnn3d and sefusion 2.6-3.6 points over their training
    statistics (cnn_transformer 1.9, mts3d -0.6); the same trials without the predicted
    one among them gain nothing, and 4 (3 touches and the window) cost cnn1d 2.8 points.
    rf/knn stay within two points of the plain forest. Until ``minimum`` touches are in,
    the model predicts as trained (rf/knn from before they kept a view as trained do not
    predict).

    Statistics of one gesture repeated normalise that gesture away: replayed, free play
    settling on one gesture costs cnn1d 24 points unguarded. So a network adapts only while
    no one gesture, as the model as trained sees each touch when it is kept, is more than
    a share ``alike`` of its last touches (a third; half of 4 gestures, all of 2), and
    predicts as trained otherwise (replayed: that case level with as trained, a protocol of
    shuffled gestures keeps its gain). ``variety`` K, the other guard measured (K different
    gestures or more among them), is off. rf/knn (and fused forests) trained with
    ``--adapt`` judge by their features standardised with the training people's pooled
    statistics (unguarded, free play on one gesture cost the adapted forest 21 points
    against the plain one, cnn1d fused with it 19); runs from before they kept those
    statistics are not guarded."""

    def __init__(self, model: WindowModel, touches: int = 9, minimum: int = 8,
                 alike: float | None = None, variety: int = 0,
                 contact_share: float = 0.05) -> None:
        # contact_share: a light poke touches ~5-15% of a 2 s window
        self.model, self.minimum, self.contact_share = model, minimum, contact_share
        if alike is None:
            alike = max(1 / 3, 2 / max(1, len(model.labels)))
        self.variety = variety if model.has_view_as_trained else 0
        self.alike = alike if model.has_view_as_trained else 1.0
        self.windows: collections.deque[np.ndarray] = collections.deque(maxlen=touches)
        self.ends: collections.deque[int] = collections.deque(maxlen=touches)
        self.seen_as: collections.deque[int] = collections.deque(maxlen=touches)
        self.rate = 0.0  # of the newest window, which every window is read at
        self.adapted = False  # the last window was predicted adapted

    @property
    def count(self) -> int:
        return len(self.windows)

    @property
    def gestures(self) -> int:
        """How many different gestures the kept touches look like as trained."""
        return len(set(self.seen_as))

    @property
    def guarded(self) -> bool:
        return bool(self.variety) or self.alike < 1

    @property
    def ready(self) -> bool:
        """Enough touches, and (guarded) varied enough to adapt to."""
        if self.count < self.minimum or (self.variety and self.gestures < self.variety):
            return False
        return self.most_alike <= self.alike * self.count + 1e-9

    @property
    def most_alike(self) -> int:
        """How many of the kept touches look like the most common gesture as trained."""
        return max(collections.Counter(self.seen_as).values()) if self.seen_as else 0

    def is_touch(self, layout, raw: np.ndarray, baseline: np.ndarray, end: int) -> bool:
        """Raw counts ``raw`` (N, channels) ending at frame ``end`` are a touch when the
        sensor was touched in ``contact_share`` of them and they overlap the last touch
        kept by at most half."""
        if self.ends and end - self.ends[-1] < max(1, len(raw) // 2):
            return False
        touching = contact_taxels(layout, raw, baseline).any(axis=(1, 2))
        return bool(touching.mean() >= self.contact_share)

    def keep(self, layout, frames: np.ndarray, end: int, rate: float) -> None:
        """Keeps decoded ``frames`` (C, N, R, X) as a touch, with the gesture it looks like
        to the model as trained when the touches are guarded."""
        seen = -1
        if self.guarded:
            seen = int(self.model.predict_windows(layout, [frames], rate,
                                                  as_trained=True)[0].argmax())
        self.windows.append(frames)
        self.ends.append(end)
        self.seen_as.append(seen)

    def adapt_for(self, layout, frames: np.ndarray, rate: float, kept: bool) -> None:
        """Before predicting ``frames``: the model calibrated on the last touches with this
        window among them (``kept``: it is the newest touch), or as trained when the
        touches are too few or too alike."""
        self.adapted = self.ready
        if not self.adapted:
            if self.model.calibrated_on.startswith("their last"):
                self.model.uncalibrate()
            return
        recent = list(self.windows)
        if not kept:
            recent = recent[1:] + [frames] if self.count == self.windows.maxlen else \
                recent + [frames]
        self.rate = rate
        self.model.calibrate(layout, recent, rate, f"their last {self.count} touches")

    def prepare(self, layout, raw: np.ndarray, baseline: np.ndarray, frames: np.ndarray,
                end: int, rate: float) -> None:
        """Before predicting the window ``frames`` (decoded from ``raw``): keeps it if it
        is a touch, and adapts the model for it."""
        kept = self.is_touch(layout, raw, baseline, end)
        if kept:
            self.keep(layout, frames, end, rate)
        self.adapt_for(layout, frames, rate, kept)


class LiveInference:
    def __init__(self, engine, model: WindowModel, hop_s: float = PREDICTION_HOP_S,
                 smoothing: int = 4,
                 recording: Callable[[], bool] = lambda: False,
                 adapting: RunningCalibration | None = None) -> None:
        self.engine, self.model, self.adapting = engine, model, adapting
        self.hop_s, self.recording = hop_s, recording
        self.history: collections.deque[np.ndarray] = collections.deque(maxlen=max(1, smoothing))
        self.latest: LivePrediction | None = None
        self.error: str | None = None
        self.count = 0
        self._last_top: str | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="live-inference", daemon=True)
        # adapting re-estimates the network per window: its cached embeddings would go stale
        self.streamer = model.streaming_predictor() if model.streams and not adapting else None
        self._cursor: int | None = None

    def set_smoothing(self, n: int) -> None:
        with self._lock:
            self.history = collections.deque(self.history, maxlen=max(1, int(n)))

    def start(self) -> LiveInference:
        self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        self._thread.join(timeout)

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _stream(self, base: np.ndarray):
        """Push the frames that arrived since the last step; (chunk, probs) or None."""
        eng, sp = self.engine, self.streamer
        if self._cursor is None:
            self._cursor = max(0, eng.frames - sp.window)
        chunk = eng.read_since(self._cursor)
        if len(chunk) == 0:
            return None
        if chunk.start != self._cursor:  # frames were overwritten or lost: start afresh
            sp.reset()
        self._cursor = chunk.stop
        frames = self.model.channels_of(self.model.decode(eng.layout, chunk.raw, base),
                                        eng.layout)
        for frame in frames:
            sp.push(frame)
        return (chunk, sp.predict()) if sp.ready else None

    def step(self) -> LivePrediction | None:
        """One prediction on the newest window (None until the engine has one)."""
        eng = self.engine
        w = self.model.window_for(eng.device_rate_hz() or eng.nominal_rate_hz)
        base = eng.baseline
        if base is None:
            return None
        t0 = time.perf_counter()
        if self.streamer is not None:
            got = self._stream(base)
            if got is None:
                return None
            chunk, probs = got
        else:
            if eng.frames < w:
                return None
            chunk = eng.read_since(eng.frames - w, w)
            if len(chunk) < w:
                return None
            frames = self.model.decode(eng.layout, chunk.raw, base)
            span = float(chunk.device_time[-1] - chunk.device_time[0])
            rate = (w - 1) / span if span > 0 else 43.0
            if self.adapting is not None:
                self.adapting.prepare(eng.layout, chunk.raw, base, frames, chunk.stop, rate)
            if self.model.needs_calibration:
                return None
            probs = self.model.predict_windows(eng.layout, [frames], rate)[0]
        compute = (time.perf_counter() - t0) * 1e3
        latency = (time.time() - float(chunk.host_time[-1])) * 1e3
        with self._lock:
            self.history.append(probs)
            smoothed = np.mean(self.history, axis=0)
        order = np.argsort(-smoothed)[:3]
        top3 = [(self.model.labels[i], float(smoothed[i])) for i in order]
        pred = LivePrediction(chunk.stop - 1, probs, smoothed, top3, latency, compute)
        self.latest = pred
        self.count += 1
        if self.recording() and top3[0][0] != self._last_top:
            eng.add_event(Prediction(top3[0][0], round(top3[0][1], 4), self.model.name))
        self._last_top = top3[0][0]
        return pred

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.step()
            except Exception as exc:  # noqa: BLE001 - shown in the overlay; the thread ends
                self.error = f"{type(exc).__name__}: {exc}"
                return
            self._stop.wait(self.hop_s)
