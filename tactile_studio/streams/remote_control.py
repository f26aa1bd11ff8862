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
nothing. The template takes LabRecorder's placeholders: ``%p`` participant, ``%s``
session, ``%b`` task, ``%n`` run (3 digits), ``%a`` acquisition, ``%m`` modality; an
``.xdf`` ending becomes ``.h5``. Without a template the name is BIDS-style:
``sub-P01/ses-S1/sub-P01_ses-S1_task-T_run-001_tactile.h5`` (absent entities left out).

Commands are queued by the socket threads and carried out by :meth:`RemoteControl.process`
on the owner's thread (the CLI's loop, the GUI's timer), which also owns the
acquisition session, so nothing here touches the session from another thread. The
session is duck-typed (``live.AcquisitionSession``: ``start_recording``,
``stop_recording``, ``recording``, ``status()``, ``engine``), as this layer sits below it.
"""

from __future__ import annotations

import json
import queue
import re
import socket
import socketserver
import threading
from pathlib import Path
from typing import Any

from tactile_studio.errors import UserError

DEFAULT_PORT = 22345
LOOPBACK = "127.0.0.1"
REPLY_WAIT_S = 30.0
FIELDS = ("root", "template", "participant", "session", "task", "run", "acquisition",
          "modality")
PLACEHOLDERS = {"%p": "participant", "%s": "session", "%b": "task", "%n": "run",
                "%a": "acquisition", "%m": "modality"}
_FIELD = re.compile(r"\{(\w+):([^{}]*)\}")


class CommandError(UserError):
    """A command that is malformed or cannot be carried out now (the reply's text)."""


def parse_filename(text: str) -> dict[str, str]:
    """``{key:value} ...`` -> fields; CommandError on unknown keys or stray text."""
    fields = {k: v.strip() for k, v in _FIELD.findall(text)}
    if not fields or _FIELD.sub("", text).strip():
        raise CommandError("filename takes {key:value} fields, e.g. {participant:P01} "
                           "{task:touch} {run:1}")
    unknown = sorted(set(fields) - set(FIELDS))
    if unknown:
        raise CommandError(f"filename: unknown field {unknown[0]!r} (known: {', '.join(FIELDS)})")
    if "run" in fields and fields["run"] and not fields["run"].isdigit():
        raise CommandError(f"filename: run must be a number, got {fields['run']!r}")
    return fields


def bids_path(fields: dict[str, str], out_dir: Path) -> Path:
    """The file ``fields`` name (see the module docstring), under ``out_dir`` unless
    ``root`` is absolute."""
    f = {k: v for k, v in fields.items() if v}
    root = Path(f.get("root", ""))
    root = root if root.is_absolute() else out_dir / root
    run = f"{int(f['run']):03d}" if "run" in f else ""
    values = {**f, "run": run, "modality": f.get("modality", "tactile")}
    template = f.get("template")
    if template:
        name = template
        for ph, key in PLACEHOLDERS.items():
            name = name.replace(ph, values.get(key, ""))
        name = re.sub(r"_+", "_", name).replace("_.", ".")
        path = Path(name)
        path = path.with_suffix(".h5") if path.suffix in (".xdf", ".xdfz", "") else path
        return root / path
    parts = [f"{tag}-{values[key]}" for tag, key in (
        ("sub", "participant"), ("ses", "session"), ("task", "task"), ("acq", "acquisition"),
        ("run", "run")) if values.get(key)]
    folders = [p for p in parts[:2] if p.startswith(("sub-", "ses-"))]
    stem = "_".join(parts + [values["modality"]])
    return root.joinpath(*folders, f"{stem}.h5")


class RemoteControl:
    """The command interpreter and its TCP listener (see the module docstring)."""

    def __init__(self, session: Any, out_dir: str | Path, port: int = DEFAULT_PORT,
                 host: str = LOOPBACK, metadata: dict[str, Any] | None = None) -> None:
        self.session = session
        self.out_dir = Path(out_dir)
        self.metadata = dict(metadata or {})
        self.fields: dict[str, str] = {}
        self.selected = True
        self.commands: queue.Queue[tuple[str, list[str], threading.Event]] = queue.Queue()
        self.log: list[tuple[str, str]] = []  # (command, reply), for the CLI and tests
        self._server: socketserver.ThreadingTCPServer | None = None
        self._thread: threading.Thread | None = None
        self.host, self.port = host, port

    # ---- the listener ------------------------------------------------------------------
    def listen(self) -> int:
        """Open the listener; returns the port (``port=0`` picks a free one). A port in use
        is a one-line error."""
        control = self

        class Handler(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                for raw in self.rfile:
                    line = raw.decode("utf-8", "replace").strip()
                    if not line:
                        continue
                    reply = control.ask(line)
                    try:
                        self.wfile.write((reply + "\n").encode())
                    except OSError:
                        return

        socketserver.ThreadingTCPServer.allow_reuse_address = True
        socketserver.ThreadingTCPServer.daemon_threads = True
        try:
            self._server = socketserver.ThreadingTCPServer((self.host, self.port), Handler)
        except OSError as exc:
            raise UserError(f"remote control: cannot listen on {self.host}:{self.port} "
                            f"({exc.strerror or exc})") from None
        self.port = int(self._server.server_address[1])
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        name="remote-control", daemon=True)
        self._thread.start()
        return self.port

    def close(self) -> None:
        server, self._server = self._server, None
        if server is not None:
            server.shutdown()
            server.server_close()
        while not self.commands.empty():  # nobody will carry these out now
            _, slot, done = self.commands.get_nowait()
            slot.append("error: Tactile Studio is closing")
            done.set()

    @property
    def listening(self) -> bool:
        return self._server is not None

    def ask(self, line: str) -> str:
        """Queue ``line`` for the owner's thread and wait for its reply (socket threads)."""
        slot: list[str] = []
        done = threading.Event()
        self.commands.put((line, slot, done))
        if not done.wait(REPLY_WAIT_S) or not slot:
            return "error: Tactile Studio did not answer in time"
        return slot[0]

    def process(self) -> int:
        """Carry out the queued commands (owner's thread); returns how many."""
        n = 0
        while True:
            try:
                line, slot, done = self.commands.get_nowait()
            except queue.Empty:
                return n
            slot.append(self.handle(line))
            done.set()
            n += 1

    # ---- the commands --------------------------------------------------------------------
    def handle(self, line: str) -> str:
        """One command -> its one-line reply."""
        verb, _, rest = line.strip().partition(" ")
        verb, rest = verb.lower(), rest.strip()
        try:
            reply = self._do(verb, rest)
        except UserError as exc:  # CommandError, and a session that refuses (one line)
            reply = f"error: {' '.join(str(exc).split())}"
        self.log.append((line, reply))
        return reply

    def _do(self, verb: str, rest: str) -> str:
        s = self.session
        if verb == "status" and not rest:
            return json.dumps(self.status(), separators=(",", ":"))
        if verb == "filename":
            self.fields = parse_filename(rest)
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
            path = self.next_path()
            path.parent.mkdir(parents=True, exist_ok=True)
            s.start_recording(path, self._recording_metadata())
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
            s.engine.add_event("marker", text=rest, source="remote")
            return "OK"
        known = "start, stop, update, select all|none, filename {...}, status, mark TEXT"
        raise CommandError(f"unknown command {(verb + ' ' + rest).strip()!r} ({known})")

    def next_path(self) -> Path:
        """The next recording's file; a taken name gets the next free run number."""
        fields = dict(self.fields)
        path = bids_path(fields, self.out_dir)
        while path.exists():
            fields["run"] = str(int(fields.get("run") or 1) + 1)
            path = bids_path(fields, self.out_dir)
        return path

    def _recording_metadata(self) -> dict[str, Any]:
        f = self.fields
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
