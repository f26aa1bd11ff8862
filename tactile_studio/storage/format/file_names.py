"""File names made from data: a participant, a condition or a protocol's name that a file
(a session's metadata, a protocol from another lab) chose becomes part of a file we write.

Such a value must be one name, never a path: a ``/`` or ``\\``, ``..``, an absolute path
or a drive would put the file outside the folder the user named (``export`` wrote
``/tmp/x_P01.csv`` from a session whose participant was ``/tmp/x``), and a control
character puts escape sequences and line breaks in file names and in every line that
shows them. Refused too, as Windows refuses them: ``<>:"|?*`` and a name ending in a dot
or a space, so a study's files copy to any lab's machine.
"""

from __future__ import annotations

from tactile_studio.errors import UserError
from tactile_studio.terminal import shown

MAX_NAME_CHARS = 64
WINDOWS_FORBIDDEN = frozenset('<>:"|?*')


def name_problem(name: str, max_chars: int = MAX_NAME_CHARS) -> str | None:
    """Why ``name`` cannot be (part of) one file name, else None."""
    if not name:
        return "it is empty"
    if not name.isprintable():
        return "it holds a control character"
    if "/" in name or "\\" in name:
        return "it holds a path separator"
    if len(name) > max_chars:
        return f"it is longer than {max_chars} characters"
    if name.startswith("."):
        return "it starts with a dot"
    forbidden = sorted(WINDOWS_FORBIDDEN & set(name))
    if forbidden:
        return f"it holds {' '.join(forbidden)}"
    if name[0] == " " or name[-1] in ". ":
        return "it begins with a space or ends with a space or a dot"
    return None


def shown_name(name: str, limit: int = 40) -> str:
    """``name`` quoted for a message (``terminal.shown``: escaped, cut at ``limit``)."""
    return f"'{shown(name, limit)}'"


def check_name(what: str, name: str, max_chars: int = MAX_NAME_CHARS) -> str:
    """``name`` if it can be part of one file name; else a one-line UserError saying
    ``what`` it is and why not."""
    why = name_problem(name, max_chars)
    if why:
        raise UserError(f"{what} {shown_name(name)} cannot name a file: {why}")
    return name
