"""Opening and resuming collection sessions: a runner over the acquisition seam, Qt-free.

Both the GUI and ``tactile-studio collect`` use these, so a session file looks the same
whoever ran it. A collection is not a second way to assemble a recording: its file is
the :class:`~tactile_studio.acquisition.live_acquisition.LiveAcquisition`'s recording
(``start_recording``, the steps the main window uses); a caller holding only a stream
gets a session of its own that shares it.

Resume: a session file whose writer was killed cannot be reopened for writing (HDF5's
SWMR "open for write" flag stays set), and appending to a file in place risks the very
trials we want to keep. So a resume claims the file (one writer per file: a recording or
another resume of it is refused, tactile_studio/file_claims.py), copies everything it
holds (frames, baselines, events, trials, counters) into a staged file of its own next
to it and flushes it; keeps the original as ``<name>.bak-N.h5`` (a hard link, else a
copy; never over an existing backup) and then publishes the copy onto the original name
with ``os.replace`` (atomic on POSIX), so a complete session is at that name at every
instant. The copy's writer stays open and recording continues in it at the next trial of
the stored block order.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.acquisition.file_sink import close_file_sink
from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.devices.frame_stream import EngineState, LiveStream
from tactile_studio.devices.registry import plugin_class
from tactile_studio.errors import SessionFileError, UserError
from tactile_studio.file_claims import first_free
from tactile_studio.participant_id import PARTICIPANT_RE, check_participant  # noqa: F401
from tactile_studio.paths import make_out_dir
from tactile_studio.plugin_settings import validate_settings
from tactile_studio.protocol.randomise import block_orders, order_seed, practice_order
from tactile_studio.protocol.trial_check import TrialChecker, unknown_gestures
from tactile_studio.protocol.trial_runner import Clock, RunnerOptions, State, TrialRunner
from tactile_studio.storage.format.protocol_file import CollectionProtocol, restored_protocol
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.trials import trials_done
from tactile_studio.storage.recording.recorder import Recorder

COPY_CHUNK = 8192
_NOT_COPIED = ("layout", "device", "schema_version", "app_version")


@dataclass
class Collection:
    """A running collection: the runner plus what it writes to. ``close()`` when done."""


    runner: TrialRunner
    recorder: Recorder
    engine: LiveStream
    path: Path
    protocol: CollectionProtocol
    participant: str
    seed: int
    resumed: bool = False
    backup: Path | None = None
    touches: str = ""                  # who makes the touches, in words (touch_source)
    restore_gesture: str | None = None  # a simulator's own mode before the session
    pilot: bool = False                # a rehearsal: marked so, left out of datasets

    def end_if_cut_off(self) -> str | None:
        """End the session when it cannot go on, and say why in one line (None: it goes
        on): its file cannot be written, or its device ended for good (failed, or stopped;
        a device that is reconnecting may come back, and the session waits for it). The
        runner is aborted first, so the abort is in the file after the completed trials.
        Headless collection and the console both ask this at every tick."""
        if self.runner.state in State.DONE:
            return None
        if self.recorder.write_error:
            why = f"{self.path}: {self.recorder.write_error}"
        elif EngineState(self.engine.state).is_over:
            why = f"device {self.engine.device_name}: {self.engine.error or self.engine.state}"
        else:
            return None
        self.runner.abort()
        return why

    def close(self) -> None:
        """Stop (aborting an unfinished runner; its finished trials stay) and close the
        file cleanly. The engine is left running: it belongs to the caller (a simulator
        the session quietened goes back to what it did before)."""
        if self.runner.state not in State.DONE:
            self.runner.abort()
        close_file_sink(self.recorder)  # hours booked once, whoever stops it first
        if self.restore_gesture is not None:
            self.engine.device.set_gesture(self.restore_gesture)
            self.restore_gesture = None


def quiet_simulator(engine: LiveStream) -> str | None:
    """A simulated device performing by itself (its demo cycle, gesture ``auto``, or a
    scripted gesture) goes idle from the next frame: a collection records the
    participant's touches only, never the simulator's own. Returns the mode it had (to go
    back to when the session closes), None when it was idle or is not a simulator."""
    device = engine.device
    mode = str((getattr(device, "settings", None) or {}).get("gesture", "idle"))
    if not hasattr(device, "set_gesture") or mode == "idle":
        return None
    device.set_gesture("idle")
    return mode


def touch_source(engine: LiveStream, virtual: bool = False, pilot: bool = False) -> str:
    """Who makes the touches a collection records, as the console shows it."""
    if virtual or (pilot and can_perform(engine)):
        return "Touches: a virtual participant, on the simulated sensor"
    if pilot:
        return (f"Touches: you, rehearsing on the sensor "
                f"({engine.device_info().get('plugin') or 'device'})")
    if hasattr(engine.device, "set_gesture"):
        return ("Touches: simulated sensor, idle until a virtual participant or a person "
                "touches (its demo gestures are off)")
    return f"Touches: the sensor ({engine.device_info().get('plugin') or 'device'})"


def can_perform(engine: LiveStream) -> bool:
    """The device is a simulator a virtual participant can perform on."""
    return hasattr(engine.device, "perform")


def session_names(out_dir: Path, participant: str, protocol: CollectionProtocol, pilot: bool = False
                  ) -> Callable[[int], Path]:
    """The k-th candidate name of a new session: ``P01_shear9_<time>.h5``, then ``-2``,
    ``-3``... The writer's claim decides (``first_free``): two collections that start in
    one second in one folder both record, each into its own file. A pilot's name begins
    ``PILOT_``, so it is told apart in any file list."""
    stem = f"{participant}_{protocol.name}_{time.strftime('%Y%m%d-%H%M%S')}"
    if pilot:
        stem = f"PILOT_{stem}"
    return lambda k: out_dir / (f"{stem}.h5" if k == 0 else f"{stem}-{k + 1}.h5")


def session_metadata(protocol: CollectionProtocol, participant: str, seed: int,
                     orders: list[list[str]],
                     practice: list[str], condition: str = "", pilot: bool = False
                     ) -> dict[str, Any]:
    """What a collection's file says of itself; ``pilot: true`` marks a rehearsal, which
    datasets, ``train`` and ``info``'s study leave out (storage/format/session_set.py)."""
    pilot_mark = {"pilot": True} if pilot else {}
    return {**pilot_mark,
        "participant": participant, "protocol": protocol.name, "condition": condition,
        "gestures": protocol.gesture_names, "source": "collect",
        "protocol_spec": protocol.to_dict(), "seed": int(seed),
        "order_seed": order_seed(protocol, participant, seed),
        "block_order": orders, "practice_order": practice, "trial_order": protocol.order,
    }


