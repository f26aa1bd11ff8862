"""``check_stage`` / ``check_force``: conformance checks for instrument-plugin authors.

Like :func:`tactile_studio.devices.check_plugin`, each drives the plugin the way the
characterisation procedure does and raises one :class:`InstrumentCheckError` listing
every problem found::

    from tactile_studio.characterise import check_stage
    def test_my_stage():
        check_stage(MyStage, {"port": "..."})

``device`` (optional) is the sensor device to couple to (the simulated instruments
need the simulated sensor); it is streamed (``open_stream``) during the check. That is
why the checks live here, above acquisition, and not beside the contracts in
``instruments/``, which sits below the recording and may not open a stream.
"""

from __future__ import annotations

import re
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import UserError
from tactile_studio.instruments.contract import ForcePlugin, ForceSamples, StagePlugin
from tactile_studio.plugin_settings import Setting

NAME_RE = re.compile(r"^[a-z][a-z0-9_-]*$")


class InstrumentCheckError(AssertionError):
    """Every way an instrument plugin breaks its contract, one per line."""

    def __init__(self, plugin: str, problems: list[str]) -> None:
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in problems)
        super().__init__(f"instrument plugin {plugin}: {len(problems)} problem(s)\n{lines}")


def _check_class(cls: type, base: type, problems: list[str]) -> None:
    if not (isinstance(cls, type) and issubclass(cls, base)):
        raise InstrumentCheckError(repr(cls), [f"{cls!r} is not a subclass of {base.__name__}"])
    if not isinstance(cls.name, str) or not NAME_RE.match(cls.name):
        problems.append(f"name {cls.name!r}: give a lowercase name (letters, digits, - or _)")
    if not cls.description:
        problems.append("description is empty: say in one line what the instrument is")
    seen = set()
    for s in cls.settings_schema:
        if not isinstance(s, Setting):
            problems.append(f"settings_schema entry {s!r} is not a Setting")
            continue
        if s.name in seen:
            problems.append(f"setting {s.name!r} is declared twice")
        seen.add(s.name)
        try:
            s.parse(s.default, cls.name)
        except UserError as exc:
            problems.append(f"setting {s.name!r}: its default does not validate ({exc})")


def _close_twice(instrument: StagePlugin | ForcePlugin, problems: list[str]) -> None:
    """close() must be safe to call twice: the second is what an exit hook does."""
    for _ in range(2):
        try:
            instrument.close()
        except Exception as exc:
            problems.append(f"close() raised {exc!r} (must be safe twice)")
            break


class _Streaming:
    """Streams ``device`` while instruments are checked (their clock may be its own)."""

    def __init__(self, device: DevicePlugin | None) -> None:
        self.engine = None if device is None else open_stream(device)

    def __enter__(self) -> _Streaming:
        if self.engine is not None:
            self.engine.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.engine is not None:
            self.engine.stop()


def check_stage(cls: type, settings: Mapping[str, Any] | None = None, *,
                device: DevicePlugin | None = None, move_mm: float = 1.0) -> dict[str, Any]:
    """Construct, open, couple, home, move by ``move_mm`` in x and z, wait, read the
    position, move back, retract, close twice. Returns the positions observed."""
    problems: list[str] = []
    _check_class(cls, StagePlugin, problems)
    observed: dict[str, Any] = {}
    try:
        stage = cls(**dict(settings or {}))
    except Exception as exc:
        raise InstrumentCheckError(cls.name, [*problems, f"construction failed: {exc!r}"]) from None
    with _Streaming(device):
        try:
            stage.open()
            stage.couple(device)
            stage.home()
            home = np.array(stage.position())
            stage.move_by(dx=move_mm, dz=-move_mm / 2, speed=5.0)
            stage.wait_until_still(timeout_s=30.0)
            moved = np.array(stage.position())
            observed.update(home=home.tolist(), moved=moved.tolist())
            want = home + [move_mm, 0.0, -move_mm / 2]
            if not np.allclose(moved, want, atol=0.02):
                problems.append(f"after move_by the position is {moved.tolist()}, expected "
                                f"{want.tolist()} (within 0.02 mm)")
            stage.move_to(*home.tolist(), speed=5.0)
            stage.wait_until_still(timeout_s=30.0)
            stage.retract()
            if stage.position()[2] < home[2] - 0.02:
                problems.append("retract() left the indenter lower than home")
            clock = stage.clock()
            if not isinstance(clock.now(), float):
                problems.append("clock().now() must return float seconds")
        except Exception as exc:
            problems.append(f"driving the stage failed: {exc!r}")
        finally:
            _close_twice(stage, problems)
    if problems:
        raise InstrumentCheckError(cls.name, problems)
    return observed


def check_force(cls: type, settings: Mapping[str, Any] | None = None, *,
                device: DevicePlugin | None = None, stage: StagePlugin | None = None,
                samples: int = 5, timeout_s: float = 5.0) -> dict[str, Any]:
    """Construct, open, couple, tare, read until ``samples`` arrive (bounded), check their
    shape and times, close twice. ``stage`` (already coupled) advances a simulated clock."""
    problems: list[str] = []
    _check_class(cls, ForcePlugin, problems)
    try:
        force = cls(**dict(settings or {}))
    except Exception as exc:
        raise InstrumentCheckError(cls.name, [*problems, f"construction failed: {exc!r}"]) from None
    got: list[ForceSamples] = []
    with _Streaming(device):
        try:
            force.open()
            force.couple(device, stage)
            force.tare()
            deadline = time.monotonic() + timeout_s
            while sum(len(s) for s in got) < samples and time.monotonic() < deadline:
                if stage is not None:
                    stage.clock().sleep(0.05)
                else:
                    time.sleep(0.02)
                s = force.read()
                if not isinstance(s, ForceSamples):
                    problems.append(f"read() returned {type(s).__name__}, not ForceSamples")
                    break
                got.append(s)
            n = sum(len(s) for s in got)
            if n < samples:
                problems.append(f"only {n} samples in {timeout_s} s (wanted {samples})")
            elif got:
                t = np.concatenate([s.t for s in got])
                f = np.concatenate([s.f for s in got])
                if f.shape[1:] != (3,):
                    problems.append(f"forces have shape {f.shape}, expected (n, 3)")
                if np.any(np.diff(t) < 0):
                    problems.append("sample times go backwards")
                if not np.all(np.isfinite(f)):
                    problems.append("forces contain NaN or inf")
        except Exception as exc:
            problems.append(f"driving the force reference failed: {exc!r}")
        finally:
            _close_twice(force, problems)
    if problems:
        raise InstrumentCheckError(cls.name, problems)
    return {"samples": sum(len(s) for s in got)}
