"""A beep as PCM samples, without Qt: the GUI's beeper plays these bytes.

Kept in the core so the tone is testable and reusable (a CLI could write it to a WAV).
The short raised-cosine fade at both ends keeps the speaker from clicking.
"""

from __future__ import annotations

import numpy as np

SAMPLE_RATE = 44_100


def tone_samples(frequency_hz: float, length_s: float, sample_rate: int = SAMPLE_RATE,
                 volume: float = 0.5, fade_s: float = 0.005) -> np.ndarray:
    """A sine tone as int16 samples (mono), faded in and out over ``fade_s``."""
    if frequency_hz <= 0 or length_s <= 0:
        raise ValueError("frequency and length must be positive")
    if not 0.0 <= volume <= 1.0:
        raise ValueError("volume must be in 0..1")
    n = max(1, int(round(length_s * sample_rate)))
    t = np.arange(n) / sample_rate
    wave = np.sin(2 * np.pi * frequency_hz * t)
    k = min(n // 2, int(fade_s * sample_rate))
    if k > 0:
        ramp = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, k))
        wave[:k] *= ramp
        wave[n - k:] *= ramp[::-1]
    return np.round(wave * volume * 32767).astype(np.int16)


def tone_pcm(frequency_hz: float, length_s: float, sample_rate: int = SAMPLE_RATE,
             volume: float = 0.5) -> bytes:
    """The same tone as little-endian signed 16-bit mono PCM bytes (what QAudioSink plays)."""
    return tone_samples(frequency_hz, length_s, sample_rate, volume).astype("<i2").tobytes()
