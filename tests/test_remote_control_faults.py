"""The remote-control port is an input from strangers (issue 43, cases 3 and 10-13): a
real ``tactile-studio listen`` process, real sockets, what any local process could send.

Each case ends one way: an ``error:`` reply naming the cause, the listener and any
recording going on, nothing written outside ``--out``, nothing overwritten, nothing a
client sent reaching the terminal raw. Budget: ~10 s (one listener per test)."""

from __future__ import annotations

import socket
import threading

from remote_helpers import WAIT_S, listening, raw_exchange, read_to_end
from waiting import wait_until

from tactile_studio.storage import SessionFile
from tactile_studio.streams.remote_control import send_commands
from tactile_studio.streams.remote_socket import MAX_CLIENTS, MAX_LINE_BYTES


def _session_files(root):
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file()
                  and p.suffix in (".h5", ".txt"))


def test_a_template_without_a_run_number_is_refused_not_an_endless_search(tmp_path):
    """Case 3: start, stop, start with ``{template:sub-%p_task-%b.xdf}`` looped for ever
    at 100% CPU; every later reply was "did not answer in time", Ctrl-C was ignored."""
    out = tmp_path / "rec"
    with listening(tmp_path, out) as ls:
        assert ls.send("filename {template:sub-%p_task-%b.xdf} {participant:P1} "
                       "{task:T}", "start") == ["OK", "OK"]
        ls.wait_frames(5)
        assert ls.send("stop") == ["OK"]
        (reply,) = ls.send("start")
        assert reply == (f"error: {out / 'sub-P1_task-T.h5'} already exists and the "
                         "template has no %n to number another run; send a filename with "
                         "another name")
        assert ls.status()["recording"] is False
        assert ls.send("filename {template:sub-%p_task-%b_run-%n.xdf} {participant:P1} "
                       "{task:T} {run:1}", "start") == ["OK", "OK"]
        ls.wait_frames(5)
        assert ls.send("stop") == ["OK"]
    assert ls.returncode == 0, ls.stderr  # Ctrl-C ends it as before
    assert _session_files(out) == ["sub-P1_task-T.h5", "sub-P1_task-T_run-001.h5"]


def test_names_that_leave_the_folder_or_are_not_names_are_refused(tmp_path):
    """Case 10: ``{participant:../../../esc}`` wrote outside ``--out`` and
    ``{template:/x.txt}`` wrote HDF5 under any name; a symbolic link inside ``--out``
    leading out is followed no more."""
    out = tmp_path / "rec"
    out.mkdir()
    (tmp_path / "elsewhere").mkdir()
    (out / "link").symlink_to(tmp_path / "elsewhere")
    label = "use letters, digits, '_', '-' or '.'"
    refused = {
        "{participant:../../../esc}": f"bad participant '../../../esc': {label}",
        "{session:..}": f"bad session '..': {label}",
        "{participant:a\\b}": label,
        "{task:Р01}": label,  # a Cyrillic Р, P's look-alike
        "{participant:" + "x" * 65 + "}": label,
        "{participant:CON}": "a device name Windows reserves",
        "{task:aux.txt}": "a device name Windows reserves",
        "{participant:P01.}": "ends with a dot",
        f"{{template:{tmp_path}/x.txt}}": "is an absolute path",
        "{template:/x.txt}": "is an absolute path",
        "{template:x.txt}": "must end in .xdf or .h5",
        "{template:../x.xdf}": "is not a name",
        "{template:a//b.xdf}": "an empty folder name",
        "{template:a\\b.xdf}": "holds a path separator",
        "{template:ab:c.xdf}": "which Windows forbids",
        "{template:nul.xdf}": "a device name Windows reserves",
        "{root:/tmp}": "is an absolute path",
        "{root:C:\\data}": "is an absolute path",
        "{root:sub/../..}": "is not a name",
        "{root:.git}": "starts with a dot",
        "{root:link}": "leads out of the recorder's folder",
        "{root:" + "y" * 65 + "}": "longer than 64 characters",
    }
    with listening(tmp_path, out) as ls:
        replies = ls.send(*(f"filename {fields}" for fields in refused), "start")
        for fields, reply in zip(refused, replies, strict=False):
            assert reply.startswith("error: filename: ") and refused[fields] in reply, \
                (fields, reply)
        assert replies[-1] == "OK"  # the last good name (none: tactile.h5 under --out)
        ls.wait_frames(5)
        assert ls.send("stop") == ["OK"]
    assert _session_files(tmp_path) == ["rec/tactile.h5"]


