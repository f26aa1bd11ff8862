"""The file a remote client's ``filename`` names: a stranger's fields made into a path that
stays under the recorder's folder.

Any local process can reach the remote-control port, so every field is checked before it
is kept (the ``filename`` command is refused otherwise, with the reason). ``participant``,
``session``, ``task``, ``acquisition`` and ``modality`` follow the rule every participant
ID follows (participant_id.py: ASCII letters, digits, ``_ - .``, at most 64), so
no look-alike letters and no separators. ``root`` and ``template`` may hold several
names separated by ``/``, each of printable characters (NFC-normalised, so names that
look the same are the same name), at most ``MAX_FIELD_CHARS`` long. Refused anywhere: a
NUL or any other control or format character, ``\\``, ``.``/``..`` and names starting
with a dot, an absolute path, the characters Windows forbids (``<>:"|?*``), a name
ending in a space or a dot, the names Windows reserves (``CON``, ``NUL``, ``COM1``...).
A template must end in ``.xdf``, ``.xdfz`` or ``.h5`` (or have no extension); the file
is always ``.h5``. The joined path is resolved (symbolic links followed) and must lie
under the folder. ``run`` is 1 to ``MAX_RUN_DIGITS`` ASCII digits.

Names (docs/lsl.md, "Remote control"): BIDS-style by default,
``sub-P01/ses-S1/sub-P01_ses-S1_task-T_run-001_tactile.h5`` (absent entities left out);
a template takes LabRecorder's placeholders ``%p`` participant, ``%s`` session, ``%b``
task, ``%n`` run (3 digits), ``%a`` acquisition, ``%m`` modality, replaced in one pass
(a value holding ``%n`` stays as it is).
"""

from __future__ import annotations

import os
import re
import unicodedata
from collections.abc import Callable
from pathlib import Path

from tactile_studio.errors import UserError
from tactile_studio.participant_id import PARTICIPANT_RE
from tactile_studio.terminal import shown

FIELDS = ("root", "template", "participant", "session", "task", "run", "acquisition",
          "modality")
PLACEHOLDERS = {"%p": "participant", "%s": "session", "%b": "task", "%n": "run",
                "%a": "acquisition", "%m": "modality"}
MAX_FIELD_CHARS = 64       # a name; root and template: per component
MAX_PATH_CHARS = 255       # root and template as a whole
MAX_RUN_DIGITS = 6
MAX_NAME_BYTES = 255       # one component of the final path, as most file systems allow
NEXT_RUNS = 1000           # how far a taken name's run number is counted up
TEMPLATE_SUFFIXES = (".xdf", ".xdfz", ".h5")
WINDOWS_FORBIDDEN = set('<>:"|?*')
WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL", "CONIN$", "CONOUT$",
                    *(f"{dev}{n}" for dev in ("COM", "LPT") for n in "0123456789¹²³")}
_FIELD = re.compile(r"\{(\w+):([^{}]*)\}")
_PLACEHOLDER = re.compile("|".join(PLACEHOLDERS))
EXAMPLE = "e.g. {participant:P01} {task:touch} {run:1}"


class CommandError(UserError):
    """A command that is malformed or cannot be carried out now (the reply's text)."""


def quoted(text: str, limit: int = 60) -> str:
    """A client's text quoted in a reply (``terminal.shown``: escaped, long text cut)."""
    return f"'{shown(text, limit)}'"


def parse_filename(text: str) -> dict[str, str]:
    """``{key:value} ...`` -> checked fields (see the module docstring); CommandError."""
    pairs = _FIELD.findall(text)
    if not pairs or _FIELD.sub("", text).strip():
        raise CommandError(f"filename takes {{key:value}} fields, {EXAMPLE}")
    fields: dict[str, str] = {}
    for key, value in pairs:
        if key not in FIELDS:
            raise CommandError(f"filename: unknown field {quoted(key)} (known: "
                               f"{', '.join(FIELDS)})")
        if key in fields:
            raise CommandError(f"filename: {key} given twice")
        fields[key] = check_field(key, value)
    return fields


def check_field(key: str, value: str) -> str:
    """One field's value, normalised; CommandError saying what is wrong with it."""
    value = unicodedata.normalize("NFC", value.strip())
    if not value:
        return ""
    if key == "run":
        if not (value.isascii() and value.isdigit()) or len(value) > MAX_RUN_DIGITS:
            raise CommandError(f"filename: run must be a number of 1 to {MAX_RUN_DIGITS} "
                               f"digits, got {quoted(value)}")
        return value
    if key in ("root", "template"):
        if len(value) > MAX_PATH_CHARS:
            raise CommandError(f"filename: {key} longer than {MAX_PATH_CHARS} characters")
        if value.startswith(("/", "\\")) or re.match(r"[A-Za-z]:", value):
            raise CommandError(f"filename: {key} {quoted(value)} is an absolute path; it "
                               "must be relative to the recorder's folder")
        for part in value.split("/"):
            check_name(f"{key} {quoted(value)}", part)
        if key == "template" and Path(value).suffix.lower() not in ("", *TEMPLATE_SUFFIXES):
            raise CommandError(f"filename: template {quoted(value)} must end in .xdf or .h5 "
                               "(the file is HDF5)")
        return value
    if not PARTICIPANT_RE.match(value):  # collected and imported sessions' one rule
        raise CommandError(f"filename: bad {key} {quoted(value)}: use letters, digits, '_', "
                           "'-' or '.' (at most 64), e.g. P01")
    check_name(key, value)
    return value


