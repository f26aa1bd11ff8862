"""The instrument emulators' common part: a thread serving one :class:`PtyPort`."""

from __future__ import annotations

import threading

from tactile_studio.devices.pty_port import PtyPort


class PtyEmulator:
    """An instrument on the other end of a :class:`PtyPort`, served by one thread.

    Subclasses set ``self.pty`` and implement ``_run`` (the serving loop, which ends when
    ``self._stop`` is set); opening, the port path, unplugging and stopping are shared.
    """

    thread_name = "pty-emulator"
    pty: PtyPort

    def _init_thread(self) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def open(self) -> str:
        """Open (or reopen after an unplug) the pty and start serving; returns its path."""
        path = self.pty.open()
        if self._thread is None or not self._thread.is_alive():
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name=self.thread_name,
                                            daemon=True)
            self._thread.start()
        return path

    @property
    def port(self) -> str:
        return self.pty.port

    def unplug(self) -> None:
        """Close the pty as a pulled cable would; ``open()`` plugs it back in."""
        self.pty.close()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self.pty.close()

    def _run(self) -> None:
        raise NotImplementedError