def test_malformed_requests_never_stop_the_listener_or_the_recording(tmp_path):
    """Case 11: a NUL, odd digits, a 5,000-digit run or ``{template:/}`` ended the
    listener with a traceback and streaming stopped; so did a folder name that is a file."""
    out = tmp_path / "rec"
    out.mkdir()
    (out / "taken").write_text("not a folder")
    with listening(tmp_path, out) as ls:
        assert ls.send("filename {participant:P7} {run:1}", "start") == ["OK", "OK"]
        before = ls.wait_frames(5)["frames"]
        replies = ls.send("filename {participant:a\0b}", "filename {run:²}",
                          "filename {run:" + "9" * 4000 + "}", "filename {template:/}",
                          "filename {run:-1}", "filename {participant:A} {participant:B}",
                          "\0\0\0", "filename {template:a\0b.xdf}", "mark \0")
        assert all(r.startswith("error: ") for r in replies[:8]), replies
        assert replies[0].startswith("error: filename: bad participant 'a\\x00b'")
        assert "run must be a number of 1 to 6 digits" in replies[1]
        assert "run must be a number" in replies[2] and len(replies[2]) < 200
        assert "given twice" in replies[5]
        assert "holds a control character (\\x00)" in replies[7]
        assert ls.send("filename {run:" + "9" * 5000 + "}") == \
            ["error: line longer than 4096 bytes; disconnecting"]
        assert replies[8] == "OK"  # a marker's text is content, kept as sent
        ls.wait_frames(before + 5)  # still recording, still streaming
        assert ls.send("stop") == ["OK"]
        assert ls.send("filename {root:taken}", "start") == \
            ["OK", f"error: {out / 'taken'}: cannot write (exists and is not a folder)"]
        assert ls.send("filename {root:taken/deeper}", "start") == \
            ["OK", f"error: {out / 'taken/deeper'}: cannot write (Not a directory)"]
        assert ls.status()["state"] == "running"
    assert ls.returncode == 0 and "Traceback" not in ls.stderr, ls.stderr
    with SessionFile(out / "sub-P7/sub-P7_run-001_tactile.h5") as s:
        assert s.n_frames >= before + 5
        assert [e["text"] for e in s.events if e["kind"] == "marker"] == ["\0"]


def test_a_line_too_long_is_refused_and_its_client_disconnected(tmp_path):
    """Case 12: a 400 MB line without a newline grew the listener to 2 GB and was
    echoed to stdout whole. Now a line over the limit ends its connection at the limit,
    and the listener goes on answering the others."""
    out = tmp_path / "rec"
    with listening(tmp_path, out) as ls:
        got = raw_exchange(ls.port, b"x" * (MAX_LINE_BYTES + 1))
        assert got == f"error: line longer than {MAX_LINE_BYTES} bytes; disconnecting\n" \
            .encode()
        got = raw_exchange(ls.port, b"mark " + b"y" * MAX_LINE_BYTES + b"\nstatus\n")
        assert got.startswith(b"error: line longer than") and got.count(b"\n") == 1
        flood = socket.create_connection(("127.0.0.1", ls.port), timeout=WAIT_S)
        sent = 0
        try:  # 64 MB that never ends a line: the listener hangs up part way
            for _ in range(1024):
                flood.sendall(b"z" * 65536)
                sent += 65536
        except OSError:
            pass
        flood.close()
        assert sent < 64 * 2**20
        assert ls.send("update") == ["OK"]
    assert ls.stdout_path.stat().st_size < 10_000  # nothing of the flood was echoed


def test_nothing_a_client_sends_reaches_the_terminal_raw(tmp_path):
    """Case 13: ``mark \\x1b]0;owned\\x07\\x1b[2J`` reached the experimenter's terminal
    (title set, screen cleared); a CR landed in file names."""
    out = tmp_path / "rec"
    hostile = "mark \x1b]0;owned\x07\x1b[2J \u202eevil\r"
    with listening(tmp_path, out) as ls:
        assert ls.send("filename {participant:P1}", "start") == ["OK", "OK"]
        assert ls.send(hostile)[0] == "OK"
        reply = ls.send("filename {participant:a\rb}", "filename {template:a\rb.xdf}")
        assert reply[0].startswith("error: filename: bad participant 'a\\rb'")
        assert reply[1].startswith("error: filename: template 'a\\rb.xdf': 'a\\rb.xdf' holds a "
                                   "control character (\\r)")
        (reply,) = ls.send("\x1b[2Jbogus")
        assert "\x1b" not in reply and "'\\x1b[2Jbogus'" in reply
        ls.wait_frames(5)
        assert ls.send("stop") == ["OK"]
    for text in (ls.stdout, ls.stderr):
        assert all(c.isprintable() or c == "\n" for c in text), repr(text)
    assert "> mark \\u001b]0;owned\\u0007\\u001b[2J \\u202eevil" in ls.stdout
    with SessionFile(out / "sub-P1/sub-P1_tactile.h5") as s:  # the file keeps the text sent
        (mark,) = [e for e in s.events if e["kind"] == "marker"]
        assert mark["text"] == "\x1b]0;owned\x07\x1b[2J \u202eevil"


