"""Long jobs: progress reporting and cooperative cancellation, shared by CLI and GUI.

A long job is a plain function taking ``progress`` (a callable ``(fraction, message)``)
and ``cancel`` (a ``CancelToken``). It calls ``cancel.check()`` between units of work,
which raises ``Cancelled``; whatever the job finished before that is kept by the job.
The CLI wires Ctrl-C to the token; the GUI wires a Cancel button.
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
import time
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from tactile_studio.errors import Cancelled
from tactile_studio.terminal import printable, raw_stream

ProgressFn = Callable[[float, str], None]


def no_progress(fraction: float, message: str = "") -> None:
    """The default progress callback: ignore."""


def about(seconds: float) -> str:
    """A duration as a person plans with it: "about 40 s", "about 3 min", "about 14 h"
    (two significant units at most; estimates are never more precise than that)."""
    s = max(0.0, float(seconds))
    if s < 60:
        return f"about {max(1, round(s))} s"
    if s < 3600:
        m, rest = divmod(round(s), 60)
        return f"about {m} min" + (f" {rest} s" if m < 3 and rest else "")
    h, m = divmod(round(s / 60), 60)
    return f"about {h} h" + (f" {m} min" if h < 10 and m else "")


class CancelToken:
    def __init__(self) -> None:
        self._event = threading.Event()

    def cancel(self) -> None:
        self._event.set()

    @property
    def cancelled(self) -> bool:
        return self._event.is_set()

    def check(self) -> None:
        if self._event.is_set():
            raise Cancelled("cancelled")

    def wait(self, seconds: float) -> bool:
        """Sleep up to ``seconds``; True if cancelled meanwhile."""
        return self._event.wait(seconds)


def interactive(stream) -> bool:  # noqa: ANN001
    """True when ``stream`` is a terminal a live display may redraw: not under CI
    (``CI=true``), not ``TERM=dumb``, and ``isatty()``."""
    if os.environ.get("CI", "").strip().lower() in ("1", "true", "yes"):
        return False
    if os.environ.get("TERM") == "dumb":
        return False
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty and isatty())
    except (ValueError, OSError):  # a closed stream
        return False


class TerminalProgress:
    """Progress of a long job on stderr, called like any ``ProgressFn``.

    In a terminal: a rich progress display (bar, percent, elapsed, ETA, rate, message)
    with optional nested rows (:meth:`subtask`, e.g. a fold inside a round). Piped, under
    CI or on a dumb terminal: plain lines, one per 10% step and one at the end, with no
    control characters, so logs stay readable and parseable. ``total``/``unit`` turn the
    fraction into units for the rate column (e.g. 600 ``s`` of recording).
    """

    def __init__(self, label: str, stream=None, width: int = 30,  # noqa: ANN001
                 total: float | None = None, unit: str = "") -> None:
        self.label, self.width = label, width
        self.stream = stream or sys.stderr
        self.total, self.unit = (total, unit) if total else (100.0, "%")
        self.live = interactive(self.stream)
        self._progress = None
        self._task = None
        self._subtasks: dict[str, Any] = {}
        self._start = time.monotonic()
        self._step = -1
        self._done = False

    # ---- the ProgressFn interface ----------------------------------------------------
    def __call__(self, fraction: float, message: str = "") -> None:
        fraction = min(max(fraction, 0.0), 1.0)
        if self._done:
            return
        if self.live:
            self._rich(fraction, message)
        else:
            self._plain(fraction, message)
        if fraction >= 1.0:
            self.close()

    def _plain(self, fraction: float, message: str) -> None:
        step = int(fraction * 10)
        if step == self._step and fraction < 1.0:
            return
        self._step = step
        text = "".join(c for c in message if c.isprintable())[:80]
        tail = f" ({time.monotonic() - self._start:.1f} s)" if fraction >= 1.0 else ""
        self.stream.write(f"{self.label} [{fraction * 100:3.0f}%] {text}{tail}".rstrip() + "\n")
        self.stream.flush()

    def _rich(self, fraction: float, message: str) -> None:
        if self._progress is None:
            self._progress = _rich_progress(self.stream, self.width)
            self._progress.start()
            _LIVE.add(self)
            self._task = self._progress.add_task(_shown(self.label, 200), total=self.total,
                                                 unit=self.unit, message="")
        self._progress.update(self._task, completed=fraction * self.total,
                              message=_shown(message))

    # ---- nested rows -----------------------------------------------------------------
    def subtask(self, key: str, label: str, completed: float, total: float | None,
                message: str = "", unit: str = "") -> None:
        """Create or update the nested row ``key`` (shown in a terminal only): ``total``
        None gives an indeterminate bar (e.g. epochs until early stopping)."""
        if not self.live or self._done:
            return
        if self._progress is None:
            self._rich(0.0, "")
        new = key not in self._subtasks
        if new:
            self._subtasks[key] = self._progress.add_task(f"  {_shown(label)}", total=total,
                                                          unit=unit, message="")
        self._progress.update(self._subtasks[key], description=f"  {_shown(label)}",
                              total=total, completed=completed, message=_shown(message),
                              refresh=new)

    def end_subtask(self, key: str) -> None:
        task = self._subtasks.pop(key, None)
        if task is not None and self._progress is not None:
            self._progress.remove_task(task)

    def close(self) -> None:
        """Stop the display and end its line (a job that stops early: error, Ctrl-C), so
        whatever is printed next starts on a line of its own."""
        self._done = True
        if self._progress is not None:
            for key in list(self._subtasks):
                self.end_subtask(key)
            self._progress.stop()
            self._progress = None
            _LIVE.discard(self)


def _shown(text: str, limit: int = 60) -> str:
    """A message for the live display: printable (it may name a file or a peer), no rich
    markup (a ``[red]`` in a name stays text), at most ``limit`` characters."""
    from rich.markup import escape

    return escape(printable(text[:limit]))


_LIVE: weakref.WeakSet[TerminalProgress] = weakref.WeakSet()


@atexit.register
def _stop_live_displays() -> None:
    """A job that ended by an exception without closing its display still gives the
    terminal back (cursor shown, line ended) when the program exits."""
    for bar in list(_LIVE):
        bar.close()


def _rich_progress(stream, width: int):  # noqa: ANN001, ANN202
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        ProgressColumn,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class RateColumn(ProgressColumn):
        def render(self, task) -> Text:  # noqa: ANN001
            speed, unit = task.speed, task.fields.get("unit", "")
            if not speed or not unit:
                return Text("")
            if unit == "%" and speed < 1:
                return Text(f"{speed * 60:.1f} %/min", style="progress.data.speed")
            return Text(f"{speed:.1f} {unit}/s", style="progress.data.speed")

    console = Console(file=raw_stream(stream))  # draws itself; its texts are _shown
    return Progress(TextColumn("{task.description}"), BarColumn(bar_width=width),
                    TaskProgressColumn(), TimeElapsedColumn(), TextColumn("ETA"),
                    TimeRemainingColumn(), RateColumn(), TextColumn("{task.fields[message]}"),
                    console=console, redirect_stdout=False, redirect_stderr=True,
                    refresh_per_second=8)


class Terminated(KeyboardInterrupt):
    """SIGTERM (a ``kill``, a job scheduler, a shutdown) reached a command: it unwinds like
    Ctrl-C, so ``finally`` blocks and exit handlers close open files."""


@contextmanager
def signals_handled(handler: Callable[[int, Any], None],
                    *signals: signal.Signals) -> Iterator[Callable[[], None]]:
    """While active, ``handler`` handles ``signals``; the previous handlers come back at
    the end, or earlier through the function it yields. Outside the main thread Python
    cannot set handlers: nothing changes there."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    previous = {sig: signal.signal(sig, handler) for sig in signals}

    def restore() -> None:
        for sig, old in previous.items():
            signal.signal(sig, old)

    try:
        yield restore
    finally:
        restore()


