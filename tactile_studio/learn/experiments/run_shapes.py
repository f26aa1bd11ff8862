"""What a run folder's JSON must hold before anything reads it.

A run folder may come from someone else (a colleague's results, a download), and every
reader (``evaluate``, ``export-model``, ``compare``, live inference, the workspace) takes
``config.json`` and each ``fold.json`` as written by us. A field of another type or size
made them end in a traceback (``overrides`` a list, ``window_s`` text, no ``data_info``,
repeated labels) or allocate what the file claimed (``n_classes`` 10^12: 7 TiB). So
``runfolder.run_problems`` checks them here first: each field has the type the dataclass
declares, sizes are within what a model of ours can have, and a fold's recorded
predictions agree with the run's labels. Each problem is one line naming the file and the
field. A file's extra keys are ignored (a newer version may add some).
"""

from __future__ import annotations

import math
import types
import typing
from pathlib import Path
from typing import Any

from tactile_studio.learn.experiments.config import ExperimentConfig

MAX_CLASSES = 1000
MAX_CHANNELS = 64
MAX_GRID = 1024
FOLD_LISTS = ("train", "val", "test", "heldout", "test_participants")


def conforms(value: Any, hint: Any) -> bool:
    """Whether a JSON value is of the type ``hint`` (as dataclasses declare them: int,
    float, str, bool, None, ``X | None``, ``list[X]``, ``tuple[X, ...]``, ``tuple[X, Y]``,
    ``dict[str, Any]``, ``Any``). A float is finite; an int is not a bool."""
    if hint is Any:
        return True
    if hint is type(None) or hint is None:
        return value is None
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return any(conforms(value, a) for a in args)
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return conforms(value, int) or (isinstance(value, float) and math.isfinite(value))
    if hint is str:
        return isinstance(value, str)
    if origin is list:
        return isinstance(value, list) and all(conforms(v, args[0]) for v in value)
    if origin is tuple:  # stored as a JSON list
        if not isinstance(value, list):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(conforms(v, args[0]) for v in value)
        return len(value) == len(args) and all(conforms(v, a) for v, a in zip(value, args))
    if origin is dict:
        return isinstance(value, dict) and all(conforms(v, args[1]) for v in value.values())
    return isinstance(value, hint)


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def config_problem(path: Path, cfg: dict[str, Any]) -> str | None:
    """Why ``config.json`` (``{"config": ..., "resolved": ...}``) cannot be read, else None."""
    hints = typing.get_type_hints(ExperimentConfig)
    for key, value in cfg["config"].items():
        if key in hints and not conforms(value, hints[key]):
            return f"{path}: config.{key} is {_shown(value)}, not {_hint_name(hints[key])}"
    info = cfg["resolved"].get("data_info")
    if not isinstance(info, dict):
        return f"{path}: resolved.data_info is missing or not a table"
    n = info.get("n_classes")
    checks = (
        ("n_classes", conforms(n, int) and 2 <= n <= MAX_CLASSES, f"2..{MAX_CLASSES} classes"),
        ("in_channels", conforms(info.get("in_channels"), int)
         and 1 <= info["in_channels"] <= MAX_CHANNELS, f"1..{MAX_CHANNELS} channels"),
        ("grid", conforms(info.get("grid"), tuple[int, int])
         and all(1 <= g <= MAX_GRID for g in info["grid"]), f"two sizes 1..{MAX_GRID}"),
        ("channel_names", conforms(info.get("channel_names"), list[str]), "a list of names"),
        ("cell_pitch", conforms(info.get("cell_pitch"), float) and info["cell_pitch"] > 0,
         "a positive number"),
    )
    for key, ok, want in checks:
        if not ok:
            return f"{path}: resolved.data_info.{key} is {_shown(info.get(key))}, not {want}"
    labels = (cfg["resolved"].get("dataset") or {}).get("labels") \
        if isinstance(cfg["resolved"].get("dataset"), dict) else None
    if not conforms(labels, list[str]) or len(set(labels)) != len(labels) or len(labels) != n:
        return (f"{path}: resolved.dataset.labels is {_shown(labels)}, not {n} different "
                "gesture names")
    return None


def fold_problem(path: Path, rec: dict[str, Any], n_classes: int | None) -> str | None:
    """Why a ``fold.json`` cannot be read with a run of ``n_classes`` labels, else None."""
    for key in FOLD_LISTS:
        if key in rec and not conforms(rec[key], list[str]):
            return f"{path}: {key} is {_shown(rec[key])}, not a list of names"
    if not conforms(rec.get("name"), str):
        return f"{path}: name is {_shown(rec.get('name'))}, not a name"
    norm = rec.get("norm")
    if norm is not None and not (isinstance(norm, dict) and _numbers(list(norm.values()))):
        return f"{path}: norm is {_shown(norm)}, not numbers by name"
    sha = rec.get("model_sha256")
    if sha is not None and not (conforms(sha, dict[str, str])
                                and all(Path(k).name == k and k for k in sha)):
        return f"{path}: model_sha256 is {_shown(sha)}, not digests by file name"
    for key in ("predictions", "heldout_predictions"):
        why = _predictions_problem(rec.get(key), n_classes)
        if why:
            return f"{path}: {key} {why}"
    return None


def _numbers(value: Any) -> bool:
    """Finite numbers, nulls or (nested) lists of them: a normalisation's statistics."""
    if isinstance(value, list):
        return all(_numbers(v) for v in value)
    return value is None or conforms(value, float)


def _predictions_problem(p: Any, n_classes: int | None) -> str | None:
    if p is None:
        return None
    if not (isinstance(p, dict) and conforms(p.get("y_true"), list[int])
            and conforms(p.get("owner"), list[int])
            and conforms(p.get("probs"), list[list[float]])):
        return "are not lists of labels, owners and probabilities"
    n = len(p["y_true"])
    if len(p["owner"]) != n or len(p["probs"]) != n:
        return f"hold {n} labels, {len(p['owner'])} owners and {len(p['probs'])} probabilities"
    if n_classes is not None and (any(not 0 <= y < n_classes for y in p["y_true"])
                                  or any(len(row) != n_classes for row in p["probs"])):
        return f"do not fit the run's {n_classes} labels"
    return None


def _hint_name(hint: Any) -> str:
    return str(hint).replace("typing.", "").replace("<class '", "").replace("'>", "")
