"""The remote control's limits that a listener process cannot show quickly, in process
with real sockets: a line begun and never ended, a command its client gave up on, and
the names a stranger may choose (issue 43's hunt). The owner's thread is a real one
calling ``process()``, as the CLI's loop and the GUI's timer do. Budget: ~3 s."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from remote_helpers import WAIT_S, read_to_end
from waiting import wait_until

from tactile_studio.streams.remote_control import RemoteControl, send_commands
from tactile_studio.streams.remote_names import (
    CommandError,
    free_path,
    parse_filename,
    recording_path,
)


@contextmanager
def served(control: RemoteControl, **limits: float) -> Iterator[int]:
    """``control`` listening, its commands carried out on an owner thread."""
    port = control.listen(**limits)
    stop = threading.Event()

    def owner() -> None:
        while not stop.wait(0.01):
            control.process()

    thread = threading.Thread(target=owner)
    thread.start()
    try:
        yield port
    finally:
        stop.set()
        thread.join(WAIT_S)
        control.close()


def test_a_line_begun_and_never_ended_loses_its_place_an_idle_client_keeps_it(tmp_path):
    """A client that sends part of a line and then a byte now and then held its thread
    for ever (thousands of them, the listener's threads); a client connected without
    sending anything is a script between two commands and keeps its connection."""
    with served(RemoteControl(None, tmp_path), line_timeout_s=0.3) as port:
        idle = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
        idle.sendall(b"update\n")
        assert idle.recv(100) == b"OK\n"
        slow = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
        dribbled = threading.Event()

        def dribble() -> None:  # one byte at a time, never a newline
            try:
                while not dribbled.wait(0.05):
                    slow.sendall(b"u")
            except OSError:
                pass

        sender = threading.Thread(target=dribble)
        sender.start()
        try:
            assert read_to_end(slow) == \
                b"error: a line was begun and not ended within 0.3 s; disconnecting\n"
        finally:
            dribbled.set()
            sender.join(WAIT_S)
            slow.close()
        idle.sendall(b"update\n")  # idle longer than the line limit, still served
        assert idle.recv(100) == b"OK\n"
        idle.close()


def test_a_command_its_client_gave_up_on_is_not_carried_out_later(tmp_path):
    """The reply said "did not answer in time" and the command was carried out anyway
    when the owner got to it: a script told ``start`` failed found a recording running."""
    control = RemoteControl(None, tmp_path, port=0, reply_wait_s=0.2)
    port = control.listen()
    try:  # no owner thread yet: the owner is busy (a long stop, a slow disk)
        assert send_commands(["select none"], port, timeout=WAIT_S) == \
            ["error: Tactile Studio was busy for 0.2 s; 'select none' was not carried out"]
        assert control.process() == [] and control.selected
    finally:
        control.close()


def test_closing_ends_every_connection_and_answers_what_waits(tmp_path):
    """A client of a listener that was switched off waited 30 s for an answer that
    nobody would give; now its connection ends when the listener closes."""
    control = RemoteControl(None, tmp_path, port=0)
    port = control.listen()
    client = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
    client.sendall(b"update\n")
    replies: list[bytes] = []
    reader = threading.Thread(target=lambda: replies.append(read_to_end(client)))
    reader.start()
    wait_until(lambda: not control.commands.empty(), what="the command queued")
    control.close()
    reader.join(WAIT_S)
    assert replies == [b"error: Tactile Studio is closing\n"]
    client.close()


def test_names_look_alikes_and_placeholders(tmp_path):
    same = [recording_path(parse_filename(f"{{root:{r}}} {{participant:P1}}"), tmp_path)
            for r in ("caf\u00e9", "cafe\u0301")]  # one name in NFC and NFD
    assert same[0] == same[1] == tmp_path / "café/sub-P1/sub-P1_tactile.h5"
    for bad in ("{root:a\u202eb}", "{root:a\u200bb}", "{template:x\u0085.xdf}"):
        with pytest.raises(CommandError, match="holds a control character"):
            parse_filename(bad)
    # placeholders are replaced in one pass: a value cannot inject another one
    f = parse_filename("{template:x_%b_%n.xdf} {task:T} {run:7}")
    assert recording_path(f, tmp_path) == tmp_path / "x_T_007.h5"
    assert recording_path({**f, "task": "%n"}, tmp_path) == tmp_path / "x_%n_007.h5"
    with pytest.raises(CommandError, match="a name longer than 255"):
        recording_path(parse_filename("{template:" + "%p" * 20 + ".xdf} {participant:"
                                      + "p" * 60 + "}"), tmp_path)


def test_a_taken_name_includes_links_and_the_search_is_bounded(tmp_path):
    """A dangling symbolic link at the name is taken (writing through it would create a
    file wherever it points); a thousand taken runs end in a reply, not a long search."""
    os.symlink(tmp_path / "elsewhere.h5", tmp_path / "tactile.h5")
    path, run = free_path({}, tmp_path)
    assert (path, run) == (tmp_path / "run-002_tactile.h5", "2")
    fields = parse_filename("{template:x_%n.xdf} {run:1}")
    seen: list = []
    with pytest.raises(CommandError, match="next 1000 run numbers are taken"):
        free_path(fields, tmp_path, taken=lambda p: seen.append(p) or True)
    assert len(seen) == 1001


def test_listening_beyond_this_machine_is_said():
    """``listen --host`` another interface prints a warning (no password on the port)."""
    from tactile_studio.streams.remote_control import this_machine_only

    assert all(map(this_machine_only, ("127.0.0.1", "127.0.0.2", "::1", "localhost")))
    assert not any(map(this_machine_only, ("0.0.0.0", "192.168.1.5", "::", "lab-pc")))