def check_name(what: str, name: str, max_chars: int = MAX_FIELD_CHARS) -> None:
    """``name`` is one path component a stranger may choose (CommandError naming ``what``)."""
    why = _name_problem(name, max_chars)
    if why:
        raise CommandError(f"filename: {what}: {why}")


def _name_problem(name: str, max_chars: int) -> str:
    if not name:
        return "an empty folder name (two '/' in a row, or one at the end)"
    if len(name) > max_chars:
        return f"a name longer than {max_chars} characters"
    bad = next((c for c in name if not c.isprintable() and c != " "), None)
    if bad is not None:
        return f"{quoted(name)} holds a control character ({shown(bad)})"
    if "/" in name or "\\" in name:
        return f"{quoted(name)} holds a path separator; a name is one folder or file name"
    if name in (".", ".."):
        return f"{quoted(name)} is not a name; the file must stay in the recorder's folder"
    if name.startswith("."):
        return f"{quoted(name)} starts with a dot (a hidden file)"
    forbidden = sorted(WINDOWS_FORBIDDEN & set(name))
    if forbidden:
        return f"{quoted(name)} holds {' '.join(forbidden)}, which Windows forbids in names"
    if name[-1] in ". " or name[0] == " ":
        return f"{quoted(name)} begins or ends with a space or ends with a dot"
    if name.split(".")[0].rstrip().upper() in WINDOWS_RESERVED:
        return f"{quoted(name)} is a device name Windows reserves"
    return ""


def recording_path(fields: dict[str, str], out_dir: Path, run: int | None = None) -> Path:
    """The file ``fields`` name (``run`` in place of theirs), under ``out_dir``
    (CommandError when the name built would leave it or is not a usable file name)."""
    f = {k: v for k, v in fields.items() if v}
    if run is not None:
        f["run"] = str(run)
    values = {**f, "run": f"{int(f['run']):03d}" if "run" in f else "",
              "modality": f.get("modality", "tactile")}
    template = f.get("template")
    if template:
        name = _PLACEHOLDER.sub(lambda m: values.get(PLACEHOLDERS[m[0]], ""), template)
        name = re.sub(r"_+", "_", name).replace("_.", ".")
        stem, suffix = os.path.splitext(name)
        rel = f"{stem}.h5" if suffix.lower() in TEMPLATE_SUFFIXES else f"{name}.h5"
    else:
        parts = [f"{tag}-{values[key]}" for tag, key in (
            ("sub", "participant"), ("ses", "session"), ("task", "task"),
            ("acq", "acquisition"), ("run", "run")) if values.get(key)]
        folders = [p for p in parts[:2] if p.startswith(("sub-", "ses-"))]
        rel = "/".join([*folders, "_".join(parts + [values["modality"]]) + ".h5"])
    if f.get("root"):
        rel = f"{f['root']}/{rel}"
    return _under(out_dir, rel)


def _under(out_dir: Path, rel: str) -> Path:
    """``out_dir/rel`` once each component is checked and the resolved path is inside."""
    for part in rel.split("/"):
        check_name(f"the file name {quoted(rel)}", part, MAX_NAME_BYTES)
        if len(part.encode()) > MAX_NAME_BYTES:
            raise CommandError(f"filename: the file name {quoted(rel)}: a name longer than "
                               f"{MAX_NAME_BYTES} bytes")
    path = out_dir.joinpath(*rel.split("/"))
    try:
        inside = path.resolve().is_relative_to(out_dir.resolve())
    except (OSError, RuntimeError):  # a symbolic-link loop
        inside = False
    if not inside:
        raise CommandError(f"filename: {quoted(rel)} leads out of the recorder's folder "
                           "(through a symbolic link)")
    return path


def free_path(fields: dict[str, str], out_dir: Path,
              taken: Callable[[Path], bool] = os.path.lexists) -> tuple[Path, str]:
    """The next recording's file and its run: the name ``fields`` give, or with the next
    free run number when it is taken, so nothing is overwritten. A name that the run
    number does not change (a template without ``%n``), or ``NEXT_RUNS`` taken runs, is
    a CommandError, never an endless search."""
    path = recording_path(fields, out_dir)
    if not taken(path):
        return path, fields.get("run", "")
    first = int(fields.get("run") or 1)
    if recording_path(fields, out_dir, first + 1) == path:
        raise CommandError(f"{path} already exists and the template has no %n to number "
                           "another run; send a filename with another name")
    for run in range(first + 1, first + 1 + NEXT_RUNS):
        path = recording_path(fields, out_dir, run)
        if not taken(path):
            return path, str(run)
    raise CommandError(f"{path}: this name and its next {NEXT_RUNS} run numbers are "
                       "taken; send a filename with another name")
