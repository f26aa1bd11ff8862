"""Name maps for imports: which gesture a pressed key means, which participant a file
name means.

Both are given as a TOML file or inline as ``old=new,old=new``. Old ShearSense file
names spell participants freely ("Pilot", "PILOT", "P8", "P08"), so participants are
normalised before they are mapped: case is folded (upper case) and numbers are
zero-padded to two digits (P8 -> P08, P008 -> P08, P123 stays).
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from tactile_studio.errors import UserError
from tactile_studio.participant_id import check_participant
from tactile_studio.storage.format.protocol_file import (
    CollectionProtocol,
    list_protocols,
    load_protocol,
)


class MapError(UserError):
    """A ``--gestures`` or ``--participant-map`` value that cannot be used."""


def normalise_participant(name: str) -> str:
    """"Pilot" and "PILOT" -> "PILOT"; "P8", "p08", "P008" -> "P08"; "" stays ""."""
    s = str(name).strip().upper()
    m = re.fullmatch(r"P0*(\d+)", s)
    if m:
        return f"P{int(m.group(1)):02d}"
    return s


def read_map(value: str, option: str) -> dict[str, str]:
    """``value`` as a TOML file (top-level ``old = "new"`` pairs, or one table of
    them) or as ``old=new,...``; an existing file path wins."""
    path = Path(value).expanduser()
    if path.is_file() or value.lower().endswith(".toml"):
        if not path.is_file():
            raise MapError(f"{option}: {value}: no such file")
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise MapError(f"{option}: {value}: not a readable TOML file ({exc})") from None
        tables = [v for v in data.values() if isinstance(v, dict)]
        if len(tables) == 1 and len(data) == 1:
            data = tables[0]
        out = {}
        for k, v in data.items():
            if not isinstance(v, (str, int)) or isinstance(v, bool):
                raise MapError(f"{option}: {value}: {k!r} must map to a name, got {v!r}")
            out[str(k)] = str(v)
        return out
    out = {}
    for part in value.split(","):
        if not part.strip():
            continue
        old, sep, new = part.partition("=")
        if not sep or not old.strip() or not new.strip():
            raise MapError(f"{option}: {part.strip()!r} is not old=new "
                           "(give old=new,old=new or a .toml file)")
        out[old.strip()] = new.strip()
    if not out:
        raise MapError(f"{option}: empty map (give old=new,old=new or a .toml file)")
    return out


def gesture_key_map(value: str) -> dict[str, str]:
    """``--gestures``: pressed key -> gesture name. A key is one character ("r") or,
    as the old CSV stores it, its character code ("114"). A protocol names its gestures'
    keys too: a shipped one by name (``cost14``) or a protocol file (one with
    ``[[gestures]]``), so a study recorded with it needs no hand-written map."""
    protocol = _protocol_in(value)
    if protocol is not None:
        return {g.key: g.name for g in protocol.gestures}
    if "=" not in value and not value.lower().endswith(".toml") \
            and not Path(value).expanduser().is_file():
        raise MapError(f"--gestures: {value!r} is not key=Name,..., a .toml file or a "
                       f"shipped protocol ({', '.join(list_protocols())})")
    out = {}
    for key, name in read_map(value, "--gestures").items():
        if len(key) > 1 and key.isdigit():
            code = int(key)
            if not 0 < code < 0x110000:
                raise MapError(f"--gestures: key code {key} is out of range")
            key = chr(code)
        elif len(key) != 1:
            raise MapError(f"--gestures: key {key!r} must be one character or a character "
                           "code such as 114")
        out[key] = name
    return out


def gesture_map_source(value: str) -> str:
    """Where a ``--gestures`` map came from, as the import summary names it."""
    if value in list_protocols():
        return f"protocol {value}"
    if Path(value).expanduser().is_file():
        kind = "protocol file" if _protocol_in(value) is not None else "file"
        return f"{kind} {Path(value).name}"
    return "the map given"


def _protocol_in(value: str) -> CollectionProtocol | None:
    if value in list_protocols():
        return load_protocol(value)
    path = Path(value).expanduser()
    if not path.is_file():
        return None
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None  # read_map says what is wrong with it
    return load_protocol(path) if isinstance(data.get("gestures"), list) else None


def participant_map(value: str) -> dict[str, str]:
    """``--participant-map``: file-name participant (normalised) -> participant id."""
    out = {}
    for old, new in read_map(value, "--participant-map").items():
        try:
            out[normalise_participant(old)] = check_participant(new)
        except UserError as exc:
            raise MapError(f"--participant-map: {exc}") from None
    return out


__all__ = ["MapError", "gesture_key_map", "gesture_map_source", "normalise_participant",
           "participant_map", "read_map"]
