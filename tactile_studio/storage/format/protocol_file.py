"""Collection protocols as TOML files, validated field by field.

A protocol says which gestures are collected (name, key, definition, optional image),
how long a trial is, how many blocks, how blocks are randomised, whether the block's
order is prompted one gesture at a time (the default) or free, when breaks come, the
free play and practice at the start, and the beep. Shipped protocols live in
``tactile_studio.resources/protocols``; any other ``.toml`` path works too. Every problem
is one ``UserError`` line naming the file and the field, e.g.
``shear9.toml: gestures[3].key: duplicate key 'r'``.
"""

from __future__ import annotations

import dataclasses
import math
import posixpath
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path, PureWindowsPath
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.storage.format.file_names import name_problem, shown_name

RANDOMISATION_MODES = ("shuffle_per_block", "fixed")
# "prompted": the screen prompts the next gesture of the block's order and only its key
# starts the trial; "free": any gesture of the block not done yet, in any order
ORDER_MODES = ("prompted", "free")
# A protocol from another lab is read whole and its blocks are stored in every session:
# bounds far above any study (the papers: 9-14 gestures, 52 blocks, 468 trials) keep a
# stranger's file from making a collection allocate gigabytes before its first trial
MAX_PROTOCOL_BYTES = 1 << 20
MAX_GESTURES = 100
MAX_TRIALS = 100_000
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".gif", ".bmp", ".webp", ".svg")  # what Qt reads


class ProtocolError(UserError):
    """A protocol file is missing, not TOML, or has a bad field."""


@dataclass(frozen=True)
class Gesture:
    name: str
    key: str
    definition: str
    # the image's name relative to the protocol file's folder ("images/poke.png"), as
    # sessions store it: never the experimenter's own folders (older sessions stored an
    # absolute path, which still loads); ``CollectionProtocol.image_file`` finds the file
    image: str | None = None
    # the force it is performed with, "light" | "natural" | "heavy" (None: not checked);
    # a trial outside that range is flagged too_light / too_heavy (protocol/quality.py)
    force: str | None = None


FORCES = ("light", "natural", "heavy")


@dataclass(frozen=True)
class CollectionProtocol:
    name: str
    title: str
    description: str
    gestures: tuple[Gesture, ...]
    trial_s: float
    blocks: int
    free_play_s: float = 10.0
    practice_trials: int = 0
    randomisation: str = "shuffle_per_block"
    seed: int = 0
    order: str = "prompted"
    break_every: int = 0
    break_min_s: float = 0.0
    beep_hz: float = 1000.0
    beep_s: float = 0.2
    min_contact_fraction: float = 0.03  # a light poke touches ~5-15% of a 2 s trial
    centre_fraction: float = 0.7
    min_contact_share: float = 0.0  # [quality]: short_contact below this share (0: off)
    wellness_required: bool = False   # [wellness] required: a check before each participant
    wellness_max_age_h: float = 24.0  # [wellness] max_age_h: older checks are stale
    source: str = ""
    # the protocol file's folder on this machine, where its images are; never stored
    folder: Path | None = dataclasses.field(default=None, compare=False)

    @property
    def gesture_names(self) -> list[str]:
        return [g.name for g in self.gestures]

    def gesture_by_key(self, key: str) -> Gesture | None:
        key = key.lower()
        return next((g for g in self.gestures if g.key == key), None)

    def gesture_by_name(self, name: str) -> Gesture:
        return next(g for g in self.gestures if g.name == name)

    def image_file(self, gesture: Gesture) -> str | None:
        """The file to show for ``gesture``'s image on this machine, None without one (or
        when the protocol's folder is unknown: a resume of another protocol than a
        shipped one shows the definitions alone)."""
        if not gesture.image:
            return None
        if Path(gesture.image).is_absolute():  # a session written before names were stored
            return gesture.image
        name = _inside_name(gesture.image)
        return str(self.folder / name) if self.folder is not None and name else None

    def with_overrides(self, **changes: Any) -> CollectionProtocol:
        """A copy with some fields changed, validated like a file (tests, --blocks)."""
        data = self.to_dict()
        data.update(changes)
        # images were checked when this protocol was loaded (or deliberately not, on resume)
        return protocol_from_dict(data, self.source or f"{self.name}.toml", self.folder,
                                  check_images="gestures" in changes)

    def to_dict(self) -> dict[str, Any]:
        """The flat form stored in session metadata, so a resume needs no file on disk
        (images by their names relative to the protocol, no folder of this machine)."""
        d = dataclasses.asdict(self)
        d["gestures"] = [dataclasses.asdict(g) for g in self.gestures]
        d.pop("source")
        d.pop("folder")
        return d