@contextmanager
def signals_deferred() -> Iterator[None]:
    """While active, Ctrl-C and SIGTERM wait: a step that must finish once begun (the
    characterisation stage lifting its indenter off the sensor) is not cut by a second
    Ctrl-C. A signal that came meanwhile is raised at the end (KeyboardInterrupt or
    :class:`Terminated`), so the command still stops."""
    came: list[int] = []

    def hold(signum: int, frame: object) -> None:
        came.append(signum)
        sys.stderr.write("\nfinishing a step that must not be cut (it takes a moment)...\n")

    with signals_handled(hold, signal.SIGINT, signal.SIGTERM):
        yield
    if came:
        raise Terminated if came[0] == signal.SIGTERM else KeyboardInterrupt


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated


@contextmanager
def terminate_unwinds() -> Iterator[None]:
    """While active, SIGTERM raises :class:`Terminated` in the main thread instead of
    ending the process on the spot (which would skip every cleanup, leaving a
    recording's file to be repaired and a sweep's workers running)."""
    with signals_handled(_raise_terminated, signal.SIGTERM):
        yield


@contextmanager
def ctrl_c_cancels(token: CancelToken) -> Iterator[CancelToken]:
    """While active, the first Ctrl-C or SIGTERM sets ``token`` (the job stops cleanly,
    keeping what it finished); a second one interrupts at once."""

    def handler(signum, frame):  # noqa: ANN001
        if token.cancelled:
            restore()
            raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt
        why = "" if signum == signal.SIGINT else " on SIGTERM"
        sys.stderr.write(f"\nstopping{why} (Ctrl-C again to interrupt at once)...\n")
        token.cancel()

    with signals_handled(handler, signal.SIGINT, signal.SIGTERM) as restore:
        yield token
