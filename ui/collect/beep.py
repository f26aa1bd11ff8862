"""The end-of-trial beep, played through QtMultimedia with a generated tone.

Every request is recorded (``requests``) so tests and the console can check what was
asked to play without a speaker. Without an audio output (a headless lab PC, CI, a
broken PulseAudio) it falls back to ``QApplication.beep()`` plus the ``flash`` signal,
which the participant screen turns into a visual flash, and logs why once.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from PySide6.QtCore import QBuffer, QByteArray, QIODevice, QObject, Signal
from PySide6.QtWidgets import QApplication

from tactile_studio.protocol.tone import SAMPLE_RATE, tone_pcm

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BeepRequest:
    """One beep that was asked for, and how it was delivered ("audio" or "fallback")."""

    frequency_hz: float
    length_s: float
    via: str


class QtBeeper(QObject):
    """Plays beeps; ``flash`` is emitted whenever a beep had to fall back."""

    flash = Signal()
    played = Signal(object)  # the BeepRequest

    def __init__(self, parent: QObject | None = None, audio: bool = True,
                 volume: float = 0.5) -> None:
        super().__init__(parent)
        self.volume = volume
        self.requests: list[BeepRequest] = []
        self.fallback_reason: str | None = None
        self._sink = None
        self._buffer: QBuffer | None = None
        self._device = None
        self._format = None
        if audio:
            self._init_audio()
        else:
            self.fallback_reason = "audio disabled"

    def _init_audio(self) -> None:
        try:
            from PySide6.QtMultimedia import QAudioFormat, QMediaDevices
        except ImportError as exc:  # QtMultimedia missing (e.g. no libpulse0)
            self.fallback_reason = f"QtMultimedia unavailable ({exc})"
            return
        device = QMediaDevices.defaultAudioOutput()
        if device.isNull():
            self.fallback_reason = "no audio output device"
            return
        fmt = QAudioFormat()
        fmt.setSampleRate(SAMPLE_RATE)
        fmt.setChannelCount(1)
        fmt.setSampleFormat(QAudioFormat.SampleFormat.Int16)
        if not device.isFormatSupported(fmt):
            self.fallback_reason = f"audio device {device.description()!r} cannot play 16-bit mono"
            return
        self._device, self._format = device, fmt

    @property
    def has_audio(self) -> bool:
        return self._device is not None

    def beep(self, frequency_hz: float, length_s: float) -> BeepRequest:
        """Play a tone now (never blocks); returns what was recorded."""
        via = "audio" if self.has_audio and self._play(frequency_hz, length_s) else "fallback"
        if via == "fallback":
            if self.fallback_reason is None:
                self.fallback_reason = "audio output failed"
            if not any(r.via == "fallback" for r in self.requests):
                log.warning("beep falls back to system beep + visual flash: %s",
                            self.fallback_reason)
            QApplication.beep()
            self.flash.emit()
        req = BeepRequest(float(frequency_hz), float(length_s), via)
        self.requests.append(req)
        self.played.emit(req)
        return req

    # runner-facing alias: the runner's beeper interface calls play(frequency, length)
    play = beep

    def _play(self, frequency_hz: float, length_s: float) -> bool:
        from PySide6.QtMultimedia import QAudio, QAudioSink

        if self._sink is not None:
            self._sink.stop()
        data = QByteArray(tone_pcm(frequency_hz, length_s, SAMPLE_RATE, self.volume))
        self._buffer = QBuffer(self)
        self._buffer.setData(data)
        self._buffer.open(QIODevice.OpenModeFlag.ReadOnly)
        self._sink = QAudioSink(self._device, self._format, self)
        self._sink.start(self._buffer)
        if self._sink.error() != QAudio.Error.NoError:
            self.fallback_reason = f"audio output error {self._sink.error().name}"
            self._device = None
            return False
        return True

    def stop(self) -> None:
        if self._sink is not None:
            self._sink.stop()