@dataclass(frozen=True)
class CollectionSettings:
    """What a new collection is (who, which protocol, where) and how its runner goes:
    the setup form's choices, ``collect``'s options, a test's few."""

    protocol: CollectionProtocol
    participant: str
    out_dir: str | os.PathLike[str]
    seed: int = 0
    condition: str = ""
    auto_continue: bool = True
    hold_flagged: bool = False
    #: the caller's file name (refused if taken or being written); default: a new name
    path: str | os.PathLike[str] | None = None
    #: the sensor's health at the start (tactile_studio.health.gate), kept in the file
    wellness: dict[str, Any] | None = None
    #: a rehearsal: the file marked so and named ``PILOT_...`` (see session_metadata)
    pilot: bool = False
    #: the model that checks each trial (protocol/trial_check.py); its description is
    #: the metadata's ``trial_check``
    trial_check: TrialChecker | None = None
    #: fit the check to the participant with their first block's trials
    personalise_check: bool = False


def acquisition_of(source: LiveAcquisition | LiveStream) -> LiveAcquisition:
    """The acquisition session a collection records through: the caller's, or, for a
    bare stream (a test's, a benchmark's), one of its own that shares it (and never
    starts or stops it)."""
    if isinstance(source, LiveAcquisition):
        if source.engine is None:
            raise RuntimeError("open a device on the acquisition session before collecting")
        return source
    acquisition = LiveAcquisition()
    acquisition.share(source)
    return acquisition


