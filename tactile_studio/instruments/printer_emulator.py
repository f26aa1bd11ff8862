"""A Marlin-style 3D printer on a pty, for testing the ``gcode`` stage without hardware.

Understands G28 (home), G90, G0/G1 with X Y Z F (moves run in real time at the feed rate,
queued as Marlin's planner does; "ok" as soon as a move is queued), M400 (ok when every
move finished; "echo:busy: processing" every ``busy_s`` meanwhile), M114 (position now),
M204 (acceleration), M410 (quick stop: moves abandoned where the head is). Replies
"Error:..." to moves outside the bed, before homing, to ``fail_home`` homing and once
after :meth:`inject_error`; "echo:Unknown command" otherwise. :meth:`unplug` is a pulled
cable. Used in-process by tests and by ``tactile-studio emulate-printer``.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable

import numpy as np

from tactile_studio.devices.pty_port import PtyPort
from tactile_studio.instruments.pty_emulator import PtyEmulator

_WORD = re.compile(r"([A-Z])\s*(-?\d+(?:\.\d*)?)")


class PrinterEmulator(PtyEmulator):
    thread_name = "printer-emulator"

    def __init__(self, link: str | None = None, bed: tuple[float, ...] = (0, 220, 0, 220, 0, 200),
                 fail_home: bool = False, home_s: float = 0.2, busy_s: float = 1.0,
                 home: tuple[float, float, float] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.pty = PtyPort(link)
        self.bed = bed
        self.fail_home, self.home_s, self.busy_s = fail_home, home_s, busy_s
        self.clock = clock
        self.homed = False
        self.feed = 1000.0  # mm/min
        self.received: list[str] = []
        self.stopped_at: list[np.ndarray] = []  # where each M410 quick stop left the head
        self._moves: list[tuple[float, np.ndarray, np.ndarray, float]] = []  # t0, p0, p1, dur
        self.home = np.array(home if home is not None else (0.0, 0.0, float(bed[5])), float)
        self._pos = self.home.copy()
        self._error: str | None = None
        self._lock = threading.RLock()
        self._init_thread()

    # ---- lifecycle -------------------------------------------------------------------
    def inject_error(self, message: str = "Printer halted. kill() called!") -> None:
        """The next command gets ``Error:<message>`` before its ok."""
        self._error = message

    # ---- motion ----------------------------------------------------------------------
    def position(self, now: float | None = None) -> np.ndarray:
        """Where the head is at ``now`` (default: now), moves interpolated."""
        now = self.clock() if now is None else now
        with self._lock:
            pos = self._pos
            for t0, p0, p1, dur in self._moves:
                if now < t0:
                    break
                frac = 1.0 if dur <= 0 else min(1.0, (now - t0) / dur)
                pos = p0 + (p1 - p0) * frac
            return pos.copy()

    def busy(self) -> bool:
        with self._lock:
            return bool(self._moves) and self.clock() < self._moves[-1][0] + self._moves[-1][3]

    def _queue(self, target: np.ndarray) -> None:
        now = self.clock()
        with self._lock:
            if self._moves and now >= self._moves[-1][0] + self._moves[-1][3]:
                self._pos = self._moves[-1][2].copy()
                self._moves.clear()
            start = max(now, self._moves[-1][0] + self._moves[-1][3]) if self._moves else now
            p0 = self._moves[-1][2] if self._moves else self._pos
            dur = float(np.linalg.norm(target - p0)) / (self.feed / 60.0)
            self._moves.append((start, p0.copy(), target, dur))

    def _quickstop(self) -> None:
        with self._lock:
            self._pos = self.position()
            if self.busy():
                self.stopped_at.append(self._pos.copy())
            self._moves.clear()

    # ---- protocol --------------------------------------------------------------------
    def _reply(self, *lines: str) -> None:
        self.pty.write("".join(f"{ln}\n" for ln in lines).encode())

    def _run(self) -> None:
        while not self._stop.is_set():
            if not self.pty.is_open:
                time.sleep(0.01)
                continue
            for line in self.pty.read_lines(0.01):
                line = line.split(";")[0].strip().upper()
                if line:
                    self.received.append(line)
                    self._handle(line)

    def _handle(self, line: str) -> None:
        code, _, rest = line.partition(" ")
        words = {k: float(v) for k, v in _WORD.findall(rest)}
        if self._error is not None:
            msg, self._error = self._error, None
            self._reply(f"Error:{msg}", "ok")
            return
        if code == "G28":
            time.sleep(self.home_s)
            if self.fail_home:
                self._reply("Error:Homing failed: Z endstop not triggered", "ok")
                return
            self._quickstop()
            with self._lock:
                self._pos = self.home.copy()
            self.homed = True
            self._reply("ok")
        elif code in ("G0", "G1"):
            if not self.homed:
                self._reply("Error:Home XYZ first", "ok")
                return
            if "F" in words:
                self.feed = words["F"]
            cur = self._moves[-1][2] if self._moves else self._pos
            target = np.array([words.get(a, cur[i]) for i, a in enumerate("XYZ")])
            lo, hi = np.array(self.bed[0::2]), np.array(self.bed[1::2])
            if np.any(target < lo) or np.any(target > hi):
                self._reply(f"Error:Move out of range: X{target[0]:.2f} Y{target[1]:.2f} "
                            f"Z{target[2]:.2f}", "ok")
                return
            self._queue(target)
            self._reply("ok")
        elif code == "M400":
            next_busy = self.clock() + self.busy_s
            while self.busy() and not self._stop.is_set() and self.pty.is_open:
                if self.clock() >= next_busy:
                    self._reply("echo:busy: processing")
                    next_busy += self.busy_s
                time.sleep(0.005)
            self._reply("ok")
        elif code == "M114":
            p = self.position()
            self._reply(f"X:{p[0]:.3f} Y:{p[1]:.3f} Z:{p[2]:.3f} E:0.00 Count X:0 Y:0 Z:0", "ok")
        elif code == "M410":
            self._quickstop()
            self._reply("ok")
        elif code in ("G90", "M204", "M84", "M110", "M115"):
            self._reply("ok")
        else:
            self._reply(f'echo:Unknown command: "{line}"', "ok")
