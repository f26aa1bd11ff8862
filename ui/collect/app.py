"""Ways into the collection console: the main window's menu and the ``collect`` command.

``add_collection_menu`` puts "New collection session..." and "Resume collection
session..." into a menu; the console then shares the main window's live engine when it
is streaming. ``run_console`` is what ``tactile-studio collect`` (without
``--virtual-participant``) calls to open the console pre-filled, or resuming a file;
``build_console`` is its event-loop-free part (tests check the pre-filled form).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QMenu, QWidget

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.errors import UserError
from tactile_studio.protocol.console_options import ConsoleOptions
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


def build_console(options: ConsoleOptions) -> CollectConsole:
    """A shown console with its setup form pre-filled from ``options`` (or resuming
    ``options.resume``).

    The form stays editable: the experimenter checks it and clicks "Open session". A
    resume that fails shows its one-line error under the form. Needs a QApplication.
    """
    o = options
    acquisition = LiveAcquisition()
    acquisition.marker_streams = tuple(o.markers)
    if o.silence_warning_s is not None:
        acquisition.silence_warning_s = o.silence_warning_s
    console = CollectConsole(acquisition=acquisition)
    try:
        console.setup.prefill(
            o.protocol, o.participant, o.device,
            {k: _text(v) for k, v in o.device_settings.items()},
            o.out_dir, o.blocks, o.seed, o.condition, o.pilot)
        if o.qc:
            console.setup.qc.prefill(**o.qc)
    except UserError:
        console.close()
        console.deleteLater()
        raise
    console.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    console.lsl_toggle.setChecked(o.lsl)  # streams once a session is open
    console.show()
    if o.resume is not None:
        console.resume_from(o.resume)
    return console


def run_console(options: ConsoleOptions) -> int:
    """Open the console pre-filled (or resuming) and run until it is closed."""
    from tactile_studio.ui.application import ensure_app

    app = ensure_app()
    console = build_console(options)
    # held until the window is closed (and deleted), also if the loop ends first
    _RUNNING.append(console)
    console.destroyed.connect(lambda *_: console in _RUNNING and _RUNNING.remove(console))
    return int(app.exec())
