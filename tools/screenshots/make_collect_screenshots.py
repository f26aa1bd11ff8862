"""Screenshots of the collection screens from a real session on the simulated sensor.

``QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_collect_screenshots.py
[OUT_DIR]`` (default: this folder) writes collect-*.png: the setup step (with the
simulator's settings form), the participant screen prompting the next gesture, refusing
another gesture's key, during a trial countdown and in a break, and the experimenter
console waiting for the prompted gesture and with a flagged trial waiting for a
decision; then a pilot (a rehearsal: the console and the participant screen marked
PILOT while a virtual participant performs), and the main window's device panel while a
collection holds its simulator idle. Works headless (QT_QPA_PLATFORM=offscreen); takes
about 40 s.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

PARTICIPANT_SIZE = (1600, 900)
CONSOLE_SIZE = (1500, 900)


def _pump(app: object, until: Callable[[], bool], timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not until():
        app.processEvents()  # type: ignore[attr-defined]
        time.sleep(0.005)
        if time.monotonic() > deadline:
            raise TimeoutError("screenshot session did not reach the expected state")


def _settle(app: object, seconds: float) -> None:
    _pump(app, lambda t=time.monotonic() + seconds: time.monotonic() > t)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else (Path(__file__).resolve().parents[2] / "docs" / "screenshots")
    out.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    tmp = Path(tempfile.mkdtemp(prefix="collect-shots-"))
    os.environ["TACTILE_STUDIO_SETTINGS"] = str(tmp / "settings.ini")

    from PySide6.QtWidgets import QApplication

    from tactile_studio.protocol.snapshot import State
    from tactile_studio.ui.collect.console import CollectConsole

    app = QApplication.instance() or QApplication([])
    console = CollectConsole()
    console.resize(*CONSOLE_SIZE)
    console.show()
    s = console.setup
    s.participant.setText("P01")
    s.out_dir.setText(str(tmp))
    s.set_device("simulated", {"speed": "4", "gesture": "idle", "seed": "3"})
    s.blocks.setValue(2)
    _settle(app, 0.2)
    console.grab().save(str(out / "collect-setup.png"))

    choice = s.choice()
    choice.protocol = choice.protocol.with_overrides(break_every=1, break_min_s=120.0,
                                                     free_play_s=0.0)
    console.start_session(choice)
    runner, dev = console.runner, console.engine.device
    screen = console.participant
    screen.resize(*PARTICIPANT_SIZE)
    screen.show()

    def snap():  # noqa: ANN202
        return runner.snapshot()

    def perform(name: str, duration_s: float) -> None:
        """A person lets go of one gesture before the next."""
        _pump(app, lambda: dev.next_frame >= dev.performing_until)
        dev.perform(name, duration_s=duration_s)

    def trial(g, perform_it: bool = True) -> None:  # noqa: ANN001
        n = len(snap().trials)
        if perform_it:
            perform(g.name, 2.4)
        console.forward_key(g.key)
        _pump(app, lambda: len(snap().trials) > n and snap().state not in
              (State.RECORDING, State.TRIAL_END))

    console.primary_action()  # Start
    _pump(app, lambda: snap().state == State.WAITING)
    gestures = snap().gestures
    for g in gestures[:3]:
        trial(g)
        if snap().state == State.REVIEW:
            console.primary_action()
    _settle(app, 0.6)  # let the beep's flash fade
    screen.grab().save(str(out / "collect-participant-waiting.png"))

    console.forward_key(gestures[5].key)  # an upcoming gesture: refused, the prompt named
    _settle(app, 0.1)
    screen.grab().save(str(out / "collect-participant-refused.png"))
    perform("Constant Touch", 3.0)  # something on the heatmap
    _settle(app, 0.8)
    console.grab().save(str(out / "collect-console.png"))

    perform(gestures[3].name, 2.4)
    console.forward_key(gestures[3].key)
    _pump(app, lambda: snap().state != State.RECORDING or snap().trial_remaining_s < 1.25)
    console.tick()
    screen.grab().save(str(out / "collect-participant-trial.png"))
    _pump(app, lambda: snap().state not in (State.RECORDING, State.TRIAL_END))
    if snap().state == State.REVIEW:
        console.primary_action()

    for g in gestures[4:6]:
        trial(g)
        if snap().state == State.REVIEW:
            console.primary_action()
    engine = console.engine  # the last touch relaxes off the skin (tau ~3 s) first
    settled = engine.frames + round(15 * engine.nominal_rate_hz)
    _pump(app, lambda: engine.frames >= settled)
    trial(gestures[6], perform_it=False)  # nobody touched: flagged and held for a decision
    perform("Circular Stroke", 6.0)
    _settle(app, 1.0)
    console.grab().save(str(out / "collect-console-flagged.png"))
    console.redo_last()
    for g in snap().gestures:
        if not g.done:
            trial(g)
            if snap().state == State.REVIEW:
                console.primary_action()
    _pump(app, lambda: snap().state == State.BREAK)
    _settle(app, 1.2)
    screen.grab().save(str(out / "collect-participant-break.png"))
    console.close()
    screen.close()
    _pilot(app, out, tmp)
    _held_panel(app, out, tmp)
    for p in [*sorted(out.glob("collect-*.png")), out / "main-window-panel-collecting.png"]:
        print(p)
    return 0


def _pilot(app: object, out: Path, tmp: Path) -> None:
    """A rehearsal: a virtual participant performs, everything says PILOT."""
    from tactile_studio.protocol.snapshot import State
    from tactile_studio.ui.collect.console import CollectConsole

    console = CollectConsole()
    console.resize(*CONSOLE_SIZE)
    console.show()
    s = console.setup
    s.participant.setText("P00")
    s.out_dir.setText(str(tmp / "pilot"))
    s.set_device("simulated", {"speed": "4", "seed": "3"})
    s.blocks.setValue(1)
    s.pilot.setChecked(True)
    choice = s.choice()
    choice.protocol = choice.protocol.with_overrides(free_play_s=0.0)
    console.start_session(choice)
    runner = console.runner
    screen = console.participant
    screen.resize(*PARTICIPANT_SIZE)
    screen.show()
    console.primary_action()  # Start: the experimenter's, as with a person
    _pump(app, lambda: len(runner.snapshot().trials) >= 3
          and runner.snapshot().state == State.WAITING, timeout=60.0)

    def touched() -> bool:  # the virtual participant's touch is on the console's map
        frame = console.live.latest()
        return (runner.snapshot().state == State.RECORDING and frame is not None
                and float(frame.normal.max()) > 3.0 and console.heatmap.image_data() is not None)

    _pump(app, touched, timeout=60.0)
    _settle(app, 0.05)
    console.grab().save(str(out / "collect-console-pilot.png"))
    screen.grab().save(str(out / "collect-participant-pilot.png"))
    console.close()
    screen.close()


def _held_panel(app: object, out: Path, tmp: Path) -> None:
    """The main window's device panel while a collection holds its simulator idle."""
    from tactile_studio.ui.collect.app import open_console
    from tactile_studio.ui.main_window import MainWindow

    w = MainWindow(device="simulated", settings={"speed": "4"})
    w.resize(1400, 860)
    w.show()
    w.panel.connect_device()
    engine = w.acquisition.engine
    _pump(app, lambda: engine.baseline is not None)
    console = open_console(lambda: (engine, "simulated"))
    s = console.setup
    s.participant.setText("P02")
    s.out_dir.setText(str(tmp / "held"))
    console.start_session(s.choice())
    _pump(app, lambda: not w.panel.form_box.fields["gesture"].widget.isEnabled())
    _settle(app, 0.5)
    w.panel.grab().save(str(out / "main-window-panel-collecting.png"))
    console.close()
    w.shutdown()
    w.close()


if __name__ == "__main__":
    raise SystemExit(main())
