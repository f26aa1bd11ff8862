"""The ``tactile-studio`` command line.

Every module in this package that defines ``register(subparsers)`` adds its commands;
nothing else needs editing to add one. User errors print one line and exit with their
status; so does an output that cannot be written (``output_faults``).
"""

from __future__ import annotations

import argparse
import importlib
import io
import os
import pkgutil
import sys
from typing import NoReturn

from tactile_studio import __version__
from tactile_studio.errors import (
    EXIT_BROKEN_PIPE,
    EXIT_CANCELLED,
    EXIT_ERROR,
    EXIT_TERMINATED,
    EXIT_USAGE,
    Cancelled,
    UserError,
)
from tactile_studio.jobs import Terminated, terminate_unwinds
from tactile_studio.output_faults import fault_line
from tactile_studio.terminal import printable_output


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is two lines instead of the whole usage block above
    it: ``tactile-studio <cmd>: error: <message>`` and where to look
    (``try 'tactile-studio <cmd> --help'``); the exit status stays 2 (EXIT_USAGE). Every
    command's parser is one of these (``add_subparsers`` makes its parent's class)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\ntry '{self.prog} --help'\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="tactile-studio",
        description="Tactile Studio: record, view, collect and learn from tactile arrays.")
    parser.add_argument("--version", action="version", version=f"tactile-studio {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(module, "register"):
            module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    _ignore_file_size_signal()
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        args = parser.parse_args(["gui", *(argv or [])])
    with printable_output():  # what files and peers say never drives the terminal
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """The command, and the one line and exit status of how it ended."""
    try:
        with terminate_unwinds():  # the GUI's window loop closes its windows instead
            code = int(args.func(args) or 0)
        sys.stdout.flush()  # inside the try: a closed pipe shows here, not at exit
        return code
    except BrokenPipeError:
        # whoever read our output has gone (`| head`): stop quietly, as Unix tools do
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except UserError as exc:
        print(f"tactile-studio: error: {exc}", file=sys.stderr)
        return int(exc.exit_code)
    except OSError as exc:
        # a place that cannot be written (read-only, full, no permission...) is the
        # environment's fault: one line naming the file; any other OSError is a bug
        line = fault_line(exc)
        if line is None:
            raise
        print(f"tactile-studio: error: {line}", file=sys.stderr)
        return EXIT_ERROR
    except Cancelled as exc:
        # a job that knows what it kept says so ("sweep cancelled: 3 of 8 tasks finished,
        # kept in runs/x"); a bare one gets the general line
        said = str(exc)
        if said in ("", "cancelled"):
            said = "cancelled; finished work was kept"
        print(f"tactile-studio: {said}", file=sys.stderr)
        return EXIT_CANCELLED
    except Terminated:
        print("tactile-studio: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("tactile-studio: interrupted", file=sys.stderr)
        return EXIT_CANCELLED


def _ignore_file_size_signal() -> None:
    """A file-size limit (``ulimit -f``) must fail the write (EFBIG: the recorder stops
    cleanly and says so) rather than kill the process with SIGXFSZ. Python ignores it at
    start already; say so here, where an embedding program may have changed it."""
    import signal
    import threading

    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's last flush finds no closed pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, io.UnsupportedOperation):
        pass  # not a real file (captured in tests): nothing will flush to the pipe
