"""``check_plugin``: the conformance check a device-plugin author runs in their own tests.

It drives the plugin as the acquisition engine does (construct, open, read until a few
frames arrived, close, close again) and checks the class against the contract in
:mod:`tactile_studio.devices.contract`, then raises one :class:`PluginCheckError` listing
every problem found, so an author fixes them all in one round::

    from tactile_studio.devices import check_plugin

    def test_my_plugin_meets_the_contract():
        check_plugin(MyDevice, {"port": "..."})

A new optional hook is checked by adding it to ``contract.OPTIONAL_HOOKS`` (flag,
signature, needed attributes) and, for checks beyond those, a function in ``HOOK_CHECKS``.
"""

from __future__ import annotations

import inspect
import json
import math
import re
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from tactile_studio.devices.contract import (
    OPTIONAL_HOOKS,
    DevicePlugin,
    FrameBatch,
    OptionalHook,
    Setting,
)
from tactile_studio.errors import UserError
from tactile_studio.plugin_settings import SETTING_KINDS
from tactile_studio.sensor.layout import Layout

NAME_RE = re.compile(r"^[a-z][a-z0-9_-]*$")


class PluginCheckError(AssertionError):
    """Every way a plugin breaks the contract, one per line."""

    def __init__(self, plugin: str, problems: list[str]) -> None:
        self.plugin = plugin
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in problems)
        super().__init__(f"device plugin {plugin}: {len(problems)} problem(s)\n{lines}")


def check_plugin(cls: type, settings: Mapping[str, Any] | None = None, *,
                 frames: int = 3, timeout_s: float = 5.0) -> dict[str, Any]:
    """Check ``cls`` against the device contract; raise PluginCheckError listing every
    problem. ``settings`` are what the plugin needs to open (a port, a file); ``frames``
    frames must arrive within ``timeout_s`` seconds. Returns what was observed (frames
    read, batches, malformed counts) for the caller's own assertions."""
    problems: list[str] = []
    label = getattr(cls, "name", "") or getattr(cls, "__name__", repr(cls))
    if not (isinstance(cls, type) and issubclass(cls, DevicePlugin)):
        raise PluginCheckError(label, [f"{cls!r} is not a subclass of DevicePlugin"])
    _check_class(cls, problems)
    _check_schema(cls, problems)
    for hook in OPTIONAL_HOOKS:
        _check_hook(cls, hook, problems)
    observed: dict[str, Any] = {"frames": 0, "batches": 0, "malformed": {}}
    dev = _construct(cls, dict(settings or {}), problems)
    if dev is not None:
        _check_layout(dev, problems)
        _check_cycle(dev, frames, timeout_s, problems, observed)
    if problems:
        raise PluginCheckError(label, problems)
    return observed


def _check_class(cls: type[DevicePlugin], problems: list[str]) -> None:
    if not isinstance(cls.name, str) or not NAME_RE.match(cls.name):
        problems.append(f"name {cls.name!r}: give a lowercase name (letters, digits, - or _), "
                        "the one users type after --device")
    if not isinstance(cls.description, str) or not cls.description.strip():
        problems.append("description: give a one-line description (shown by `devices`)")
    if not isinstance(cls.supports_reconnect, bool):
        problems.append(f"supports_reconnect must be a bool, not {cls.supports_reconnect!r}")
    if inspect.isabstract(cls):
        missing = ", ".join(sorted(cls.__abstractmethods__))
        problems.append(f"abstract methods not implemented: {missing}")


def _check_schema(cls: type[DevicePlugin], problems: list[str]) -> None:
    schema = cls.settings_schema
    if not isinstance(schema, tuple) or not all(isinstance(s, Setting) for s in schema):
        problems.append("settings_schema must be a tuple of Setting")
        return
    seen: set[str] = set()
    for s in schema:
        where = f"setting {s.name!r}"
        if not s.name.isidentifier():
            problems.append(f"{where}: the name must be an identifier (used as --set {s.name}=...)")
        if s.name in seen:
            problems.append(f"{where}: declared twice")
        seen.add(s.name)
        if s.kind not in SETTING_KINDS:
            problems.append(f"{where}: kind {s.kind!r} is not one of {', '.join(SETTING_KINDS)}")
            continue
        if s.kind == "choice" and not s.choices:
            problems.append(f"{where}: a choice needs choices")
        if not s.help.strip():
            problems.append(f"{where}: give a help text (shown by `devices` and the form)")
        try:
            parsed = s.parse(s.default, cls.name)
            again = s.parse(str(parsed).lower() if s.kind == "bool" else str(parsed), cls.name)
        except UserError as exc:
            problems.append(f"{where}: the default {s.default!r} does not parse ({exc})")
            continue
        if parsed != s.default:
            problems.append(f"{where}: the default {s.default!r} is not a {s.kind} "
                            f"(parses to {parsed!r})")
        if again != parsed:
            problems.append(f"{where}: the default's text {str(parsed)!r} parses back to "
                            f"{again!r}, not {parsed!r}")