def open_collection(settings: CollectionSettings, source: LiveAcquisition | LiveStream, *,
                    beeper: Any = None, clock: Clock | None = None) -> Collection:
    """Create the session file and a runner in ``setup``; call ``runner.start()``.

    ``source``: the acquisition session (its recording is the collection's file) or a
    bare stream (:func:`acquisition_of`). Its stream may be started or not: the file
    opened before ``start()`` (the start order of an LiveAcquisition) has rows equal
    to stream frames; on a running stream the file begins now.
    """
    s = settings
    acquisition = acquisition_of(source)
    engine = acquisition.engine
    assert engine is not None  # acquisition_of says so
    participant = check_participant(s.participant)
    out = make_out_dir(s.out_dir)  # a missing folder is made: the rule of every output
    orders = block_orders(s.protocol, participant, s.seed)
    practice = practice_order(s.protocol, participant, s.seed)
    meta = session_metadata(s.protocol, participant, s.seed, orders, practice, s.condition,
                            s.pilot)
    if s.wellness is not None:  # the sensor's health at the start
        meta["wellness"] = s.wellness
        meta["sensor_id"] = s.wellness.get("sensor_id") or None
    if s.trial_check is not None:
        meta["trial_check"] = check_metadata(s.trial_check, s.protocol)
    restore = quiet_simulator(engine)  # before the file: its settings say idle
    try:
        if s.path is not None:  # the caller's name: refused if taken or being written
            rec = acquisition.start_recording(Path(s.path), meta)
        else:
            rec = first_free(session_names(out, participant, s.protocol, s.pilot),
                             lambda p: acquisition.start_recording(p, meta))
    except BaseException:
        if restore is not None:
            engine.device.set_gesture(restore)
        raise
    options = RunnerOptions(beeper=beeper, clock=clock, auto_continue=s.auto_continue,
                            hold_flagged=s.hold_flagged, trial_check=s.trial_check,
                            personalise_check=s.personalise_check)
    runner = TrialRunner(s.protocol, engine, rec, participant, orders, practice=practice,
                         options=options)
    return Collection(runner, rec, engine, Path(rec.path), s.protocol, participant,
                      s.seed, touches=touch_source(engine, pilot=s.pilot),
                      restore_gesture=restore, pilot=s.pilot)


def check_metadata(trial_check: TrialChecker, protocol: CollectionProtocol) -> dict[str, Any]:
    """The session's ``trial_check`` metadata: the model's description and the protocol's
    gestures it does not know (not scored)."""
    return {**trial_check.describe(),
            "not_scored": unknown_gestures(trial_check, protocol.gesture_names)}


def read_resume_info(path: str | os.PathLike,
                     at_hand: CollectionProtocol | None = None) -> dict[str, Any]:
    """What a resume needs from a session file (protocol, participant, seed, device...);
    ``at_hand``: the protocol file the experimenter has chosen, whose folder holds the
    images when it is the file's protocol (``restored_protocol``)."""
    with SessionFile(path) as old:
        meta = dict(old.metadata)
        if meta.get("source") != "collect" or "block_order" not in meta:
            raise SessionFileError(f"{path}: not a collection session (nothing to resume)")
        protocol = restored_protocol(meta.get("protocol_spec"),
                                     f"{Path(path).name}: protocol_spec", at_hand)
        total = sum(len(o) for o in meta["block_order"])
        return {"protocol": protocol, "participant": meta["participant"],
                "seed": int(meta.get("seed", 0)), "device": meta.get("device", {}),
                "sensor_id": meta.get("sensor_id"),
                "other_sensor": meta.get("other_sensor") or [],
                "pilot": bool(meta.get("pilot")),
                "layout": old.layout.name, "trials_done": trials_done(old.trials),
                "trials_total": total,
                "frames": old.n_frames}


def _backup_name(path: Path, n: int) -> Path:
    return path.with_name(f"{path.stem}.bak-{n}{path.suffix}")


def _keep_backup(path: Path) -> Path:
    """The original under the first free ``.bak-N`` name: a hard link (instant, same
    bytes), else a copy; never over an existing backup (a name taken meanwhile, by a
    copy of the folder or a user, is skipped). Returns it."""
    n = 1
    while True:
        backup = _backup_name(path, n)
        n += 1
        if os.path.lexists(backup):
            continue
        try:
            os.link(path, backup)
            return backup
        except FileExistsError:
            continue
        except OSError:  # no hard links here: a copy, created exclusively
            try:
                with open(path, "rb") as src, open(backup, "xb") as dst:
                    shutil.copyfileobj(src, dst, 1 << 20)
            except FileExistsError:
                continue
            except BaseException:
                backup.unlink(missing_ok=True)
                raise
            shutil.copystat(path, backup)
            return backup


