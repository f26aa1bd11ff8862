"""The remote control's TCP listener: lines in, one reply line out, with limits, since any
local process may connect and send anything (docs/lsl.md, "Remote control").

* A line is at most ``MAX_LINE_BYTES``; a longer one is answered ``error: line longer
  than ... bytes; disconnecting`` and the client is disconnected, before more of it is
  kept, so a flood costs one buffer, not memory without bound (what it goes on sending
  is read and dropped for a moment, so the reply is not lost in a reset connection).
* At most ``MAX_CLIENTS`` connections at once; one more is answered ``error: too many
  clients ...`` and closed, without a thread of its own.
* A line once begun must end within ``LINE_TIMEOUT_S`` (a client that sends part of a
  line and then nothing, or a byte now and then, holds its place no longer); a client
  that stays connected without sending anything is fine (scripts keep one connection
  for a whole experiment). A reply the client does not read within that time ends the
  connection too.
* A line that is an HTTP request or header ends the connection before anything else in
  it is read: a web page the experimenter has open can make the browser post to
  127.0.0.1, and the lines of its body would otherwise be taken as commands.
* :meth:`LineServer.close` stops accepting and ends every connection, so a client of a
  listener switched off sees its connection closed instead of waiting for an answer.
"""

from __future__ import annotations

import re
import socket
import socketserver
import sys
import threading
import time
from collections.abc import Callable

MAX_LINE_BYTES = 4096
MAX_CLIENTS = 64
LINE_TIMEOUT_S = 30.0
# a web page's request (a browser posting to 127.0.0.1): its body's lines are not commands
_HTTP = re.compile(r"(?:[A-Z]+ \S+ HTTP/\d|(?i:host|origin|user-agent|content-\w+):)")
LINGER_S, LINGER_BYTES = 1.0, 1 << 20  # a hung-up client's bytes read after the reply


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    request_queue_size = 128  # a burst of clients connecting at once is not refused
    # Windows' SO_REUSEADDR would let another program take over the port
    allow_reuse_address = sys.platform != "win32"


class LineServer:
    """Serve ``answer(line) -> reply`` on ``host:port`` (see the module docstring)."""

    def __init__(self, answer: Callable[[str], str], host: str, port: int,
                 line_timeout_s: float = LINE_TIMEOUT_S, max_clients: int = MAX_CLIENTS
                 ) -> None:
        """OSError when the port cannot be had."""
        self.answer = answer
        self.line_timeout_s = line_timeout_s
        self.max_clients = max_clients
        self._lock = threading.Lock()
        self._clients: set[socket.socket] = set()
        self._closing = False
        owner = self

        class Handler(socketserver.BaseRequestHandler):
            def handle(self) -> None:
                try:
                    owner._serve(self.request)
                finally:
                    with owner._lock:
                        owner._clients.discard(self.request)

        class Server(_Server):
            def process_request(self, request, client_address):  # noqa: ANN001
                with owner._lock:
                    admitted = not owner._closing and len(owner._clients) < owner.max_clients
                    if admitted:
                        owner._clients.add(request)
                if admitted:
                    super().process_request(request, client_address)
                    return
                _send_now(request, f"error: too many clients connected (at most "
                                   f"{owner.max_clients}); try again later")
                self.shutdown_request(request)

        self._server = Server((host, port), Handler)
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        name="remote-control", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop accepting and end every connection (a reply being sent is sent first)."""
        with self._lock:
            self._closing = True
        self._server.shutdown()
        self._server.server_close()
        with self._lock:
            clients = list(self._clients)
        for sock in clients:
            try:
                sock.shutdown(socket.SHUT_RD)  # its reader sees the end; a reply still goes
            except OSError:
                pass

    def _serve(self, sock: socket.socket) -> None:
        buf = bytearray()
        begun = 0.0  # when the unfinished line in ``buf`` began
        while True:
            left = begun + self.line_timeout_s - time.monotonic()
            if buf and left <= 0:
                self._hang_up(sock, f"error: a line was begun and not ended within "
                                    f"{self.line_timeout_s:g} s; disconnecting")
                return
            try:
                sock.settimeout(left if buf else None)
                chunk = sock.recv(MAX_LINE_BYTES + 1)
            except TimeoutError:
                continue  # said above
            except OSError:
                return
            if not chunk:
                return
            if not buf:
                begun = time.monotonic()
            buf += chunk
            while 0 <= (end := buf.find(b"\n")) <= MAX_LINE_BYTES:
                line = buf[:end].decode("utf-8", "replace").strip()
                del buf[:end + 1]
                begun = time.monotonic()
                if _HTTP.match(line):
                    self._hang_up(sock, "error: this port takes LabRecorder's commands, not "
                                        "HTTP; disconnecting")
                    return
                if line and not self._send(sock, self.answer(line)):
                    return
            if len(buf) > MAX_LINE_BYTES:
                self._hang_up(sock, f"error: line longer than {MAX_LINE_BYTES} bytes; "
                                    "disconnecting")
                return

    def _send(self, sock: socket.socket, reply: str) -> bool:
        """False when the client cannot be written to (gone, or not reading)."""
        try:
            sock.settimeout(self.line_timeout_s)
            sock.sendall((reply + "\n").encode())
        except OSError:
            return False
        return True

    def _hang_up(self, sock: socket.socket, reply: str) -> None:
        """Say why and end the connection. What the client sent meanwhile is read (at
        most ``LINGER_BYTES``, for at most ``LINGER_S``) and dropped, so the close does
        not reset the connection and the reply reaches a client still sending."""
        if not self._send(sock, reply):
            return
        try:
            sock.shutdown(socket.SHUT_WR)
            end, drained = time.monotonic() + LINGER_S, 0
            while drained < LINGER_BYTES and (left := end - time.monotonic()) > 0:
                sock.settimeout(left)
                chunk = sock.recv(65536)
                if not chunk:
                    return
                drained += len(chunk)
        except OSError:
            pass


def _send_now(sock: socket.socket, text: str) -> None:
    """A short line to a client we are about to close, never waiting for it."""
    try:
        sock.setblocking(False)
        sock.send((text + "\n").encode())
    except OSError:
        pass