# ---- loading ---------------------------------------------------------------------------
def list_protocols() -> list[str]:
    """Names of the shipped protocols."""
    folder = resources.files("tactile_studio.resources") / "protocols"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def _find(name_or_path: str | Path) -> tuple[str, bytes, Path | None]:
    text = str(name_or_path)
    path = Path(text)
    if text.endswith(".toml") or path.parent != Path("."):
        if not path.is_file():
            raise ProtocolError(f"{path}: no such protocol file")
        size = path.stat().st_size
        if size > MAX_PROTOCOL_BYTES:
            raise ProtocolError(f"{path}: {size / 2**20:.1f} MB is not a protocol file "
                                f"(at most {MAX_PROTOCOL_BYTES >> 20} MB)")
        # absolute, so its images still resolve after the working folder changes
        return path.name, path.read_bytes(), path.parent.resolve()
    res = resources.files("tactile_studio.resources") / "protocols" / f"{text}.toml"
    if not res.is_file():
        known = ", ".join(list_protocols())
        raise ProtocolError(f"unknown protocol {text!r} (shipped: {known}; or give a .toml path)")
    return f"{text}.toml", res.read_bytes(), shipped_folder(text)


def shipped_folder(name: str) -> Path | None:
    """The folder of the shipped protocol ``name`` (where its images are), else None."""
    res = resources.files("tactile_studio.resources") / "protocols" / f"{name}.toml"
    if not res.is_file():
        return None
    folder = Path(str(res)).parent
    return folder if folder.is_dir() else None