def test_a_taken_name_is_never_overwritten_and_the_file_says_its_own_run(tmp_path):
    """A filename naming an existing recording records into the next free run; its
    metadata says that run (it said the run asked for, which another file holds)."""
    out = tmp_path / "rec"
    taken = out / "exp_001.h5"
    with listening(tmp_path, out) as ls:
        fields = "filename {template:exp_%n.xdf} {run:1}"
        for _ in range(2):
            assert ls.send(fields, "start") == ["OK", "OK"]
            ls.wait_frames(5)
            assert ls.send("stop") == ["OK"]
        first = taken.read_bytes()
        (out / "exp_003.h5").mkdir()  # a folder in the way is taken too
        assert ls.send(fields, "start") == ["OK", "OK"]
        ls.wait_frames(5)
        assert ls.send("stop") == ["OK"]
    assert taken.read_bytes() == first
    for name, run in (("exp_001.h5", "1"), ("exp_002.h5", "2"), ("exp_004.h5", "4")):
        with SessionFile(out / name) as s:
            assert s.metadata["run"] == run


def test_clients_beyond_the_limit_are_turned_away_and_fifty_are_served(tmp_path):
    """Thousands of idle connections took a thread each; now at most ``MAX_CLIENTS``
    are held, one more is told so and closed, and the listener serves again once they
    leave. Fifty clients at once are all answered (issue 43's "held up well")."""
    out = tmp_path / "rec"
    with listening(tmp_path, out) as ls:
        replies: list[list[str]] = []

        def client(k: int) -> None:
            replies.append(send_commands([f"filename {{participant:P{k}}}", "status"],
                                         ls.port, timeout=WAIT_S))

        clients = [threading.Thread(target=client, args=(k,)) for k in range(50)]
        for t in clients:
            t.start()
        for t in clients:
            t.join(WAIT_S)
        assert len(replies) == 50 and all(r[0] == "OK" for r in replies)
        held: list[socket.socket] = []
        try:
            for _ in range(4 * MAX_CLIENTS):  # until MAX_CLIENTS are held (the fifty
                if len(held) == MAX_CLIENTS:  # may not all have been seen to leave yet)
                    break
                sock = socket.create_connection(("127.0.0.1", ls.port), timeout=WAIT_S)
                sock.sendall(b"update\n")
                if sock.makefile("rb").readline() == b"OK\n":
                    held.append(sock)
                else:
                    sock.close()
            assert len(held) == MAX_CLIENTS
            with socket.create_connection(("127.0.0.1", ls.port), timeout=WAIT_S) as extra:
                assert read_to_end(extra) == (f"error: too many clients connected (at most "
                                              f"{MAX_CLIENTS}); try again later\n").encode()
        finally:
            for sock in held:
                sock.close()
        assert wait_until(lambda: send_commands(["update"], ls.port, timeout=WAIT_S)
                          == ["OK"], what="the listener serving again")


def test_a_web_page_posting_to_the_port_starts_nothing(tmp_path):
    """A page open in the experimenter's browser can POST to 127.0.0.1:22345; the lines
    of its body were carried out as commands (``start``, ``filename``...). An HTTP
    request line ends the connection before its body is read."""
    out = tmp_path / "rec"
    body = b"filename {template:web_%n.xdf}\nstart\n"
    request = (b"POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: text/plain\r\n"
               b"Content-Length: %d\r\n\r\n" % len(body)) + body
    with listening(tmp_path, out) as ls:
        assert raw_exchange(ls.port, request) == \
            b"error: this port takes LabRecorder's commands, not HTTP; disconnecting\n"
        status = ls.status()
        assert status["recording"] is False and status["file"] is None
    assert not out.exists() or _session_files(out) == []
