"""A real ``tactile-studio listen`` process for the remote-control tests, and a raw client.

The listener's stdout and stderr go to files (not pipes): a test that floods it must not
block it on a full pipe, and what it printed can be measured afterwards."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from tactile_studio.streams.remote_control import send_commands

WAIT_S = 30.0  # a safety net for a hung process, never a timing assertion


@dataclass
class Listener:
    proc: subprocess.Popen
    port: int
    stdout_path: Path
    stderr_path: Path
    returncode: int | None = None

    def send(self, *lines: str) -> list[str]:
        return send_commands(list(lines), self.port, timeout=WAIT_S)

    def status(self) -> dict:
        return json.loads(self.send("status")[0])

    def wait_frames(self, n: int) -> dict:
        """The status once the recording holds at least ``n`` frames (bounded)."""
        deadline = time.monotonic() + WAIT_S
        while time.monotonic() < deadline:
            status = self.status()
            if status["frames"] >= n:
                return status
            time.sleep(0.05)
        raise AssertionError(f"the recording did not reach {n} frames: {status}")

    @property
    def stdout(self) -> str:
        return self.stdout_path.read_bytes().decode("utf-8", "replace")

    @property
    def stderr(self) -> str:
        return self.stderr_path.read_bytes().decode("utf-8", "replace")


@contextmanager
def listening(tmp_path: Path, out: Path, *args: str) -> Iterator[Listener]:
    """``listen`` on a free port streaming the simulator into ``out``; ended with Ctrl-C
    (its exit status is then in ``returncode``)."""
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(tmp_path / "data")}
    stdout, stderr = tmp_path / "listen.out", tmp_path / "listen.err"
    with open(stdout, "wb") as o, open(stderr, "wb") as e:
        proc = subprocess.Popen([sys.executable, "-m", "tactile_studio", "listen",
                                 "--set", "rate=200", "--port", "0", "--out", str(out),
                                 *args], stdout=o, stderr=e, env=env)
    listener = Listener(proc, 0, stdout, stderr)
    try:
        deadline = time.monotonic() + WAIT_S
        while "listening on" not in listener.stderr:
            assert proc.poll() is None and time.monotonic() < deadline, listener.stderr
            time.sleep(0.05)
        listener.port = int(listener.stderr.split("127.0.0.1:")[1].split()[0])
        yield listener
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            listener.returncode = proc.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:  # Ctrl-C ignored: never leave it running
            proc.kill()
            proc.wait()
            raise


def raw_exchange(port: int, data: bytes) -> bytes:
    """Send ``data`` as it is and read until the listener closes (or ``WAIT_S``)."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(data)
        return read_to_end(sock)


def read_to_end(sock: socket.socket) -> bytes:
    got = b""
    while True:
        try:
            chunk = sock.recv(65536)
        except ConnectionResetError:
            return got
        if not chunk:
            return got
        got += chunk