def load_protocol(name_or_path: str | Path) -> CollectionProtocol:
    """A shipped protocol by name (``shear9``) or any protocol file by path."""
    label, data, folder = _find(name_or_path)
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise ProtocolError(f"{label}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise ProtocolError(f"{label}: not valid TOML ({exc})") from None
    return _parse_file(raw, label, folder)


def _parse_file(raw: dict[str, Any], label: str, folder: Path | None) -> CollectionProtocol:
    v = _Validator(label)
    v.known(raw, "", {"name", "title", "description", "trial_s", "blocks", "free_play_s",
                      "practice_trials", "order", "randomisation", "breaks", "beep",
                      "quality", "wellness", "gestures"})
    rnd = v.table(raw, "randomisation")
    brk = v.table(raw, "breaks")
    beep = v.table(raw, "beep")
    qual = v.table(raw, "quality")
    well = v.table(raw, "wellness")
    v.known(well, "wellness.", {"required", "max_age_h"})
    v.known(rnd, "randomisation.", {"mode", "seed"})
    v.known(brk, "breaks.", {"every_blocks", "min_s"})
    v.known(beep, "beep.", {"frequency_hz", "length_s"})
    v.known(qual, "quality.", {"min_contact_fraction", "centre_fraction", "min_contact_share"})
    flat = {k: raw[k] for k in ("name", "title", "description", "trial_s", "blocks",
                                "free_play_s", "practice_trials", "order", "gestures")
            if k in raw}
    rename = {("randomisation", "mode"): "randomisation", ("randomisation", "seed"): "seed",
              ("breaks", "every_blocks"): "break_every", ("breaks", "min_s"): "break_min_s",
              ("beep", "frequency_hz"): "beep_hz", ("beep", "length_s"): "beep_s",
              ("quality", "min_contact_fraction"): "min_contact_fraction",
              ("quality", "centre_fraction"): "centre_fraction",
              ("quality", "min_contact_share"): "min_contact_share",
              ("wellness", "required"): "wellness_required",
              ("wellness", "max_age_h"): "wellness_max_age_h"}
    tables = {"randomisation": rnd, "breaks": brk, "beep": beep, "quality": qual,
              "wellness": well}
    fields = {}
    for (table, key), target in rename.items():
        if key in tables[table]:
            flat[target] = tables[table][key]
            fields[target] = f"{table}.{key}"
    return protocol_from_dict(flat, label, folder, fields)


def protocol_from_dict(data: dict[str, Any], label: str, folder: Path | None = None,
                       field_names: dict[str, str] | None = None,
                       check_images: bool = True) -> CollectionProtocol:
    """Validate the flat form (``CollectionProtocol.to_dict()``); errors name the field.

    ``check_images=False`` when restoring from a session file on another machine.
    """
    v = _Validator(label, field_names or {})
    name = v.text(data, "name", default=Path(label).stem)
    why = name_problem(name)
    if why:  # it names every session file of the protocol
        v.fail("name", f"{shown_name(name)} cannot name session files: {why}")
    gestures = _gestures(v, data.get("gestures"), folder, check_images)
    mode = v.text(data, "randomisation", default="shuffle_per_block")
    if mode not in RANDOMISATION_MODES:
        v.fail("randomisation", f"unknown mode {mode!r} (use {' or '.join(RANDOMISATION_MODES)})")
    order = v.text(data, "order", default="prompted")
    if order not in ORDER_MODES:
        v.fail("order", f"unknown order {order!r} (use {' or '.join(ORDER_MODES)})")
    blocks = v.integer(data, "blocks", low=1, high=10_000, required=True)
    practice = v.integer(data, "practice_trials", low=0, high=1000, default=0)
    trials = blocks * len(gestures) + practice
    if trials > MAX_TRIALS:
        v.fail("blocks", f"{blocks} blocks of {len(gestures)} gestures make {trials:,} trials; "
                         f"a protocol holds at most {MAX_TRIALS:,}")
    return CollectionProtocol(
        name=name,
        title=v.text(data, "title", default=name),
        description=v.text(data, "description", default="", allow_empty=True),
        gestures=gestures,
        trial_s=v.number(data, "trial_s", low=0.05, high=600.0, required=True),
        blocks=blocks,
        free_play_s=v.number(data, "free_play_s", low=0.0, high=3600.0, default=0.0),
        practice_trials=practice,
        randomisation=mode,
        order=order,
        seed=v.integer(data, "seed", low=-(2**62), high=2**62, default=0),
        break_every=v.integer(data, "break_every", low=0, high=10_000, default=0),
        break_min_s=v.number(data, "break_min_s", low=0.0, high=86_400.0, default=0.0),
        beep_hz=v.number(data, "beep_hz", low=20.0, high=20_000.0, default=1000.0),
        beep_s=v.number(data, "beep_s", low=0.01, high=5.0, default=0.2),
        min_contact_fraction=v.number(data, "min_contact_fraction", low=0.0, high=1.0,
                                      default=0.03),
        centre_fraction=v.number(data, "centre_fraction", low=0.05, high=1.0, default=0.7),
        min_contact_share=v.number(data, "min_contact_share", low=0.0, high=1.0, default=0.0),
        wellness_required=_flag(v, data, "wellness_required"),
        wellness_max_age_h=v.number(data, "wellness_max_age_h", low=0.01, high=100_000.0,
                                    default=24.0),
        source=label,
        folder=folder,
    )


def restored_protocol(spec: Any, label: str,
                      at_hand: CollectionProtocol | None = None) -> CollectionProtocol:
    """The protocol a session stored (``protocol_spec``), found on this machine: its images
    are names in the protocol's folder, which the session does not keep, so the folder is
    a shipped protocol's, or that of ``at_hand`` (the protocol file the experimenter has
    chosen) when it is the same protocol; else none (the definitions show alone)."""
    if not isinstance(spec, dict):
        raise ProtocolError(f"{label}: not a protocol (expected a table of its fields)")
    p = protocol_from_dict(spec, label, check_images=False)
    if at_hand is not None and at_hand.folder is not None and at_hand.name == p.name \
            and at_hand.gestures == p.gestures:
        return dataclasses.replace(p, folder=at_hand.folder)
    return dataclasses.replace(p, folder=shipped_folder(p.name))


def _flag(v: _Validator, data: dict[str, Any], key: str) -> bool:
    value = data.get(key, False)
    if not isinstance(value, bool):
        v.fail(key, f"must be true or false, not {value!r}")
    return bool(value)


def _gestures(v: _Validator, items: Any, folder: Path | None,
              check_images: bool = True) -> tuple[Gesture, ...]:
    if items is None:
        v.fail("gestures", "missing (at least one [[gestures]] table is needed)")
    if not isinstance(items, list) or not items:
        v.fail("gestures", "must be a non-empty list of [[gestures]] tables")
    if len(items) > MAX_GESTURES:
        v.fail("gestures", f"{len(items)} gestures; a protocol has at most {MAX_GESTURES} "
                           "(a participant presses one key for each)")
    out: list[Gesture] = []
    names: dict[str, int] = {}
    keys: dict[str, int] = {}
    for i, item in enumerate(items):
        where = f"gestures[{i}]"
        if not isinstance(item, dict):
            v.fail(where, "must be a table with name, key and definition")
        v.known(item, f"{where}.", {"name", "key", "definition", "image", "force"})
        gv = _Validator(v.label, prefix=f"{where}.")
        name = gv.text(item, "name")
        key = gv.text(item, "key")
        if len(key) != 1 or not key.isprintable() or key.isspace():
            gv.fail("key", f"must be one printable character, got {key!r}")
        key = key.lower()
        if name.lower() in names:
            gv.fail("name", f"duplicate gesture name {name!r} "
                            f"(also gestures[{names[name.lower()]}])")
        if key in keys:
            gv.fail("key", f"duplicate key {key!r} (also gestures[{keys[key]}])")
        names[name.lower()], keys[key] = i, i
        definition = gv.text(item, "definition")
        image = None
        if item.get("image") is not None:
            image = gv.text(item, "image")
            if check_images:
                image = _image_name(gv, image, folder)
        force = None
        if item.get("force") is not None:
            force = gv.text(item, "force")
            if force not in FORCES:
                gv.fail("force", f"unknown force {force!r} (use {', '.join(FORCES)})")
        out.append(Gesture(name, key, definition, image, force))
    return tuple(out)


def _image_name(v: _Validator, image: str, folder: Path | None) -> str:
    """A protocol file's image as the name sessions store: relative to the protocol's
    folder and inside it (a stranger's protocol cannot show, or make a session name, a
    file elsewhere on the machine); it must exist there and be a picture Qt reads."""
    name = _inside_name(image)
    if name is None:
        v.fail("image", f"{image!r} is outside the protocol's folder (name an image beside "
                        "the protocol file or in a folder below it)")
    if Path(name).suffix.lower() not in IMAGE_SUFFIXES:
        v.fail("image", f"{image!r} is not an image (use {', '.join(IMAGE_SUFFIXES)})")
    if folder is not None and not (folder / name).is_file():
        v.fail("image", f"no such file {image!r} (relative to the protocol file)")
    return name


def _inside_name(image: str) -> str | None:
    """``image`` as a name inside its protocol's folder (normalised, ``/`` between
    folders), None when it leads out of it (absolute, a drive, ``..``)."""
    name = posixpath.normpath(image.replace("\\", "/"))
    if PureWindowsPath(image).drive or posixpath.isabs(name) or name == ".." \
            or name.startswith("../"):
        return None
    return name


class _Validator:
    """Reads typed fields and raises one-line errors ``<file>: <field>: <problem>``."""

    def __init__(self, label: str, names: dict[str, str] | None = None, prefix: str = "") -> None:
        self.label, self.names, self.prefix = label, names or {}, prefix

    def fail(self, field: str, problem: str) -> None:
        raise ProtocolError(f"{self.label}: {self.prefix}{self.names.get(field, field)}: {problem}")

    def known(self, table: dict[str, Any], prefix: str, allowed: set[str]) -> None:
        for key in table:
            if key not in allowed:
                raise ProtocolError(f"{self.label}: {prefix}{key}: unknown field "
                                    f"(known: {', '.join(sorted(allowed))})")

    def table(self, data: dict[str, Any], key: str) -> dict[str, Any]:
        value = data.get(key, {})
        if not isinstance(value, dict):
            self.fail(key, "must be a table")
        return value

    def text(self, data: dict[str, Any], key: str, default: str | None = None,
             allow_empty: bool = False) -> str:
        if key not in data:
            if default is None:
                self.fail(key, "missing")
            return default
        value = data[key]
        if not isinstance(value, str):
            self.fail(key, f"expected text, got {value!r}")
        if not allow_empty and not value.strip():
            self.fail(key, "must not be empty")
        return value.strip() if key != "key" else value

    def number(self, data: dict[str, Any], key: str, low: float, high: float,
               default: float | None = None, required: bool = False) -> float:
        if key not in data:
            if required or default is None:
                self.fail(key, "missing")
            return float(default)
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(key, f"expected a number, got {value!r}")
        if not math.isfinite(value):  # TOML has nan and inf; every field needs a number
            self.fail(key, f"{value} is not a finite number")
        if not low <= value <= high:
            self.fail(key, f"{value} is out of range {low:g}..{high:g}")
        return float(value)

    def integer(self, data: dict[str, Any], key: str, low: int, high: int,
                default: int | None = None, required: bool = False) -> int:
        if key not in data:
            if required or default is None:
                self.fail(key, "missing")
            return int(default)
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"expected a whole number, got {value!r}")
        if not low <= value <= high:
            self.fail(key, f"{value} is out of range {low}..{high}")
        return int(value)