def _check_hook(cls: type[DevicePlugin], hook: OptionalHook, problems: list[str]) -> None:
    declared = getattr(cls, hook.flag, False)
    base = inspect.getattr_static(DevicePlugin, hook.name, None)
    own = inspect.getattr_static(cls, hook.name, None)
    overridden = own is not base
    if not isinstance(declared, bool):
        problems.append(f"{hook.flag} must be a bool, not {declared!r}")
        return
    if not declared:
        if overridden:
            problems.append(f"{hook.name} is defined but {hook.flag} is False: set "
                            f"{hook.flag} = True to declare it")
        return
    if not overridden:
        problems.append(f"{hook.flag} is True but {hook.name} is not defined")
        return
    if hook.kind == "classmethod" and not isinstance(own, classmethod):
        problems.append(f"{hook.name} must be a @classmethod")
        return
    params = tuple(inspect.signature(getattr(cls, hook.name)).parameters)
    if hook.kind == "method":
        params = params[1:]  # self
    if params != hook.params:
        problems.append(f"{hook.name}{_sig(params)}: the declared signature is "
                        f"{hook.name}{_sig(hook.params)}")
    for attr in hook.attributes:
        if not any(attr in vars(k) for k in cls.__mro__ if k is not DevicePlugin):
            problems.append(f"{hook.name}: set the class attribute {attr}")
    extra = HOOK_CHECKS.get(hook.name)
    if extra is not None:
        extra(cls, problems)


def _sig(params: tuple[str, ...]) -> str:
    return "(" + ", ".join(("cls",) + params) + ")"


def _check_discover(cls: type[DevicePlugin], problems: list[str]) -> None:
    """discover_setting names a str setting; an instant discover returns (value, label)."""
    names = {s.name: s for s in cls.settings_schema}
    target = names.get(cls.discover_setting)
    if target is None:
        problems.append(f"discover_setting {cls.discover_setting!r} is not a setting "
                        f"(settings: {', '.join(names) or 'none'})")
    elif target.kind not in ("str", "path", "choice"):
        problems.append(f"discover_setting {cls.discover_setting!r} is a {target.kind}; "
                        "a scan fills a text setting")
    if not isinstance(cls.discover_instant, bool):
        problems.append(f"discover_instant must be a bool, not {cls.discover_instant!r}")
        return
    if not cls.discover_instant:
        return  # it may scan a radio for seconds: not called here
    try:
        found = cls.discover(cls.validate_settings({}))
    except UserError:
        return  # e.g. no adapter on this machine: a user-facing error is allowed
    except Exception as exc:
        problems.append(f"discover raised {type(exc).__name__}: {exc}")
        return
    if not isinstance(found, list) or not all(
            isinstance(x, tuple) and len(x) == 2 and all(isinstance(v, str) for v in x)
            for x in found):
        problems.append(f"discover must return a list of (value, label) str pairs, got {found!r}")


HOOK_CHECKS: dict[str, Callable[[type[DevicePlugin], list[str]], None]] = {
    "discover": _check_discover,
}


def _construct(cls: type[DevicePlugin], settings: dict[str, Any],
               problems: list[str]) -> DevicePlugin | None:
    try:
        dev = cls(**settings)
    except UserError as exc:
        problems.append(f"{cls.__name__}(**{settings!r}) refused its settings: {exc}")
        return None
    except Exception as exc:
        problems.append(f"{cls.__name__}(**{settings!r}) raised {type(exc).__name__}: {exc}")
        return None
    if not isinstance(getattr(dev, "settings", None), dict):
        problems.append("__init__ must call super().__init__(**settings) (self.settings unset)")
        return None
    try:
        dev.close()  # before open: must be safe
    except Exception as exc:
        problems.append(f"close() before open() raised {type(exc).__name__}: {exc}")
    return dev


def _check_layout(dev: DevicePlugin, problems: list[str]) -> None:
    layout = dev.layout
    if not isinstance(layout, Layout):
        problems.append(f"layout must be a tactile_studio.sensor.layout.Layout, got {layout!r}")
    elif layout.n_channels <= 0:
        problems.append(f"layout {layout.name}: no channels")
    rate = dev.nominal_rate_hz
    if not isinstance(rate, (int, float)) or not math.isfinite(rate) or rate <= 0:
        problems.append(f"nominal_rate_hz must be a positive number, got {rate!r}")