class OtherSensorRefused(UserError):
    """A resume on another device or sensor than the file's, with no note saying why:
    the command names the option that overrides it, the console offers the choice."""

    def __init__(self, path: Path, why: str) -> None:
        self.path, self.why = path, why
        super().__init__(f"{path}: {why}; resume on the same sensor (or give the reason "
                         "with --allow-other-sensor NOTE)")


def other_sensor(info: dict[str, Any], engine: LiveStream) -> str | None:
    """Why ``engine`` is not the device and sensor the file was recorded with (another
    plugin, another frame rate, another sensor ID such as the simulator's seed), or None
    when it is. A sensor an earlier resume went on to with a note is the file's too: the
    file's device is then that one, and resuming it again needs no second note."""
    old_plugin = (info.get("device") or {}).get("plugin")
    new_plugin = engine.device_info().get("plugin")
    if old_plugin and new_plugin and old_plugin != new_plugin:
        return f"recorded with device {old_plugin}, not {new_plugin}"
    # one file, one frame rate: trials, durations and info's rate count on it
    old_rate = _rate((info.get("device") or {}).get("nominal_rate_hz"))
    new_rate = _rate(engine.nominal_rate_hz)
    if old_rate and new_rate and abs(old_rate - new_rate) > 1e-6 * old_rate:
        return f"recorded at {old_rate:g} Hz, but the device runs at {new_rate:g} Hz"
    old_sensor, new_sensor = info.get("sensor_id"), engine.sensor_id()
    approved = {str(e.get("sensor_id")) for e in info.get("other_sensor") or []
                if isinstance(e, dict) and e.get("sensor_id")}
    if old_sensor and new_sensor and str(new_sensor) not in {str(old_sensor), *approved}:
        return f"recorded on sensor {old_sensor}, but the device is sensor {new_sensor}"
    return None


def _rate(value: Any) -> float | None:
    """A nominal rate in Hz, None when unknown (missing, not a number, not positive)."""
    try:
        rate = float(value)
    except (TypeError, ValueError):
        return None
    return rate if np.isfinite(rate) and rate > 0 else None


def resume_device(info: dict[str, Any]) -> tuple[str | None, dict[str, Any]]:
    """The device a resume of the file (``read_resume_info``) runs on unless the user
    says otherwise: the file's plugin and its settings that differ from the plugin's
    defaults, so the sensor is the file's (a simulator's seed); a simulator's speed and
    scripted gesture are left out (a virtual participant's, not a session's). (None, {})
    when the file names no plugin installed here."""
    old = info.get("device") or {}
    name = old.get("plugin") or None
    if name is None:
        return None, {}
    try:
        schema = plugin_class(name).settings_schema
    except UserError:
        return None, {}
    defaults = {s.name: s.default for s in schema}
    settings = {k: v for k, v in (old.get("settings") or {}).items()
                if k in defaults and defaults[k] != v}
    if name == "simulated":
        settings.pop("speed", None)
        settings.pop("gesture", None)
    return name, settings


def device_differences(info: dict[str, Any], name: str | None,
                       settings: dict[str, Any]) -> str | None:
    """How device ``name`` with ``settings`` (a form's or ``--set``'s values) differs from
    the device the file (``read_resume_info``) was recorded with, in words ("seed 5 there,
    7 here"); None when it is the same, or when that cannot be told before the device is
    opened (the live device, a plugin not installed here, a value the form refuses).
    Settings such as a port may differ on the same sensor: ``other_sensor`` decides."""
    file_name, file_settings = resume_device(info)
    if name is None or file_name is None:
        return None
    if name != file_name:
        return f"the file was recorded with device {file_name}, not {name}"
    schema = plugin_class(name).settings_schema
    try:
        theirs = validate_settings(schema, file_settings, name)
        mine = validate_settings(schema, settings, name)
    except UserError:
        return None
    ignored = ("speed", "gesture") if name == "simulated" else ()  # not the sensor's
    diffs = [f"{k} {theirs[k]} there, {mine[k]} here" for k in theirs
             if k not in ignored and theirs[k] != mine[k]]
    return (f"the {name} device's settings differ from the file's ({'; '.join(diffs)})"
            if diffs else None)


def last_device_time(old: SessionFile) -> float | None:
    """The old file's last device time, which a resumed run's clock must follow (None
    for a file without frames or with no finite time there)."""
    n = old.n_frames
    if n == 0:
        return None
    last = float(old.column("device_time", n - 1, n)[0])
    return last if np.isfinite(last) else None


