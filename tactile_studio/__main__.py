"""The program's entry: the ``tactile-studio`` console script and ``python -m tactile_studio``.

Starting a command loads its modules (numpy, h5py, every command's parser: about 1.5 s on
a busy machine); Ctrl-C in that time must end as Ctrl-C does anywhere (one line, exit
130), not as a KeyboardInterrupt traceback out of some import. So the entry is this
module, which imports nothing heavy, and everything the command line loads is imported
inside the ``try``. Before this module's first line runs only the interpreter
starts: a Ctrl-C then ends the process by the signal itself (the shell's status 130, with
nothing printed). Once the command runs, ``cli.main`` handles Ctrl-C itself.
"""

from __future__ import annotations

import sys

from tactile_studio.errors import EXIT_CANCELLED  # no imports of its own


def main() -> int:
    """Run the command line; Ctrl-C while it is still starting is one line and 130."""
    try:
        from tactile_studio.cli import main as run_command_line

        return run_command_line()
    except KeyboardInterrupt:
        print("tactile-studio: interrupted while starting; nothing was done", file=sys.stderr)
        return EXIT_CANCELLED


if __name__ == "__main__":
    raise SystemExit(main())
