"""Ways into the collection console: the main window's menu and the ``collect`` command.

``add_collection_menu`` puts "New collection session..." and "Resume collection
session..." into a menu; the console then shares the main window's live engine when it
is streaming. ``run_console`` is what ``tactile-studio collect`` (without
``--virtual-participant``) calls to open the console pre-filled, or resuming a file;
``build_console`` is its event-loop-free part (tests check the pre-filled form).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QMenu, QWidget

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.errors import UserError
from tactile_studio.ui.collect.console import CollectConsole

LiveSource = Callable[[], tuple[LiveStream | None, str | None]]
_RUNNING: list[CollectConsole] = []  # consoles opened by run_console


def open_console(live: LiveSource | None = None, resume: bool = False,
                 keep: list[CollectConsole] | None = None) -> CollectConsole:
    """A new console window; shares the live engine from ``live()`` if it is running."""
    engine, name = live() if live is not None else (None, None)
    if engine is not None and not engine.running:
        engine, name = None, None
    console = CollectConsole(engine=engine, live_device=name, acquisition=LiveAcquisition())
    console.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    if keep is not None:  # the caller holds a reference while the window is open
        keep.append(console)
        console.destroyed.connect(lambda *_: console in keep and keep.remove(console))
    console.show()
    if resume:
        console.setup.choose_resume_file()
    return console


def add_collection_menu(window: QWidget, menu: QMenu, live: LiveSource | None = None) -> None:
    """Add the collection actions to ``menu`` (e.g. the main window's File menu)."""
    consoles: list[CollectConsole] = []
    window._collect_consoles = consoles  # type: ignore[attr-defined]
    menu.addSeparator()
    new = QAction("New &collection session\u2026", window)
    new.triggered.connect(lambda: open_console(live, keep=consoles))
    menu.addAction(new)
    resume = QAction("Resume collection session\u2026", window)
    resume.triggered.connect(lambda: open_console(live, resume=True, keep=consoles))
    menu.addAction(resume)


def _text(value: Any) -> str:
    """A setting as the form shows it: 5.0 as 5, other floats exactly."""
    if isinstance(value, float):
        return str(int(value)) if value.is_integer() else repr(value)
    return str(value)


def build_console(protocol: str | os.PathLike | None = None, participant: str = "",
                  device: str | None = None, device_settings: dict[str, Any] | None = None,
                  out_dir: str | os.PathLike | None = None, blocks: int | None = None,
                  seed: int | None = None, condition: str = "",
                  resume: str | os.PathLike | None = None, lsl: bool = False,
                  markers: list[str] | None = None,
                  silence_warning_s: float | None = None, pilot: bool = False,
                  qc: dict[str, Any] | None = None) -> CollectConsole:
    """A shown console with its setup form pre-filled (or resuming ``resume``);
    ``markers``: LSL marker streams its recording takes in (acquisition/marker_recording.py);
    ``silence_warning_s``: how long the device may be silent before it is said;
    ``qc``: the setup's trial check (``model``, ``top_k``, ``threshold``: ``--qc-model``).

    The form stays editable: the experimenter checks it and clicks "Open session". A
    resume that fails shows its one-line error under the form. Needs a QApplication.
    """
    acquisition = LiveAcquisition()
    acquisition.marker_streams = tuple(markers or ())
    if silence_warning_s is not None:
        acquisition.silence_warning_s = silence_warning_s
    console = CollectConsole(acquisition=acquisition)
    try:
        console.setup.prefill(
            None if protocol is None else str(protocol), participant, device,
            {k: _text(v) for k, v in (device_settings or {}).items()},
            None if out_dir is None else str(out_dir), blocks, seed, condition, pilot)
        if qc:
            console.setup.qc.prefill(**qc)
    except UserError:
        console.close()
        console.deleteLater()
        raise
    console.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    console.lsl_toggle.setChecked(lsl)  # streams once a session is open
    console.show()
    if resume is not None:
        console.resume_from(resume)
    return console


def run_console(protocol: str | os.PathLike | None = None, participant: str = "",
                device: str | None = None, device_settings: dict[str, Any] | None = None,
                out_dir: str | os.PathLike | None = None, blocks: int | None = None,
                seed: int | None = None, condition: str = "",
                resume: str | os.PathLike | None = None, lsl: bool = False,
                markers: list[str] | None = None,
                silence_warning_s: float | None = None, pilot: bool = False,
                qc: dict[str, Any] | None = None) -> int:
    """Open the console pre-filled (or resuming ``resume``) and run until it is closed."""
    from tactile_studio.ui.application import ensure_app

    app = ensure_app()
    console = build_console(protocol, participant, device, device_settings, out_dir, blocks,
                            seed, condition, resume, lsl=lsl, markers=markers,
                            silence_warning_s=silence_warning_s, pilot=pilot, qc=qc)
    # held until the window is closed (and deleted), also if the loop ends first
    _RUNNING.append(console)
    console.destroyed.connect(lambda *_: console in _RUNNING and _RUNNING.remove(console))
    return int(app.exec())