def resume_collection(path: str | os.PathLike, source: LiveAcquisition | LiveStream, *,
                      beeper: Any = None, clock: Clock | None = None, auto_continue: bool = True,
                      hold_flagged: bool = False,
                      allow_other_sensor: str | None = None,
                      protocol_at_hand: CollectionProtocol | None = None,
                      trial_check: TrialChecker | None = None) -> Collection:
    """Continue a killed or closed session at the next trial of its stored order.

    Refused on another device or sensor than the file's, unless ``allow_other_sensor``
    gives the reason (stored as a note and in the metadata). ``source``: as for
    :func:`open_collection`. ``protocol_at_hand``: see ``read_resume_info``."""
    path = Path(path)
    acquisition = acquisition_of(source)
    engine = acquisition.engine
    assert engine is not None  # acquisition_of says so
    info = read_resume_info(path, protocol_at_hand)
    if info["trials_done"] >= info["trials_total"]:
        raise UserError(f"{path}: session is complete ({info['trials_done']} trials); "
                        "nothing to resume")
    if engine.layout.name != info["layout"]:
        raise UserError(f"{path}: recorded with layout {info['layout']}, but the device "
                        f"delivers {engine.layout.name}")
    other = other_sensor(info, engine)
    note = " ".join(str(allow_other_sensor or "").split())
    if other and not note:
        raise OtherSensorRefused(path, other)
    restore = quiet_simulator(engine)  # before the copy: its settings say idle
    with SessionFile(path) as old:
        meta = {k: v for k, v in old.metadata.items() if k not in _NOT_COPIED}
        meta["session_id"] = old.session_id  # kept (derived once for files without one)
        meta["resumes"] = int(meta.get("resumes", 0)) + 1
        if trial_check is not None:  # the check from here on (a trial keeps its model id)
            meta["trial_check"] = check_metadata(trial_check, info["protocol"])
        if other:
            meta["other_sensor"] = [*meta.get("other_sensor", []),
                                    {"resume": meta["resumes"], "why": other, "note": note,
                                     "sensor_id": engine.sensor_id(),
                                     "device": engine.device_info()}]
        n = old.n_frames
        after = last_device_time(old)
        # the file is claimed here (a recording or another resume of it is refused
        # before anything is copied); the copy is staged beside it until published
        rec = acquisition.start_recording(path, meta, row_offset=n,
                                          base_counters=old.journal.counters, start=False,
                                          overwrite=True, staged=True)
        try:
            trials = rec.copy_earlier(old, COPY_CHUNK)
        except BaseException:
            rec.stop(discard=True)  # the staged copy goes; the file is as it was
            raise
    try:
        if engine.baseline is not None:
            rec.add_baseline(engine.baseline, n)
        # a new recording segment: a device clock that starts again continues the file's
        # (shifted one nominal frame after its last time); the recorder writes the resume
        # event with the offset once the first frame shows which clock the device has
        rate = float(engine.nominal_rate_hz or 0.0)
        backup = _keep_backup(path)
        rec.begin_segment(after, 1.0 / rate if rate > 0 else 0.0, from_file=path.name,
                          backup=backup.name, trials=len(trials))
        if other:
            rec.add_note(f"resumed on another sensor ({other}): {note}", frame=n)
        rec.publish()  # atomic: a complete session is at ``path`` at every instant
    except BaseException:
        rec.stop(discard=True)
        raise
    rec.start()
    protocol = info["protocol"]
    runner = TrialRunner(protocol, engine, rec, info["participant"],
                         meta["block_order"], practice=meta.get("practice_order", []),
                         previous_trials=trials,
                         options=RunnerOptions(beeper, clock, auto_continue, hold_flagged,
                                               trial_check))
    notes = rec.writer.metadata.get("notes", "")  # the earlier notes and the resume's own
    runner.notes = [line for line in str(notes).split("\n") if line]
    pilot = bool(meta.get("pilot"))  # a rehearsal stays one
    return Collection(runner, rec, engine, path, protocol, info["participant"],
                      info["seed"], resumed=True, backup=backup,
                      touches=touch_source(engine, pilot=pilot),
                      restore_gesture=restore, pilot=pilot)
