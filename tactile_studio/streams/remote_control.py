"""LabRecorder's remote control, so experiment scripts written for LabRecorder (PsychoPy
and the like) start and stop Tactile Studio recordings unchanged.

A TCP listener (127.0.0.1 unless another interface is named; default port 22345) takes
one command per line and answers each with one line (docs/lsl.md, "Remote control"):

=========================  ======================================================
``start``                  record into the file named by ``filename`` -> ``OK``
``stop``                   finish the recording -> ``OK``
``update``                 LabRecorder refreshes its stream list; here -> ``OK``
``select all|none``        record the device or not -> ``OK``
``filename {root:DIR} {template:T} {participant:P} {session:S} {task:T} {run:N}
{acquisition:A} {modality:M}``  the next recording's file -> ``OK``
``status``                 one JSON object: device, recording, file, frames, rate, dropped
``mark TEXT``              an event ``marker`` (text, source remote) at the current frame
=========================  ======================================================

Anything else, or a command that cannot be done now, gets ``error: <why>`` and changes
nothing. The port is an input from strangers (any local process may connect): the file
names a client may give are checked in ``remote_names.py`` (always under the folder,
never overwriting), the lines it may send are bounded in ``remote_socket.py``, and no
command, however malformed, stops the listener or a recording.

Commands are queued by the socket threads and carried out by :meth:`RemoteControl.process`
on the owner's thread (the CLI's loop, the GUI's timer), which also owns the
acquisition session, so nothing here touches the session from another thread. The
session is duck-typed (``live.LiveAcquisition``: ``start_recording``,
``stop_recording``, ``recording``, ``status()``, ``engine``), as this layer sits below it.
"""

from __future__ import annotations

import ipaddress
import json
import queue
import socket
import sys
import threading
import traceback
from pathlib import Path
from typing import Any

from tactile_studio.devices.engine_events import Marker
from tactile_studio.errors import UserError
from tactile_studio.output_faults import fault_line
from tactile_studio.streams.remote_names import (
    CommandError,
    free_path,
    parse_filename,
    quoted,
    recording_path,
)
from tactile_studio.streams.remote_socket import LineServer
from tactile_studio.terminal import printable

DEFAULT_PORT = 22345
LOOPBACK = "127.0.0.1"
REPLY_WAIT_S = 30.0
KNOWN = "start, stop, update, select all|none, filename {...}, status, mark TEXT"


class _Pending:
    """A queued command: carried out once by the owner, or given up by its client when
    the owner did not get to it in time, never both."""

    def __init__(self, line: str) -> None:
        self.line = line
        self.reply = ""
        self.state = "queued"  # -> "running" -> "done", or "queued" -> "given up"
        self.lock = threading.Lock()
        self.done = threading.Event()

    def claim(self, state: str) -> bool:
        """Move from queued to ``state``: "running" (the owner's, to carry it out) or
        "given up" (its client's, as it was not); False when the other came first."""
        with self.lock:
            if self.state != "queued":
                return False
            self.state = state
            return True

    def answer(self, reply: str) -> None:
        self.reply, self.state = reply, "done"
        self.done.set()