def _check_cycle(dev: DevicePlugin, frames: int, timeout_s: float, problems: list[str],
                 observed: dict[str, Any]) -> None:
    try:
        dev.open()
    except Exception as exc:
        problems.append(f"open() raised {type(exc).__name__}: {exc}")
        _close_twice(dev, problems)
        return
    last = {"device_time": -math.inf, "host_time": -math.inf, "seq": None}
    malformed: dict[str, int] = {}
    deadline = time.monotonic() + timeout_s
    max_frames = max(1, frames)
    try:
        while observed["frames"] < frames and time.monotonic() < deadline:
            batch = dev.read(max_frames)
            observed["batches"] += 1
            before = len(problems)
            _check_batch(dev, batch, max_frames, last, problems)
            if len(problems) > before:
                break
            observed["frames"] += len(batch)
            for kind, n in batch.malformed.items():
                malformed[kind] = malformed.get(kind, 0) + n
            if dev.finished:
                break
        else:
            if observed["frames"] < frames:
                problems.append(f"read() delivered {observed['frames']} of {frames} frames "
                                f"in {timeout_s:g} s")
    except Exception as exc:
        problems.append(f"read() raised {type(exc).__name__}: {exc}")
    observed["malformed"] = malformed
    try:
        info = dev.info()
        json.dumps(info, default=str)
        if not isinstance(info, dict) or info.get("plugin") != dev.name:
            problems.append("info() must return a dict with 'plugin': the plugin name "
                            "(extend super().info())")
    except Exception as exc:
        problems.append(f"info() raised {type(exc).__name__}: {exc}")
    _close_twice(dev, problems)


def _close_twice(dev: DevicePlugin, problems: list[str]) -> None:
    for attempt in ("close()", "a second close()"):
        try:
            dev.close()
        except Exception as exc:
            problems.append(f"{attempt} raised {type(exc).__name__}: {exc}")
            return


def _check_batch(dev: DevicePlugin, batch: Any, max_frames: int, last: dict[str, Any],
                 problems: list[str]) -> None:
    """A FrameBatch whose arrays agree with the layout and with each other, with times
    that never go back (within the batch and since the previous one)."""
    if not isinstance(batch, FrameBatch):
        problems.append(f"read() must return a FrameBatch, got {type(batch).__name__}")
        return
    layout = dev.layout
    raw = batch.raw
    if not isinstance(raw, np.ndarray) or raw.ndim != 2:
        problems.append(f"FrameBatch.raw must be a 2-D numpy array, got {_shape(raw)}")
        return
    n = raw.shape[0]
    if raw.shape[1] != layout.n_channels:
        problems.append(f"FrameBatch.raw has {raw.shape[1]} channels; layout {layout.name} "
                        f"has {layout.n_channels}")
    if raw.dtype != np.dtype(layout.raw_dtype):
        problems.append(f"FrameBatch.raw dtype {raw.dtype}; layout {layout.name} says "
                        f"{layout.raw_dtype}")
    if n > max_frames:
        problems.append(f"read({max_frames}) returned {n} frames")
    for key in ("device_time", "host_time", "seq"):
        arr = getattr(batch, key)
        if arr is None:
            continue
        if not isinstance(arr, np.ndarray) or arr.shape != (n,):
            problems.append(f"FrameBatch.{key} must be a numpy array of shape ({n},), "
                            f"got {_shape(arr)}")
            continue
        if key == "seq":
            if not np.issubdtype(arr.dtype, np.integer):
                problems.append(f"FrameBatch.seq must hold integers, got {arr.dtype}")
                continue
            full = arr if last["seq"] is None else np.concatenate([[last["seq"]], arr])
            if n and np.any(np.diff(full) <= 0):
                problems.append("FrameBatch.seq must increase from frame to frame")
            if n:
                last["seq"] = int(arr[-1])
            continue
        if not np.issubdtype(arr.dtype, np.floating) or not np.all(np.isfinite(arr)):
            problems.append(f"FrameBatch.{key} must hold finite float seconds")
            continue
        full = np.concatenate([[last[key]], arr])
        if n and np.any(np.diff(full) < 0):
            problems.append(f"FrameBatch.{key} goes back in time")
        if n:
            last[key] = float(arr[-1])
    if not isinstance(batch.malformed, dict) or not all(
            isinstance(k, str) and isinstance(v, (int, np.integer)) and v >= 0
            for k, v in batch.malformed.items()):
        problems.append(f"FrameBatch.malformed must map kind (str) to a count >= 0, "
                        f"got {batch.malformed!r}")


def _shape(x: Any) -> str:
    return f"shape {x.shape}" if isinstance(x, np.ndarray) else type(x).__name__
