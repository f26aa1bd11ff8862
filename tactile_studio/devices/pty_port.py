"""A pseudo-terminal an emulated device speaks through (the sensor's receiver, the
instruments): the plugins open its slave side with pyserial like any port. ``close``
unplugs it as pulling a USB cable does; ``link`` is a stable symlink re-pointed at each
new pty, since every pty gets a new ``/dev/pts/N``."""

from __future__ import annotations

import os
import select
import threading
import tty
from pathlib import Path

from tactile_studio.errors import UserError


class PtyPort:
    """One pluggable pty: ``open`` plugs in a new one, ``close`` pulls it out."""

    def __init__(self, link: str | os.PathLike | None = None) -> None:
        self.link = Path(link) if link is not None else None
        self.path: str | None = None
        self._master: int | None = None
        self._buf = b""
        self._lock = threading.Lock()

    def open(self) -> str:
        """Plug in a new pty (raw mode); returns the slave path."""
        self._check_link()
        self._close_master()
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no CR/LF translation: bytes arrive as written
        self.path = os.ttyname(slave)
        os.close(slave)  # so the master sees POLLHUP until a reader opens the port
        os.set_blocking(master, False)
        self._master = master
        if self.link is not None:
            tmp = self.link.with_name(f".{self.link.name}.{os.getpid()}.tmp")
            tmp.unlink(missing_ok=True)
            try:
                os.symlink(self.path, tmp)
                os.replace(tmp, self.link)  # atomic: readers never see no link at all
            except OSError as exc:  # the pty's name is not the user's to fix: the link's
                self._close_master()
                raise UserError(f"{self.link}: cannot make the link to the port "
                                f"({exc.strerror or exc})") from None
        return self.path

    def _check_link(self) -> None:
        """The link may replace only a link: a file or folder already at that name (a
        name typed wrong) is the user's, and was deleted, then the link removed at exit."""
        link = self.link
        if link is None:
            return
        if not link.parent.is_dir():
            raise UserError(f"{link}: folder {link.parent} does not exist")
        if os.path.lexists(link) and not link.is_symlink():
            kind = "folder" if link.is_dir() else "file"
            raise UserError(f"{link}: a {kind} is there, not a link; it is left as it is "
                            "(choose another name for the link)")

    @property
    def port(self) -> str:
        if self.link is not None:
            return str(self.link)
        if self.path is None:
            raise RuntimeError("pty not open")
        return self.path

    @property
    def is_open(self) -> bool:
        return self._master is not None

    @property
    def fd(self) -> int | None:
        """The master side's descriptor (None while unplugged), for callers that poll it
        or write with their own deadline."""
        return self._master

    def close(self) -> None:
        """Unplug: close the pty and remove the link, as a pulled cable removes its port
        (a link left behind points at a pty number the kernel gives to the next pty
        opened anywhere, where a reconnecting reader would go)."""
        with self._lock:
            if self.link is not None and self.link.is_symlink():
                self.link.unlink(missing_ok=True)
        self._close_master()

    def _close_master(self) -> None:
        with self._lock:
            if self._master is not None:
                os.close(self._master)
                self._master = None
                self._buf = b""

    def write(self, data: bytes) -> bool:
        """Write all of ``data`` (False when unplugged or nobody reads and it is full)."""
        with self._lock:
            fd = self._master
            if fd is None:
                return False
            view = memoryview(data)
            while view:
                try:
                    n = os.write(fd, view)
                except BlockingIOError:
                    if not select.select([], [fd], [], 0.05)[1]:
                        return False
                    continue
                except OSError:
                    return False
                view = view[n:]
            return True

    def read_lines(self, timeout_s: float) -> list[str]:
        """Complete lines received within ``timeout_s`` (may be empty)."""
        fd = self._master
        if fd is None:
            return []
        try:
            ready = select.select([fd], [], [], timeout_s)[0]
        except (OSError, ValueError):
            return []
        if ready:
            try:
                self._buf += os.read(fd, 4096)
            except (BlockingIOError, OSError):
                pass
        *lines, self._buf = self._buf.replace(b"\r", b"").split(b"\n")
        return [ln.decode("ascii", "replace").strip() for ln in lines]