class RemoteControl:
    """The command interpreter and its TCP listener (see the module docstring)."""

    def __init__(self, session: Any, out_dir: str | Path, port: int = DEFAULT_PORT,
                 host: str = LOOPBACK, metadata: dict[str, Any] | None = None,
                 reply_wait_s: float = REPLY_WAIT_S) -> None:
        self.session = session
        self.out_dir = Path(out_dir)
        self.metadata = dict(metadata or {})
        self.fields: dict[str, str] = {}
        self.selected = True
        self.reply_wait_s = reply_wait_s
        self.commands: queue.Queue[_Pending] = queue.Queue()
        self._lock = threading.Lock()  # the queue and ``_closing`` change together
        self._closing = False
        self._server: LineServer | None = None
        self.host, self.port = host, port

    # ---- the listener ------------------------------------------------------------------
    def listen(self, **limits: float) -> int:
        """Open the listener; returns the port (``port=0`` picks a free one). A port in use
        is a one-line error. ``limits``: ``line_timeout_s``, ``max_clients``
        (streams/remote_socket.py)."""
        try:
            self._server = LineServer(self.ask, self.host, self.port, **limits)
        except OSError as exc:
            raise UserError(f"remote control: cannot listen on {self.host}:{self.port} "
                            f"({exc.strerror or exc})") from None
        self.port = self._server.port
        return self.port

    def close(self) -> None:
        """Stop listening, answer what is queued, end every connection."""
        with self._lock:
            self._closing = True
        server, self._server = self._server, None
        while not self.commands.empty():  # nobody will carry these out now
            pending = self.commands.get_nowait()
            if pending.claim("running"):
                pending.answer("error: Tactile Studio is closing")
        if server is not None:
            server.close()

    @property
    def listening(self) -> bool:
        return self._server is not None

    def ask(self, line: str) -> str:
        """Queue ``line`` for the owner's thread and wait for its reply (socket threads).
        One the owner did not take up in time is not carried out later."""
        pending = _Pending(line)
        with self._lock:
            if self._closing:
                return "error: Tactile Studio is closing"
            self.commands.put(pending)
        if not pending.done.wait(self.reply_wait_s) and pending.claim("given up"):
            return (f"error: Tactile Studio was busy for {self.reply_wait_s:g} s; "
                    f"{quoted(line)} was not carried out")
        pending.done.wait()  # taken in time: its answer comes
        return pending.reply

    def process(self) -> list[tuple[str, str]]:
        """Carry out the queued commands (owner's thread); returns (command, reply) for
        each one carried out."""
        done = []
        while True:
            try:
                pending = self.commands.get_nowait()
            except queue.Empty:
                return done
            if pending.claim("running"):
                pending.answer(self.handle(pending.line))
                done.append((pending.line, pending.reply))

    # ---- the commands --------------------------------------------------------------------
    def handle(self, line: str) -> str:
        """One command -> its one-line reply. A stranger's malformed command is refused
        in that reply; one that meets a fault of ours (a traceback, printed on stderr) is
        refused too, and the listener and any recording go on."""
        verb, _, rest = line.strip().partition(" ")
        verb, rest = verb.lower(), rest.strip()
        try:
            reply = self._do(verb, rest)
            if reply is None:
                raise CommandError(f"unknown command {quoted(line.strip())} ({KNOWN})")
            return reply
        except UserError as exc:  # CommandError, and a session that refuses (one line)
            return f"error: {printable(' '.join(str(exc).split()), keep='')}"
        except Exception as exc:  # noqa: BLE001 - a bug must not end the recording
            print(f"remote control: {quoted(line)} failed:", file=sys.stderr)
            traceback.print_exc()
            return (f"error: {type(exc).__name__} in Tactile Studio while doing "
                    f"{quoted(verb)} (a bug; the recorder's log has the traceback)")

    def _do(self, verb: str, rest: str) -> str | None:
        """The reply; None: no such command."""
        s = self.session
        if verb == "status" and not rest:
            return json.dumps(self.status(), separators=(",", ":"))
        if verb == "filename":
            fields = parse_filename(rest)
            recording_path(fields, self.out_dir)  # a name that would leave --out: refused now
            self.fields = fields
            return "OK"
        if verb == "select" and rest.lower() in ("all", "none"):
            self.selected = rest.lower() == "all"
            return "OK"
        if verb == "update" and not rest:
            return "OK"
        if verb == "start" and not rest:
            if s.recording:
                raise CommandError(f"already recording into {s.recorder.path}")
            if not self.selected:
                raise CommandError("no stream selected (send 'select all')")
            if s.engine is None or not s.running:
                raise CommandError("no device is streaming")
            path, run = free_path(self.fields, self.out_dir)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise CommandError(fault_line(exc) or f"{path.parent}: cannot create the "
                                   f"folder ({exc.strerror or exc})") from None
            s.start_recording(path, self._recording_metadata(run))
            return "OK"
        if verb == "stop" and not rest:
            if not s.recording:
                raise CommandError("not recording")
            rows = s.recorder.rows_written
            path = s.stop_recording()
            if rows == 0:  # never a silent empty file
                raise CommandError(f"{path}: no frames were recorded (the device sent "
                                   "none)")
            return "OK"
        if verb == "mark":
            if not rest:
                raise CommandError("mark needs a text, e.g. mark stimulus_on")
            if s.engine is None:
                raise CommandError("no device is streaming")
            s.engine.add_event(Marker(rest, "remote"))
            return "OK"
        return None

    def _recording_metadata(self, run: str) -> dict[str, Any]:
        f = {**self.fields, "run": run}
        meta = {**self.metadata, "source": "remote"}
        for key, name in (("participant", "participant"), ("session", "session_label"),
                          ("task", "task"), ("run", "run"), ("acquisition", "acquisition"),
                          ("modality", "modality")):
            if f.get(key):
                meta[name] = f[key]
        return meta

    def status(self) -> dict[str, Any]:
        st = self.session.status()
        return {"device": st.device, "state": st.state, "recording": st.recording is not None,
                "file": st.recording, "frames": st.recorded_frames if st.recording else 0,
                "rate": round(float(st.measured_rate_hz), 3), "dropped": int(st.dropped)}

    def status_text(self) -> str:
        """For a status bar: where it listens."""
        return f"remote control {self.host}:{self.port}" if self.listening else ""


def this_machine_only(host: str) -> bool:
    """Whether listening on ``host`` keeps other machines out (a loopback address)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:  # a name: it may resolve to any interface
        return False


def send_commands(lines: list[str], port: int = DEFAULT_PORT, host: str = LOOPBACK,
                  timeout: float = 10.0) -> list[str]:
    """A tiny client (tests, scripts): each command's reply line, in order."""
    replies = []
    with socket.create_connection((host, port), timeout=timeout) as sock:
        f = sock.makefile("rwb")
        for line in lines:
            f.write((line + "\n").encode())
            f.flush()
            replies.append(f.readline().decode().strip())
    return replies
